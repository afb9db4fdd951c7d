"""The entropy objective of info_gain: the expected reduction of the post-processed map's entropy from one press,
and the boundary term that goes with it (:func:`disagreement`); voxel maps' entropy gain.
"""

from __future__ import annotations

import math

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.mapping.neighbourhood import NEIGHBOURS_8, box3_sum, shift_slices
from palpate.core.mapping.probability import entropy_unchecked
from palpate.core.planning.map_views import H_MIN, is_voxel, layers_reached


def _plane_gain(p_raw: np.ndarray, p_post: np.ndarray, explored: np.ndarray, outcomes: np.ndarray,
                likelihood: np.ndarray, base: float, p_min: float, spread: bool) -> np.ndarray:
    """Expected entropy reduction of the post-processed plane from one press per cell, shape p_raw.shape[:2].

    p_raw/p_post: (ny, nx, M) measured and post-processed probabilities; outcomes (U, M) and likelihood (M, U)
    from :func:`outcome_table`. The outcome of a press is predicted from the post-processed belief P(t) (the best
    estimate of what is there), the update (seed 001 eq. 2, clamped as the map clamps) is applied to the
    measured value (what the map will fuse it into), and with ``spread`` the change is carried to the unexplored
    8-neighbours through eq. 6.15's 1/H-weighted mean of explored neighbours (each outcome's rise of a
    neighbour's entropy counted as zero).
    """
    lb = math.log(base)
    pr = np.moveaxis(p_raw, -1, 0)  # (M, ny, nx)
    pp = np.moveaxis(p_post, -1, 0)
    new = pr[:, None] * outcomes.T[:, :, None, None]  # (M, U, ny, nx)
    new /= new.sum(axis=0)
    np.maximum(new, p_min, out=new)
    new /= new.sum(axis=0)
    w_o = np.einsum("myx,mu->uyx", pp, likelihood)  # P(outcome u) = sum_t P(t) P(u | t)
    h_new = entropy_unchecked(new, base, axis=0)  # (U, ny, nx)
    h_post = entropy_unchecked(pp, base, axis=0)  # (ny, nx)
    gain = h_post - (w_o * h_new).sum(axis=0)
    if not spread:
        return gain
    ny, nx = h_post.shape
    w_raw = np.where(explored, 1.0 / np.maximum(entropy_unchecked(pr, base, axis=0), H_MIN), 0.0)
    c_old = w_raw * pr  # each explored cell's term of eq. 6.15 (zero if unexplored)
    num_all = box3_sum(c_old)
    w_new = 1.0 / np.maximum(h_new, H_MIN)
    c_new = w_new * new  # (M, U, ny, nx): the pressed cell's term after each outcome
    for dy, dx in NEIGHBOURS_8:
        (cy, cx), (ky, kx) = shift_slices(dy, dx, ny, nx)
        free = ~explored[ky, kx]
        if not free.any():
            continue
        # Neighbour's eq. 6.15 numerator with the candidate's term swapped for its predicted one.
        num = (num_all[:, ky, kx] - c_old[:, cy, cx])[:, None] + c_new[:, :, cy, cx]
        np.maximum(num, 1e-300, out=num)  # rounding of the subtraction only; keeps log finite
        den = num.sum(axis=0)
        s = (num * np.log(num)).sum(axis=0)
        h = (np.log(den) - s / den) / lb
        # Only reductions count. Eq. 6.15 is not a Bayesian posterior, so a press that contradicts an
        # extrapolation raises the neighbour's entropy without a balancing fall elsewhere; counting the rise
        # steers the policy away from material boundaries, exactly where the map is wrong (benchmark: about
        # half the presses to 95% accuracy with the clip).
        red = np.maximum(h_post[ky, kx] - h, 0.0)
        delta = (w_o[:, cy, cx] * red).sum(axis=0)
        gain[cy, cx] += np.where(free, delta, 0.0)
    return gain


def expected_gain(grid, post, table: tuple[np.ndarray, np.ndarray], max_depth: float | None = None) -> np.ndarray:
    """Expected reduction of the post-processed map's total entropy from one press on each column, (ny, nx).

    2-D maps: the pressed cell plus, through eq. 6.15, its unexplored 8-neighbours. Voxel maps: the sum over the
    voxels the press reaches, each predicted with the same outcome table (post-processing is vertical and a press
    fills a column from the top, so it opens no gap to extrapolate into).

    Args:
        grid: the measured map (Grid2D or VoxelGrid).
        post: its post-processed version.
        table: (outcomes (U, M), likelihood (M, U)) from :func:`outcome_table`.
        max_depth: voxel maps: deepest press, m.
    """
    outcomes, likelihood = (np.asarray(v, dtype=float) for v in table)
    m = len(grid.materials)
    if outcomes.ndim != 2 or outcomes.shape[1] != m or likelihood.shape != (m, outcomes.shape[0]):
        raise ValidationError(f"outcome table must be (U, {m}) outcomes and ({m}, U) likelihoods for materials "
                              f"{grid.materials}, got {outcomes.shape} and {likelihood.shape}")
    p_raw = np.asarray(grid.probabilities)
    p_post = np.asarray(post.probabilities)
    if is_voxel(grid):
        k = layers_reached(grid, max_depth)
        nx, ny = grid.shape[:2]
        # The reachable voxels as one column of independent cells (no lateral spread).
        g = _plane_gain(p_raw[:, :, :k].reshape(-1, 1, m), p_post[:, :, :k].reshape(-1, 1, m),
                        np.asarray(grid.explored)[:, :, :k].reshape(-1, 1), outcomes, likelihood, grid.base,
                        grid.p_min, spread=False)
        return g.reshape(nx, ny, k).sum(axis=-1).T
    return _plane_gain(p_raw, p_post, np.asarray(grid.explored), outcomes, likelihood, grid.base, grid.p_min,
                       spread=True)


def disagreement(grid, reach: int = 2) -> np.ndarray:
    """Chance that an unexplored cell's material differs from what most of its measured neighbours say, (ny, nx).

    Per unexplored cell: 1 - the largest share of one material among the explored cells within ``reach`` cells
    (Chebyshev), weighted 1 / distance^2 and voting with their most probable material; 0 on explored cells and
    where no explored cell is in reach. Eq. 6.15 extrapolates confidently from a certain neighbour, so its entropy
    misses that a cell between a soft and a hard measurement is a coin toss: this term is what finds boundaries.
    """
    p = np.asarray(grid.probabilities)
    explored = np.asarray(grid.explored)
    ny, nx, m = p.shape
    vote = np.where(explored[..., None], np.eye(m)[np.argmax(p, axis=-1)], 0.0)
    acc = np.zeros((ny, nx, m))
    for dy in range(-reach, reach + 1):
        for dx in range(-reach, reach + 1):
            if dy == 0 and dx == 0:
                continue
            (cy, cx), (ky, kx) = shift_slices(dy, dx, ny, nx)
            acc[cy, cx] += vote[ky, kx] / (dy * dy + dx * dx)
    total = acc.sum(axis=-1)
    share = np.divide(acc.max(axis=-1), total, out=np.ones_like(total), where=total > 0)
    return np.where(explored, 0.0, 1.0 - share)
