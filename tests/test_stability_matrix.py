"""Stability at the extremes: every cell of the matrix, and every call of a random fuzz, is ok (finite, ordered,
at its commanded depth and force, and at the centre within WRONG of the contact law), diverged or invalid with a
message that names an option the caller has; never NaN, never a silent miss or a silent wrong answer, never a hang.
The full matrix is benchmarks/stability_matrix.py."""

from __future__ import annotations

import re

import numpy as np
import pytest

from palpate.sim import limits
from palpate.sim.extremes import (
    Cell,
    audit_cells,
    fuzz_cells,
    matrix,
    outcome_counts,
    physically_ordered,
    run_cell,
)

#: Options a caller of simulate_press / SimSource / the run_*_press functions has, one of which every message names.
ACTIONABLE = ("timestep", "speed", "slower", "deep", "depth", "taxel rate", "force target", "fidelity",
              "max_steps", "tip radius", "thicker sample", "Poisson ratio", "layer of at least")
#: How a refusal for what a rung holds (palpate.sim.limits) names its limit.
LIMIT = re.compile(r"depth limit (of )?\d+\.\d+ mm|Poisson ratio up to 0\.\d+|resolves layers from \d+(\.\d+)? mm")


def _check(outcomes):
    for o in outcomes:
        assert o.outcome in ("ok", "diverged", "invalid"), (o.cell, o.message)
        if o.outcome == "ok":
            assert np.isfinite(o.peak_force) and o.peak_force > 0, o.cell
            assert 0.0 <= o.saturated <= 1.0
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
                   speeds=(0.01, 0.2), depth_fractions=(0.1, 0.5), locations=("centre",))
    cells += [Cell("rigid", 1e5, 0.3, 2e-3, 0.01, 0.3, "corner"), Cell("analytic", 1e5, 0.3, 2e-3, 0.01, 0.3, "edge")]
    outcomes = [run_cell(c) for c in cells]
    _check(outcomes)
    # closed form cannot diverge: analytic runs every press its taxel rate can see, and refuses the rest
    ana = [o for o in outcomes if o.cell.fidelity == "analytic"]
    assert all(o.outcome == "ok" or "taxel rate" in o.message for o in ana)
    assert sum(o.outcome == "ok" for o in ana) >= len(ana) // 3
    # the stiff end at a coarse step is caught, not passed through as garbage
    assert any(o.outcome == "diverged" for o in outcomes if o.cell.young == 1e8 and o.cell.timestep == 1e-2)
    # stiff presses saturate the 8-bit pad, and that is counted
    assert max(o.saturated for o in outcomes if o.outcome == "ok" and o.cell.young == 1e8) > 0.05


def test_step_shorter_than_the_press_is_refused_with_the_timestep_to_use():
    o = run_cell(Cell("rigid", 2e5, 0.3, 1e-2, 0.2, 0.1, "centre"))
    assert o.outcome == "invalid" and "use a timestep of at most" in o.message


def test_step_budget_stops_a_press_that_would_take_too_long():
    o = run_cell(Cell("rigid", 2e5, 0.3, 1e-4, 0.001, 0.5, "centre"), max_steps=1000)
    assert o.outcome == "invalid" and "budget" in o.message and "timestep" in o.message


def test_a_press_past_three_quarters_of_the_tip_radius_is_refused_naming_the_depth():
    o = run_cell(Cell("analytic", 2e5, 0.3, 2e-3, 0.01, 0.8, "centre", thickness=0.02))
    assert o.outcome == "invalid" and "tip radii" in o.message and "deep" in o.message


def test_a_stiff_force_target_is_reached_not_silently_missed():
    """A 10 N target at 20 MPa once ended at 3.9 N with no warning: it is now reached."""
    for fidelity in ("analytic", "rigid"):
        o = run_cell(Cell(fidelity, 2e7, 0.3, 2e-3, 0.002, 0.5, "centre", "force"))
        assert o.outcome == "ok" and o.peak_force == pytest.approx(10.0, rel=0.02), o.message


def test_fuzz_of_the_closed_form_fidelities_has_no_nan_no_silent_miss_and_no_hang():
    outcomes = [run_cell(c) for c in fuzz_cells(10, seed=3, fidelities=("analytic", "rigid"))]
    _check(outcomes)
    assert outcome_counts(outcomes).get("ok", 0) >= 3


