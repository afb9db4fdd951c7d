"""The planning belief of the truth and the expected number of cells a press sets right, checked against a brute
force that presses on a copy of the map with the map's own update and post-processing."""

from __future__ import annotations

import math

import numpy as np
import pytest

from palpate.core.errors import ValidationError
from palpate.core.mapping.grids import Grid2D
from palpate.core.planning.expected_accuracy import (
    confusion_outcomes,
    expected_accuracy_gain,
    label_belief,
    material_frequencies,
)
from palpate.core.planning.outcomes import outcome_posteriors, outcome_table

MATS = ["m0", "m1", "m2"]


@pytest.fixture(scope="module")
def table(three_material_memory):
    """Outcome table of a memory whose materials overlap a little (so the confusion is not the identity)."""
    return outcome_table(outcome_posteriors(three_material_memory, 40, seed=2))


def _random_map(rng, shape=(7, 6), pressed=12) -> Grid2D:
    g = Grid2D(MATS, shape, cell_size=0.01)
    for _ in range(pressed):
        g.update_cell(int(rng.integers(shape[0])), int(rng.integers(shape[1])), rng.dirichlet([0.3, 0.3, 0.3]))
    return g


def _correct(post: np.ndarray, belief: np.ndarray) -> np.ndarray:
    top2 = np.sort(post, axis=-1)[..., -2:]
    label = np.argmax(post, axis=-1)
    return np.take_along_axis(belief, label[..., None], -1)[..., 0] * ((top2[..., 1] - top2[..., 0]) > 1e-9)


def _brute_force(g: Grid2D, table, ix: int, iy: int, corr: float) -> float:
    """Press (ix, iy) on copies of the map, once per named outcome, with Grid2D's own update and eq. 6.15."""
    rep, conf = confusion_outcomes(table)
    p = np.asarray(g.probabilities)
    freq = material_frequencies(np.argmax(p, -1), np.asarray(g.explored), 3)
    belief = label_belief(g, correlation_cells=corr, freq=freq)
    post = np.asarray(g.postprocessed().probabilities)
    ny, nx = p.shape[:2]
    block = (slice(max(0, iy - 1), iy + 2), slice(max(0, ix - 1), ix + 2))
    total = 0.0
    for o in range(3):
        p_o = float(belief[iy, ix] @ conf[:, o])
        if p_o == 0:
            continue
        h = g._empty_like()._with_arrays(np.array(p), np.array(g.explored))
        h.update_cell(ix, iy, rep[o])
        after_belief = label_belief(h, correlation_cells=corr, freq=freq)
        # the pressed cell's truth given what it was read as (Bayes with the memory's confusion)
        t = belief[iy, ix] * conf[:, o]
        after_belief[iy, ix] = t / t.sum()
        post_after = np.asarray(h.postprocessed().probabilities)
        free = ~np.asarray(g.explored)
        free[iy, ix] = True
        diff = (_correct(post_after, after_belief) - _correct(post, after_belief))[block]
        total += p_o * float(diff[free[block]].sum())
    return total


def test_expected_accuracy_gain_matches_a_brute_force_on_the_maps_own_code(table):
    rng = np.random.default_rng(4)
    for trial in range(3):
        g = _random_map(rng)
        gain = expected_accuracy_gain(g, g.postprocessed(), table, correlation_cells=3.0)
        assert gain.shape == (6, 7) and np.all(np.isfinite(gain))
        for iy, ix in [(0, 0), (2, 3), (5, 6), (3, 1)]:
            assert gain[iy, ix] == pytest.approx(_brute_force(g, table, ix, iy, 3.0), abs=1e-9), (trial, ix, iy)


def test_a_press_between_two_materials_is_worth_more_than_one_inside_a_known_region(table):
    # columns 0-3 read as m0, 5-8 as m2; column 4 never pressed: it is a coin toss, and a cell inside the
    # measured m0 region is not.
    g = Grid2D(MATS, (9, 5), cell_size=0.01)
    for ix in (0, 1, 2, 3, 5, 6, 7, 8):
        for iy in range(5):
            if (ix, iy) != (1, 2):
                g.update_cell(ix, iy, [0.998, 0.001, 0.001] if ix < 4 else [0.001, 0.001, 0.998])
    gain = expected_accuracy_gain(g, g.postprocessed(), table)
    belief = label_belief(g)
    assert 0.3 < belief[2, 4, 0] < 0.7  # the middle: either
    assert belief[2, 1, 0] > 0.9  # inside the m0 region
    assert gain[2, 4] > gain[2, 1] + 0.3


def test_belief_is_the_measurement_on_pressed_cells_and_the_frequencies_where_nothing_reaches():
    g = Grid2D(MATS, (12, 3), cell_size=0.01)
    g.update_cell(0, 1, [0.7, 0.2, 0.1])
    b = label_belief(g, reach=2)
    assert b[1, 0] == pytest.approx([0.7, 0.2, 0.1])
    freq = material_frequencies(np.argmax(np.asarray(g.probabilities), -1), np.asarray(g.explored), 3)
    assert freq == pytest.approx([0.5, 0.25, 0.25])  # (1 + 1) / (1 + 3), Laplace-smoothed
    assert b[1, 11] == pytest.approx(freq)  # 11 cells away, beyond reach
    assert b[1, 1, 0] > b[1, 2, 0] > freq[0]  # a neighbour's vote fades with distance
    assert np.allclose(b.sum(-1), 1.0)


def test_a_lower_temperature_makes_the_belief_humbler():
    g = Grid2D(MATS, (7, 1), cell_size=0.01)
    for ix in (0, 1, 2):
        g.update_cell(ix, 0, [0.998, 0.001, 0.001])
    sure = label_belief(g, temperature=1.0)[0, 3, 0]
    humble = label_belief(g, temperature=0.3)[0, 3, 0]
    assert 1 / 3 < humble < sure < 1.0


@pytest.mark.parametrize("kw, msg", [
    ({"reach": 0}, "reach must be an integer >= 1"),
    ({"correlation_cells": math.nan}, "correlation length"),
    ({"temperature": 1.5}, r"temperature must be in \(0, 1\]"),
    ({"freq": np.array([0.5, 0.5, 0.0])}, "freq must be 3 finite shares > 0"),
])
def test_bad_belief_parameters_are_refused(kw, msg):
    with pytest.raises(ValidationError, match=msg):
        label_belief(Grid2D(MATS, (3, 3)), **kw)


def test_a_voxel_map_is_refused_with_a_clear_error(table):
    from palpate.core.mapping.grids import VoxelGrid

    v = VoxelGrid(MATS, (3, 3, 2))
    with pytest.raises(ValidationError, match="2-D map"):
        expected_accuracy_gain(v, v.postprocessed(), table)
