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


def _given_weights(p: np.ndarray, h, h_min: float) -> np.ndarray | None:
    """1/H of the given entropies ``h`` (H floored at ``h_min``), or None to weight by ``p``'s own entropies."""
    return None if h is None else 1.0 / np.maximum(check_h(h, p.shape[:-1]), h_min)


def _inverse_entropy_weights(p: np.ndarray, h, base: float, h_min: float) -> np.ndarray:
    """1/H per distribution, with H floored at ``h_min`` so a certain cell gets a huge but finite weight."""
    w = _given_weights(p, h, h_min)
    return inverse_entropy(p, check_base(base), h_min) if w is None else w


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
    return extrapolate_passes(arr, mask, _given_weights(arr, h, h_min), n, check_base(base), h_min,
                              check_certainty(certainty))


def check_certainty(certainty: float) -> float:
    return check_unit_interval(certainty, "extrapolation certainty")


def check_passes(passes) -> int | None:
    if passes is None:
        return None
    if isinstance(passes, bool) or not isinstance(passes, (int, np.integer)) or passes < 1:
        raise ValidationError(f"passes must be an integer >= 1 or None (until every reachable cell is filled), "
                              f"got {passes!r}")
    return int(passes)


def extrapolate_passes(arr: np.ndarray, mask: np.ndarray, w: np.ndarray | None, passes: int | None, base: float,
                        h_min: float, certainty: float = 1.0) -> np.ndarray:
    """Eq. 6.15 repeated: pass k fills the unfilled cells next to a cell known after pass k - 1 (explored or
    filled), each weighted by 1/H of its current values; stops after ``passes`` passes or when a pass fills
    nothing. One pass is exactly :func:`extrapolate_plane` (weights ``w``, or None: 1/H of ``arr``), each keeping
    ``certainty`` of its estimates."""
    out = extrapolate_plane(arr, mask, w, base=base, h_min=h_min, certainty=certainty)
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
        out, known = extrapolate_plane(out, known, base=base, h_min=h_min, certainty=certainty), grown
        k += 1
    return out


def inverse_entropy(p: np.ndarray, base: float, h_min: float) -> np.ndarray:
    """1/H per distribution of validated ``p``, H floored at ``h_min`` (a certain cell: huge but finite)."""
    h = entropy_unchecked(p, base)
    np.maximum(h, h_min, out=h)
    return np.divide(1.0, h, out=h)


def extrapolate_plane(arr: np.ndarray, mask: np.ndarray, w: np.ndarray | None = None, *, base: float = 10.0,
                      h_min: float = 1e-12, certainty: float = 1.0) -> np.ndarray:
    """Kernel of :func:`extrapolate_unexplored` on validated arrays: one pass of eq. 6.15 over the plane axes
    (0, 1); ``w`` = 1/H per cell, or None to weight by :func:`inverse_entropy` of ``arr`` (``base``, ``h_min``);
    each estimate keeps ``certainty`` of itself and spreads the rest uniformly over the materials.

    The plane is worked through in blocks of rows small enough to stay in the CPU cache, each cell's values (its
    depth layers and materials) side by side in one row, so nothing loops over the short materials axis. Sums
    follow :func:`~palpate.core.mapping.neighbourhood.box3_sum`'s order, so the floats are the same.
    """
    n0, n1, m = arr.shape[0], arr.shape[1], arr.shape[-1]
    k = arr[0, 0].size if arr.size else m  # values per cell
    kw = k // m  # weights per cell
    out = np.empty_like(arr)
    src = arr.reshape(n0, n1 * k)
    dst = out.reshape(n0, n1 * k)
    cells = mask.reshape(n0, -1)
    # Buffers for a block and a row of neighbours each side, with zeros around: off-grid neighbours never enter
    # the sums, which is the edge/corner rule. Allocated once, so no block pays for fresh memory.
    rows_max = min(_BLOCK_ROWS, n0) + 2
    num_pad, w_pad = np.zeros((rows_max + 2, (n1 + 2) * k)), np.zeros((rows_max + 2, (n1 + 2) * kw))
    num_cols, w_cols = np.empty((rows_max + 2, n1 * k)), np.empty((rows_max + 2, n1 * kw))
    for r0 in range(0, n0, _BLOCK_ROWS):
        r1 = min(r0 + _BLOCK_ROWS, n0)
        lo, hi = max(r0 - 1, 0), min(r1 + 1, n0)
        rows = hi - lo
        num_pad[rows + 1] = 0.0  # below the grid's last row (or not read)
        w_pad[rows + 1] = 0.0
        # Unexplored cells weigh nothing, so for them the 3x3 box sum is exactly the sum over the 8 neighbours
        # (no subtraction of a huge certain centre, no cancellation); explored cells are not written.
        wb = w_pad[1:rows + 1, kw:kw + n1 * kw]
        w_all = inverse_entropy(arr[lo:hi], base, h_min) if w is None else w[lo:hi]
        np.multiply(w_all.reshape(rows, -1), cells[lo:hi], out=wb)  # where(explored, w, 0): w is finite, >= 0
        np.multiply(np.repeat(wb, m, axis=1), src[lo:hi], out=num_pad[1:rows + 1, k:k + n1 * k])
        num = _box_rows(num_pad, num_cols, k, rows, r0 - lo, r1 - lo)
        den = _box_rows(w_pad, w_cols, kw, rows, r0 - lo, r1 - lo)
        target = ~cells[r0:r1] & (den > 0)
        num /= np.repeat(np.where(target, den, 1.0), m, axis=1)
        if certainty != 1.0:
            num *= certainty
            num += (1.0 - certainty) / m
        block = dst[r0:r1]
        np.copyto(block, src[r0:r1])
        np.copyto(block, num, where=np.repeat(target, m, axis=1))
    return out


#: Rows per block of :func:`extrapolate_plane`: a block's few buffers stay in a core's cache on a 1000-cell row.
_BLOCK_ROWS = 32


def _box_rows(pad: np.ndarray, cols: np.ndarray, k: int, rows: int, a0: int, a1: int) -> np.ndarray:
    """3x3 box sums of rows a0:a1 of the block held in ``pad`` (its first ``rows`` + 2 rows, zeros around, cells
    of k values side by side), added in :func:`~palpate.core.mapping.neighbourhood.box3_sum`'s order: columns
    then rows, each centre + one side, then + the other. ``cols`` takes the column sums."""
    width = pad.shape[1] - 2 * k
    h = cols[:rows + 2]
    np.add(pad[:rows + 2, k:k + width], pad[:rows + 2, :width], out=h)
    h += pad[:rows + 2, 2 * k:]
    v = h[a0 + 1:a1 + 1] + h[a0:a1]
    v += h[a0 + 2:a1 + 2]
    return v


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