def test_the_audits_silent_wrong_answers_are_refused_naming_their_limit_or_answered_right():
    """Deeper than the base holds (every rung), thin skins, a 2 mm block pressed 1-1.8 mm, nu 0.49-0.49995."""
    outcomes = [run_cell(c) for c in audit_cells()]
    _check(outcomes)
    for o in outcomes:
        c = o.cell
        if o.outcome == "invalid":
            assert LIMIT.search(o.message), (c, o.message)
        elif c.fidelity != "analytic":
            # rigid and flex (and auto's choice of them) within the table's errors of the contact law
            assert o.fidelity == "analytic" or abs(o.error) < 0.08, (c, o.error)
    by = {(o.cell.fidelity, o.cell.poisson, o.cell.thickness, o.cell.skin, o.cell.depth_fraction): o.outcome
          for o in outcomes}
    assert all(v == "invalid" for k, v in by.items() if k[2] == 0.002 and k[4] > 0.5)  # past half the base
    assert all(v == "invalid" for k, v in by.items() if k[0] == "flex" and (0 < k[3] < 1e-3 or k[1] > 0.49))
    assert all(v == "ok" for k, v in by.items() if k[0] in ("analytic", "auto") and k[3] >= 2e-4)
    assert by[("auto", 0.499, 0.01, 0.0, 0.2)] == "ok" and by[("flex", 0.49, 0.01, 0.0, 0.2)] == "ok"


def test_the_matrix_catches_a_silent_wrong_answer(monkeypatch):
    """With flex's thin-layer limit lifted, a 0.5 mm skin is the bare block again: the matrix calls it a BUG."""
    monkeypatch.setitem(limits.MIN_LAYER, "flex", 0.0)
    o = run_cell(Cell("flex", 2e5, 0.45, 5e-3, 0.01, 0.2, skin=5e-4))
    assert o.outcome == "BUG" and "silent wrong answer" in o.message and o.error > 0.25


def test_fuzz_of_stacks_and_thin_blocks_has_no_silent_wrong_answer():
    outcomes = [run_cell(c) for c in fuzz_cells(12, seed=5, fidelities=("analytic", "rigid", "auto"), stacks=True)]
    _check(outcomes)
    assert outcome_counts(outcomes).get("ok", 0) >= 3
    over = [o for o in outcomes if o.outcome == "invalid" and "material over" in o.message]
    assert over and all(LIMIT.search(o.message) for o in over), [o.message for o in over]


@pytest.mark.physics
def test_fuzz_of_stacks_with_flex_has_no_silent_wrong_answer():
    _check([run_cell(c) for c in fuzz_cells(30, seed=21, fidelities=("flex", "auto"), stacks=True)])


@pytest.mark.physics
def test_fuzz_of_sixty_calls_with_flex_has_no_nan_no_silent_miss_and_no_hang():
    _check([run_cell(c) for c in fuzz_cells(60, seed=12)])


@pytest.mark.physics
def test_larger_subset_with_flex_and_edges():
    cells = matrix(fidelities=("rigid",), youngs=(1e3, 1e5, 1e8), poissons=(0.0, 0.49), timesteps=(1e-4, 2e-3, 1e-2),
                   speeds=(0.001, 0.2), depth_fractions=(0.1, 0.5), locations=("centre", "edge", "corner"))
    cells += matrix(fidelities=("flex",), youngs=(1e3, 1e8), poissons=(0.49,), timesteps=(2e-3, 1e-2),
                    speeds=(0.2,), depth_fractions=(0.1, 0.5), locations=("centre", "corner"))
    cells.append(Cell("flex", 1e3, 0.49, 2e-3, 0.01, 0.5, "centre"))
    _check([run_cell(c) for c in cells])


def test_fuzz_of_the_bem_rung_has_no_silent_wrong_answer_and_names_every_limit():
    """bem on random blocks, stacks and thin layers: never a NaN, a miss or a force off the contact law at the
    centre; every refusal says what to change."""
    outcomes = [run_cell(c) for c in fuzz_cells(24, seed=8, fidelities=("bem",), stacks=True)]
    _check(outcomes)
    assert outcome_counts(outcomes).get("ok", 0) >= 3
