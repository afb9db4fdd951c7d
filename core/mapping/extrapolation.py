"""Post-processing of material maps from their explored cells (seed 000 eq. 6.15, seed 001 eq. 3 and 5).

Every stage weights a neighbour by 1/H, its inverse entropy, floored at ``h_min`` so a certain neighbour dominates
without a division by zero. Post-processing never changes which cells count as explored: an extrapolated cell is an
estimate, not a measurement.
"""

from __future__ import annotations

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.mapping.calibration import check_unit_interval
from palpate.core.mapping.neighbourhood import box3_sum
from palpate.core.mapping.probability import (
    check_base,
    check_h,
    check_h_min,
    check_mask,
    check_probs,
    entropy_unchecked,
)


def _inverse_entropy_weights(p: np.ndarray, h, base: float, h_min: float) -> np.ndarray:
    """1/H per distribution, with H floored at ``h_min`` so a certain cell gets a huge but finite weight."""
    hh = entropy_unchecked(p, check_base(base)) if h is None else check_h(h, p.shape[:-1])
    return 1.0 / np.maximum(hh, h_min)


def extrapolate_unexplored(p, explored, base: float = 10.0, h_min: float = 1e-12, h=None,
                           passes: int | None = 1, certainty: float = 1.0) -> np.ndarray:
    """Estimate unexplored cells from their explored 8-neighbours, weighted by 1/H (seed 000 eq. 6.15).

    Seed 000 writes the sum over "the eight grid cells surrounding" v, and motivates it as estimating unexplored
    cells "based on the representation of neighbour cells which were explored". Only explored neighbours
    contribute here: an unexplored neighbour is (near) uniform, carries no evidence, and would only pull the
    estimate toward uniform. The pass is a single Jacobi step from the input values: a cell filled here does not
    feed its own neighbours, so nothing spreads further than one cell from explored ones.

    A neighbour with H = 0 (certain) would have infinite weight; H is floored at ``h_min`` so such a neighbour
    dominates (weight 1/h_min) without a division by zero, and several certain neighbours share equally.

    Args:
        p: probabilities, shape (ny, nx, ..., M): the first two axes are the grid plane; any further axes before
            the materials axis (e.g. depth layers of a voxel grid) are treated independently. Rows sum to one.
        explored: boolean mask, shape ``p.shape[:-1]``.
        base: entropy base for the weights.
        h_min: floor on H (in units of ``base``), > 0.
        h: optional entropies to weight by, shape ``p.shape[:-1]`` (default: computed from ``p``); useful when
            ``p`` was rounded for display and the entropies of the unrounded values are known. Used for the
            first pass only; later passes weight the cells they filled by those cells' own entropies.
        passes: how many times to repeat eq. 6.15 (see :func:`extrapolate_passes`): 1 (default) is the seed's
            single step; k > 1 lets each pass treat the cells filled by the previous passes as sources, so an
            estimate reaches k cells from the explored ones; None repeats until no unexplored cell that can be
            reached is left.
        certainty: share of each pass's estimate kept, (0, 1]; the rest is spread uniformly over the materials
            (1 = the seed). A neighbour's material continues into a cell only with some probability (a wall or a
            one-cell feature may lie between), so a calibrated estimate is less certain than its sources, and a
            cell filled k passes away is filled with certainty**k.

    Returns:
        A new array: unexplored cells within ``passes`` cells (8-connected, in-grid) of an explored cell get the
        weighted mean of their already-known neighbours; explored cells and unexplored cells further away keep
        their values.
    """
    arr = check_probs(p, "p", min_ndim=3, normalised=True)
    mask = check_mask(explored, arr.shape[:-1], "explored")
    n = check_passes(passes)
    h_min = check_h_min(h_min)
    w = _inverse_entropy_weights(arr, h, base, h_min)
    return extrapolate_passes(arr, mask, w, n, check_base(base), h_min, check_certainty(certainty))


def check_certainty(certainty: float) -> float:
    return check_unit_interval(certainty, "extrapolation certainty")


def check_passes(passes) -> int | None:
    if passes is None:
        return None
    if isinstance(passes, bool) or not isinstance(passes, (int, np.integer)) or passes < 1:
        raise ValidationError(f"passes must be an integer >= 1 or None (until every reachable cell is filled), "
                              f"got {passes!r}")
    return int(passes)


def extrapolate_passes(arr: np.ndarray, mask: np.ndarray, w: np.ndarray, passes: int | None, base: float,
                        h_min: float, certainty: float = 1.0) -> np.ndarray:
    """Eq. 6.15 repeated: pass k fills the unfilled cells next to a cell known after pass k - 1 (explored or
    filled), each weighted by 1/H of its current values; stops after ``passes`` passes or when a pass fills
    nothing. One pass is exactly :func:`extrapolate_plane`."""
    out = extrapolate_plane(arr, mask, w, certainty)
    if passes == 1:
        return out
    known = mask | (box3_sum(mask.astype(float), axes=(0, 1)) > 0)
    k = 1
    while passes is None or k < passes:
        if known.all():
            break
        grown = known | (box3_sum(known.astype(float), axes=(0, 1)) > 0)
        if not (grown & ~known).any():
            break  # the remaining cells have no known cell anywhere in their plane
        w = 1.0 / np.maximum(entropy_unchecked(out, base), h_min)
        out, known = extrapolate_plane(out, known, w, certainty), grown
        k += 1
    return out


