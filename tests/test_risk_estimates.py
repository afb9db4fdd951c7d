"""Estimates of where a press would read other than the map says (benchmarks/risk_estimates.py) and the
harness's scores (benchmarks/risk_harness.py)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))

from risk_estimates import (  # noqa: E402
    POTTS_OFFSETS,
    MapState,
    belief_risk,
    fit_potts,
    line_risk,
    potts_risk,
    subset_risk,
    wall_risk,
)
from risk_harness import auc, fit_logistic, hits_at, leave_one_family_out  # noqa: E402

from palpate.core.mapping.grids import Grid2D  # noqa: E402

M = 2


def _state(readings: np.ndarray) -> MapState:
    """The measured and post-processed (eq. 6.15, the seed's) map of presses reading ``readings`` (-1: none)."""
    ny, nx = readings.shape
    g = Grid2D([f"m{i}" for i in range(M)], (nx, ny))
    iy, ix = np.nonzero(readings >= 0)
    p = np.full((iy.size, M), 0.01)
    p[np.arange(iy.size), readings[iy, ix]] = 0.99
    g.update_cells(ix, iy, p)
    return MapState(np.asarray(g.probabilities), np.asarray(g.explored, bool),
                    np.asarray(g.postprocessed().probabilities))


def _stripe_map(stripe: int) -> np.ndarray:
    """9 x 9 of material 0 pressed on a stride-3 lattice (rows and columns 1, 4, 7), plus two presses in column 3
    (rows 2 and 6) reading ``stripe``: the centre (4, 3) between them is filled from the lattice press (4, 4), so
    its map label is 0 whatever those two read."""
    r = np.full((9, 9), -1)
    r[1::3, 1::3] = 0
    r[2, 3] = r[6, 3] = stripe
    return r


def test_line_risk_rises_on_a_hidden_stripe_between_two_presses_that_read_it():
    plain, striped = _state(_stripe_map(0)), _state(_stripe_map(1))
    assert plain.label[4, 3] == striped.label[4, 3] == 0
    assert line_risk(striped)[4, 3] > line_risk(plain)[4, 3] + 0.3


@pytest.mark.parametrize("estimate", [line_risk, potts_risk, subset_risk, belief_risk, wall_risk])
def test_a_homogeneous_map_has_almost_no_risk_next_to_its_presses(estimate):
    s = _state(_stripe_map(0))
    near = ~s.explored  # the lattice leaves no cell without a pressed 8-neighbour
    assert np.mean(estimate(s)[near]) < 0.1


def _wall_map(wall: int) -> np.ndarray:
    """9 x 9, material 0 left of column ``wall``, 1 from it on: a stride-3 lattice (rows and columns 1, 4, 7) and,
    in rows 1 and 7, presses on columns 2-5 that locate the wall; row 4 has only its lattice presses."""
    truth = (np.arange(9)[None, :] >= wall).repeat(9, 0)
    r = np.full((9, 9), -1)
    r[1::3, 1::3] = truth[1::3, 1::3]
    for row in (1, 7):
        r[row, 2:6] = truth[row, 2:6]
    return r


def test_wall_risk_extrapolates_a_wall_located_by_presses_along_it():
    # cell (4, 3) is filled from the lattice press (4, 4), which reads 1: wrong if the wall is at column 4 (rows 1
    # and 7 say so), right if it is at column 3
    moved, kept = _state(_wall_map(4)), _state(_wall_map(3))
    assert moved.label[4, 3] == kept.label[4, 3] == 1
    assert wall_risk(moved)[4, 3] > wall_risk(kept)[4, 3] + 0.1


def test_potts_fit_finds_the_direction_of_stripes():
    # horizontal stripes two rows wide, every cell pressed: neighbours along rows always agree, along columns not
    r = np.repeat((np.arange(12) // 2 % 2)[:, None], 12, axis=1)
    beta = fit_potts(_state(r))
    row, column = POTTS_OFFSETS.index((0, 1)), POTTS_OFFSETS.index((1, 0))
    assert beta[row] > beta[column] + 0.5


def test_undecided_cells_are_at_risk():
    r = np.full((3, 3), -1)
    r[1, 0], r[1, 2] = 0, 1  # the centre is a tie of its two pressed neighbours
    s = _state(r)
    for estimate in (line_risk, potts_risk, subset_risk, belief_risk, wall_risk):
        assert estimate(s)[1, 1] == 1.0


def _pairwise_auc(risk, wrong):
    pos, neg = risk[wrong], risk[~wrong]
    return np.mean((pos[:, None] > neg[None, :]) + 0.5 * (pos[:, None] == neg[None, :]))


def test_scores_against_direct_counts():
    rng = np.random.default_rng(3)
    wrong = rng.random(400) < 0.3
    risk = np.round(rng.random(400) + 0.6 * wrong, 1)  # ties on purpose
    assert auc(risk, wrong) == pytest.approx(_pairwise_auc(risk, wrong))
    # a threshold without ties: the share of wrong cells above the 90th percentile of the right ones
    smooth = rng.random(400) + 0.6 * wrong
    thr = np.sort(smooth[~wrong])[int(np.ceil(0.9 * (~wrong).sum())) - 1]
    got = hits_at(smooth, wrong, 0.1)
    assert abs(got - np.mean(smooth[wrong] > thr)) <= 1.0 / wrong.sum() + 1e-12
    assert hits_at(wrong.astype(float), wrong) == 1.0 and auc(wrong.astype(float), wrong) == 1.0


def test_leave_one_family_out_scores_a_family_without_its_own_cells():
    # family b's label follows the input the other way round: a stack fitted on a alone cannot know that
    rng = np.random.default_rng(0)
    x = rng.normal(size=(600, 1))
    family = np.repeat(np.array(["a", "b"]), 300)
    y = np.where(family == "a", x[:, 0] > 0, x[:, 0] < 0)
    out = leave_one_family_out(x, y, family)
    assert auc(out[family == "b"], y[family == "b"]) < 0.2
    inside = fit_logistic(x[family == "b"], y[family == "b"])
    assert inside[1] < 0
