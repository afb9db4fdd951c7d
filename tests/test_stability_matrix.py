"""Stability at the extremes: every cell of the matrix is ok (finite, ordered), diverged or invalid with a message
that says what to change; never NaN, never a bug. The full matrix is benchmarks/stability_matrix.py."""

from __future__ import annotations

import numpy as np
import pytest

from palpate.sim.extremes import Cell, matrix, physically_ordered, run_cell

ACTIONABLE = ("timestep", "speed", "stiffness", "young", "deep", "depth", "resolution")


def _check(outcomes):
    for o in outcomes:
        assert o.outcome in ("ok", "diverged", "invalid"), (o.cell, o.message)
        if o.outcome == "ok":
            assert np.isfinite(o.peak_force) and o.peak_force > 0, o.cell
        else:
            assert any(word in o.message for word in ACTIONABLE), (o.cell, o.message)


def test_ordering_check_catches_disorder_and_nan():
    t = np.linspace(0, 1, 5)
    d = np.array([0, 1, 2, 3, 2.0]) * 1e-3
    assert physically_ordered(t, np.array([0, 1, 2, 3, 1.0]), d) == ""
    assert "falls" in physically_ordered(t, np.array([0, 1, 3, 1, 1.0]), d)
    assert "non-finite" in physically_ordered(t, np.array([0, 1, np.nan, 3, 1.0]), d)
    assert "negative" in physically_ordered(t, np.array([0, -1, 2, 3, 1.0]), d)


def test_fast_subset_of_the_matrix():
    cells = matrix(fidelities=("analytic", "rigid"), youngs=(1e3, 1e8), poissons=(0.49,), timesteps=(1e-3, 1e-2),
                   speeds=(0.01, 0.2), depth_fractions=(0.1, 0.8), locations=("centre", "corner"))
    outcomes = [run_cell(c) for c in cells]
    _check(outcomes)
    # closed form cannot diverge: analytic runs every press its taxel rate can see, and refuses the rest
    ana = [o for o in outcomes if o.cell.fidelity == "analytic"]
    assert all(o.outcome == "ok" or "taxel rate" in o.message for o in ana)
    assert sum(o.outcome == "ok" for o in ana) >= len(ana) // 2
    # the stiff end at a coarse step is caught, not passed through as garbage
    assert any(o.outcome == "diverged" for o in outcomes if o.cell.young == 1e8 and o.cell.timestep == 1e-2)


def test_step_shorter_than_the_press_is_refused_with_the_timestep_to_use():
    o = run_cell(Cell("rigid", 2e5, 0.3, 1e-2, 0.2, 0.1, "centre"))
    assert o.outcome == "invalid" and "use a timestep of at most" in o.message


def test_step_budget_stops_a_press_that_would_take_too_long():
    o = run_cell(Cell("rigid", 2e5, 0.3, 1e-4, 0.001, 0.8, "centre"), max_steps=1000)
    assert o.outcome == "invalid" and "budget" in o.message and "timestep" in o.message


@pytest.mark.physics
def test_larger_subset_with_flex_and_edges():
    cells = matrix(fidelities=("rigid",), youngs=(1e3, 1e5, 1e8), poissons=(0.0, 0.49), timesteps=(1e-4, 2e-3, 1e-2),
                   speeds=(0.001, 0.2), depth_fractions=(0.1, 0.8), locations=("centre", "edge", "corner"))
    cells += matrix(fidelities=("flex",), youngs=(1e3, 1e8), poissons=(0.49,), timesteps=(2e-3, 1e-2),
                    speeds=(0.2,), depth_fractions=(0.1, 0.8), locations=("centre", "corner"))
    cells.append(Cell("flex", 1e3, 0.49, 2e-3, 0.01, 0.8, "centre"))  # the disordered case the matrix found
    _check([run_cell(c) for c in cells])
