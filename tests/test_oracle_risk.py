"""The oracle references (benchmarks/oracle_risk.py): info_gain told where its map is wrong marks exactly the
unpressed wrong cells and goes to a hidden one-cell feature that info_gain itself does not press next; a noisy
oracle marks the shares of cells it is given, and a blind one chooses as info_gain."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))

from oracle_risk import OracleRisk, with_oracle, wrong_unpressed  # noqa: E402

from palpate.core.errors import ValidationError  # noqa: E402
from palpate.core.mapping.accuracy import decided_labels  # noqa: E402
from palpate.core.mapping.grids import Grid2D  # noqa: E402
from palpate.core.planning.info_gain import InfoGain  # noqa: E402
from palpate.core.planning.outcomes import outcome_posteriors  # noqa: E402

MATS = ["m0", "m1", "m2"]
N = 7
BLOCK = (slice(2, 4), slice(3, 5))  # an unpressed 2 x 2 block: every cell of it has pressed neighbours
HIDDEN = (3, 3)  # (iy, ix) of a one-cell feature of m2 in it, not the cell info_gain presses next


@pytest.fixture(scope="module")
def pressed_map(three_material_memory):
    """A map of m0 with every cell pressed but BLOCK, and its truth."""
    truth = np.zeros((N, N), dtype=int)
    truth[HIDDEN] = 2
    answers = outcome_posteriors(three_material_memory, 20, seed=1)
    rng = np.random.default_rng(3)
    grid = Grid2D(MATS, (N, N))
    pressed = np.ones((N, N), dtype=bool)
    pressed[BLOCK] = False
    for iy, ix in np.argwhere(pressed):
        grid.update_cell(int(ix), int(iy), answers[truth[iy, ix], rng.integers(20)])
    return grid, truth


def test_only_unpressed_cells_the_map_gets_wrong_are_marked(pressed_map):
    grid, truth = pressed_map
    post = grid.postprocessed()
    label, decided = decided_labels(np.asarray(post.probabilities))
    counted = truth.copy()
    counted[0, 0] = -1  # a cell without a true material is never marked
    got = wrong_unpressed(grid, post, counted)
    want = (~np.asarray(grid.explored)) & (counted >= 0) & ~((label == counted) & decided)
    assert got.dtype == float and np.array_equal(got > 0, want)
    assert got[HIDDEN] == 1.0 and got.sum() == 1.0  # the rest of the block is filled right from its neighbours


def test_the_oracle_presses_the_hidden_feature_where_info_gain_does_not(pressed_map, three_material_memory):
    grid, truth = pressed_map
    post = grid.postprocessed()
    plain = InfoGain(three_material_memory, spread_stride=1, entropy_weight=3.0)
    oracle = with_oracle(plain, truth)
    assert oracle.entropy_weight == 3.0 and oracle.spread_stride == 1  # the policy's settings are kept
    a = plain.next_target(grid, post)
    b = oracle.next_target(grid, post)
    assert (a.iy, a.ix) != HIDDEN  # the map fills the feature confidently from its neighbours
    assert (b.iy, b.ix) == HIDDEN
    # the oracle only steers the choice: the stop rule's score and the values info_gain keeps between choices
    # (refreshed only where the map changes) are the plain policy's
    assert b.score == a.score
    assert np.array_equal(oracle._terms[0], plain._terms[0])


def test_a_noisy_oracle_marks_the_shares_it_is_given_and_a_blind_one_chooses_as_info_gain(pressed_map,
                                                                                        three_material_memory):
    grid, truth = pressed_map
    post = grid.postprocessed()
    plain = InfoGain(three_material_memory, spread_stride=1)
    noisy = with_oracle(plain, truth, hit=0.6, false_alarm=0.3, seed=4)
    wrong = wrong_unpressed(grid, post, truth) > 0
    free = ~np.asarray(grid.explored)
    want = (wrong & (noisy.draws < 0.6)) | (free & ~wrong & (noisy.draws < 0.3))
    assert np.array_equal(noisy.marked(grid, post) > 0, want)
    blind = with_oracle(plain, truth, hit=0.0, false_alarm=0.0, seed=4)
    assert not blind.marked(grid, post).any()
    a, b = plain.next_target(grid, post), blind.next_target(grid, post)
    assert (a.ix, a.iy, a.score) == (b.ix, b.iy, b.score)


@pytest.mark.parametrize("kwargs", [{"hit": 0.2, "false_alarm": 0.5}, {"hit": 1.5}, {"oracle_weight": -1.0},
                                    {"hit": 0.5, "draws": None}, {"reference": None}])
def test_bad_oracle_settings_are_refused(kwargs, three_material_memory):
    base = {"reference": np.zeros((3, 3), dtype=int), "draws": np.zeros((3, 3))}
    with pytest.raises(ValidationError):
        OracleRisk(three_material_memory, **{**base, **kwargs})
