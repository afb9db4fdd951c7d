"""Shifting a grid against itself: the neighbour offsets, slices and 3x3 sums the planning code shares.

Grids are indexed [..., iy, ix] (rows, columns last), as :class:`~palpate.core.mapping.grids.Grid2D` after its materials
axis is moved first or dropped.
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


def box3_sum(a: np.ndarray) -> np.ndarray:
    """Sum over each cell's in-grid 3x3 neighbourhood (itself included) on the last two axes."""
    rows = a.copy()
    rows[..., 1:] += a[..., :-1]
    rows[..., :-1] += a[..., 1:]
    out = rows.copy()
    out[..., 1:, :] += rows[..., :-1, :]
    out[..., :-1, :] += rows[..., 1:, :]
    return out
