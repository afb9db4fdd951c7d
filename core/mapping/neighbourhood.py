"""Shifting a grid against itself: the neighbour offsets, slices and 3x3 sums that post-processing and planning share.

Planning planes are indexed [..., iy, ix] (rows, columns last); a map's probabilities are (ny, nx, M), whose plane
axes are (0, 1).
"""

from __future__ import annotations

import numpy as np

#: The 8 neighbours of a cell as (dy, dx): the reach of one pass of seed 000 eq. 6.15.
NEIGHBOURS_8 = tuple((dy, dx) for dy in (-1, 0, 1) for dx in (-1, 0, 1) if (dy, dx) != (0, 0))


def shift_slices(dy: int, dx: int, ny: int, nx: int) -> tuple[tuple[slice, slice], tuple[slice, slice]]:
    """Slices of cells c and of c + (dy, dx), both inside the grid (empty when the offset exceeds the grid)."""
    cand = (slice(max(0, -dy), max(0, ny - max(0, dy))), slice(max(0, -dx), max(0, nx - max(0, dx))))
    nb = (slice(max(0, dy), max(0, ny - max(0, -dy))), slice(max(0, dx), max(0, nx - max(0, -dx))))
    return cand, nb


def box3_sum(a: np.ndarray, axes: tuple[int, int] = (-2, -1)) -> np.ndarray:
    """Sum over each cell's in-grid 3x3 neighbourhood (itself included) on two axes of ``a``, separably.

    Off-grid neighbours contribute nothing, which is the edge and corner rule of seed 000 eq. 6.15. ``axes`` are
    the (row, column) axes: the last two for planning planes, (0, 1) for a map's (ny, nx, M) probabilities.
    """
    out = a.copy()
    # Columns first, then rows: the order of the additions fixes the rounding, and maps must not change with it.
    for ax in reversed(axes):
        src = out.copy()
        lo = [slice(None)] * a.ndim
        hi = [slice(None)] * a.ndim
        lo[ax], hi[ax] = slice(1, None), slice(None, -1)
        out[tuple(lo)] += src[tuple(hi)]
        out[tuple(hi)] += src[tuple(lo)]
    return out
