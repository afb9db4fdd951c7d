"""Planning at scale: info_gain's kept scores, rescored only around each press, equal scoring every cell afresh."""

from __future__ import annotations

import numpy as np
import pytest

from palpate.core.mapping.grids import Grid2D
from palpate.core.planning.expected_accuracy import expected_accuracy_gain
from palpate.core.planning.incremental import GainCache
from palpate.core.planning.info_gain import InfoGain
from palpate.core.planning.outcomes import outcome_posteriors

MATS = ["m0", "m1", "m2"]


@pytest.fixture(scope="module")
def memory(three_material_memory):
    return three_material_memory


def _scene(rng, n: int) -> np.ndarray:
    iy, ix = np.mgrid[0:n, 0:n]
    truth = np.zeros((n, n), dtype=int)
    for _ in range(6):
        cx, cy, r = rng.uniform(0, n, 2).tolist() + [rng.uniform(1, 6)]
        truth[(ix - cx) ** 2 + (iy - cy) ** 2 <= r * r] = int(rng.integers(1, 3))
    return truth


def test_rescoring_around_each_press_gives_the_same_choices_and_scores_as_scoring_every_cell(memory):
    rng = np.random.default_rng(7)
    n = 28
    truth = _scene(rng, n)
    answers = outcome_posteriors(memory, 20, seed=1)
    grid = Grid2D(MATS, (n, n))
    for iy, ix in np.argwhere(rng.random((n, n)) < 0.15):
        grid.update_cell(int(ix), int(iy), answers[truth[iy, ix], rng.integers(20)])
    fast = InfoGain(memory, spread_stride=1)  # no lattice: every choice is scored
    slow = InfoGain(memory, spread_stride=1, incremental=False)
    local = 0
    for k in range(25):
        post = grid.postprocessed(certainty=0.95)
        a = fast.next_target(grid, post)
        b = slow.next_target(grid, post)
        assert (a.ix, a.iy, a.score) == (b.ix, b.iy, b.score), k
        cache = fast._cache
        # the kept scores are bit for bit those of scoring every cell with the same frequencies
        full = expected_accuracy_gain(grid, post, fast.table(), reach=fast.belief_reach, correlation_cells=1.0,
                                      temperature=fast.belief_temperature, freq=cache.freq)
        assert np.array_equal(cache.gain, full), k
        local += 0 < cache.rescored_cells < n * n
        grid.update_cell(a.ix, a.iy, answers[truth[a.iy, a.ix], rng.integers(20)])
    assert local >= 15  # most presses rescored only a window around them


def test_the_kept_frequencies_are_refreshed_once_they_drift(memory):
    table = InfoGain(memory).table()
    cache = GainCache(table, reach=2, correlation_cells=1.0, temperature=0.5, surprise=0.0, freq_tolerance=0.05)
    grid = Grid2D(MATS, (12, 12))
    grid.update_cell(0, 0, [0.98, 0.01, 0.01])
    cache.update(grid, grid.postprocessed())
    assert cache.freq == pytest.approx([0.5, 0.25, 0.25])
    # four presses of m2 far away: the frequencies move by far more than 0.05, so everything is rescored
    for ix in range(8, 12):
        grid.update_cell(ix, 11, [0.01, 0.01, 0.98])
    cache.update(grid, grid.postprocessed())
    assert cache.rescored_cells == 144 and cache.freq == pytest.approx([2 / 8, 1 / 8, 5 / 8])