def extrapolate_plane(arr: np.ndarray, mask: np.ndarray, w: np.ndarray, certainty: float = 1.0) -> np.ndarray:
    """Kernel of :func:`extrapolate_unexplored` on validated arrays; ``w`` = 1/H per cell; each estimate keeps
    ``certainty`` of itself and spreads the rest uniformly."""
    w = np.where(mask, w, 0.0)
    # Unexplored cells have zero weight, so for them the 3x3 box sum is exactly the sum over the 8 neighbours
    # (no subtraction of a huge certain centre, no cancellation); explored cells are not written. Off-grid
    # neighbours never enter the sums, which is the edge/corner rule.
    acc_num = box3_sum(w[..., None] * arr, axes=(0, 1))
    acc_den = box3_sum(w, axes=(0, 1))
    target = ~mask & (acc_den > 0)
    out = arr.copy()
    np.divide(acc_num, acc_den[..., None], out=out, where=target[..., None])
    if certainty != 1.0:
        m = arr.shape[-1]
        out[target] = certainty * out[target] + (1.0 - certainty) / m
    return out


def vertical_gaps(mask: np.ndarray) -> np.ndarray:
    """Unexplored voxels with an explored voxel directly above and directly below (depth = last axis)."""
    gaps = np.zeros_like(mask)
    gaps[..., 1:-1] = ~mask[..., 1:-1] & mask[..., :-2] & mask[..., 2:]
    return gaps


def extrapolate_vertical(p, explored, base: float = 10.0, h_min: float = 1e-12, h=None) -> np.ndarray:
    """Fill unexplored voxels lying between an explored upper and lower neighbour (seed 001 eq. 3).

    Each such voxel becomes the 1/H-weighted mean of the voxel directly above and the one directly below. Gaps
    of two or more voxels, and unexplored voxels at the top or bottom of a column, are left as they are.

    Args:
        p: probabilities, shape (..., nz, M), e.g. (nx, ny, nz, M); depth index 0 is the surface (top) and
            grows downward. Rows sum to one.
        explored: boolean mask, shape ``p.shape[:-1]``.
        base: entropy base for the weights.
        h_min: floor on H, > 0 (a certain neighbour dominates without dividing by zero).
        h: optional entropies to weight by, shape ``p.shape[:-1]`` (default: computed from ``p``).

    Returns:
        A new array with the gaps filled; every other voxel unchanged.
    """
    arr = check_probs(p, "p", min_ndim=2, normalised=True)
    mask = check_mask(explored, arr.shape[:-1], "explored")
    w = _inverse_entropy_weights(arr, h, base, check_h_min(h_min))
    return extrapolate_vertical_kernel(arr, mask, w)


def _pair_mean(arr: np.ndarray, w: np.ndarray, idx_a: tuple, idx_b: tuple) -> np.ndarray:
    """1/H-weighted mean of the distributions at two index sets (each a tuple of index arrays)."""
    wa, wb = w[idx_a][:, None], w[idx_b][:, None]
    return (wa * arr[idx_a] + wb * arr[idx_b]) / (wa + wb)


def extrapolate_vertical_kernel(arr: np.ndarray, mask: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Kernel of :func:`extrapolate_vertical` on validated arrays; only the gap voxels are computed."""
    out = arr.copy()
    idx = np.nonzero(vertical_gaps(mask))
    if idx[0].size:
        up = idx[:-1] + (idx[-1] - 1,)
        down = idx[:-1] + (idx[-1] + 1,)
        out[idx] = _pair_mean(arr, w, up, down)
    return out


def verify_continuity(p, explored, base: float = 10.0, h_min: float = 1e-12, h=None) -> np.ndarray:
    """Local vertical continuity verification (seed 001 eq. 5).

    Every explored voxel whose lower neighbour is also explored becomes the 1/H-weighted mean of itself and that
    lower neighbour. All voxels are computed from the original values (a Jacobi step, not a sweep that reuses
    already-updated voxels): this is what reproduces seed 001 Table 2's continuity column. The bottom explored
    voxel of a run (no explored voxel below it) is left as it is.

    Args:
        p: probabilities, shape (..., nz, M); depth index 0 is the surface. Rows sum to one.
        explored: boolean mask, shape ``p.shape[:-1]``.
        base: entropy base for the weights.
        h_min: floor on H, > 0.
        h: optional entropies to weight by, shape ``p.shape[:-1]`` (default: computed from ``p``).

    Returns:
        A new array; unexplored voxels unchanged.
    """
    arr = check_probs(p, "p", min_ndim=2, normalised=True)
    mask = check_mask(explored, arr.shape[:-1], "explored")
    w = _inverse_entropy_weights(arr, h, base, check_h_min(h_min))
    return verify_continuity_kernel(arr, mask, w)


def verify_continuity_kernel(arr: np.ndarray, mask: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Kernel of :func:`verify_continuity` on validated arrays; reads only ``arr`` (Jacobi), writes a copy."""
    out = arr.copy()
    pair = np.zeros_like(mask)
    pair[..., :-1] = mask[..., :-1] & mask[..., 1:]
    idx = np.nonzero(pair)
    if idx[0].size:
        out[idx] = _pair_mean(arr, w, idx, idx[:-1] + (idx[-1] + 1,))
    return out
