"""The calibration sweep's helpers (benchmarks/exploration_wall_sweep.py): which cells count as beside a wall, and
the rule that picks a setting from the scores."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))

from exploration_wall_sweep import chosen, near_wall  # noqa: E402

from palpate.core.mapping.calibration import MapCalibration  # noqa: E402


def test_near_wall_marks_the_cells_with_an_edge_neighbour_of_another_true_material():
    rng = np.random.default_rng(3)
    truth = rng.integers(-1, 3, size=(6, 7))
    want = np.zeros(truth.shape, bool)
    for iy in range(truth.shape[0]):
        for ix in range(truth.shape[1]):
            for dy, dx in ((0, 1), (1, 0), (0, -1), (-1, 0)):
                jy, jx = iy + dy, ix + dx
                if 0 <= jy < truth.shape[0] and 0 <= jx < truth.shape[1] and truth[iy, ix] >= 0 \
                        and truth[jy, jx] >= 0 and truth[iy, ix] != truth[jy, jx]:
                    want[iy, ix] = True
    np.testing.assert_array_equal(near_wall(truth), want)


def test_the_rule_takes_the_lowest_allowed_score_and_prefers_a_smaller_change_within_the_margin():
    shipped = MapCalibration(press_reliability=0.94, extrapolation_certainty=0.95)
    scores = {(0.94, 0.95, 0.7): 0.050, (0.97, 0.95, 0.7): 0.041, (0.99, 0.95, 0.7): 0.040,
              (0.99, 1.0, 0.6): 0.030}
    pooled = {(0.94, 0.95, 0.7): 0.02, (0.97, 0.95, 0.7): 0.02, (0.99, 0.95, 0.7): 0.02, (0.99, 1.0, 0.6): 0.04}
    # the lowest score breaks the pooled bound; of the rest 0.97 is within the margin of 0.99 and changes less
    assert chosen(scores, pooled, shipped, 0.03, 0.002) == (0.97, 0.95, 0.7)
    assert chosen(scores, pooled, shipped, 0.03, 0.0) == (0.99, 0.95, 0.7)
    assert chosen(scores, pooled, shipped, 0.05, 0.0) == (0.99, 1.0, 0.6)
    assert chosen(scores, pooled, shipped, 0.01, 0.002) is None
