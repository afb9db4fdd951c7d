"""Where to press next: exploration policies over a map (map in, next cell out).

A policy returns the next cell to press as integer indices (ix, iy) of a 2-D grid (a voxel grid is explored
column by column, so the same indices serve), or None when it has nothing left to propose. Policies hold only
their own small state (a queue, a generator); the map is passed in on each call.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from palpate.core.errors import ValidationError


@dataclass
class Predefined:
    """Press a fixed list of cells, cycling through the list ``repeats`` times (seed 000 Table 6.8: 5 regions x 2).

    Cells are 0-based (ix, iy). The k-th press goes to cells[k % len(cells)], so one "exploration cycle" visits every
    region once, as the seed's Tables 6.9-6.11 report it.
    """

    cells: list[tuple[int, int]]
    repeats: int = 1
    _k: int = field(default=0, init=False)

    def __post_init__(self) -> None:
        if not self.cells:
            raise ValidationError("predefined policy needs at least one cell")
        if self.repeats < 1:
            raise ValidationError(f"predefined policy: repeats must be >= 1, got {self.repeats}")

    @property
    def budget(self) -> int:
        return len(self.cells) * self.repeats

    def next_cell(self, shape: tuple[int, int], explored: np.ndarray | None = None) -> tuple[int, int] | None:
        """Next cell of the list, or None after the last repeat."""
        if self._k >= self.budget:
            return None
        cell = self.cells[self._k % len(self.cells)]
        self._k += 1
        nx, ny = shape
        if not (0 <= cell[0] < nx and 0 <= cell[1] < ny):
            raise ValidationError(f"predefined cell {cell} (0-based) is outside the {nx}x{ny} grid")
        return cell


@dataclass
class Raster:
    """Boustrophedon raster over the grid with a stride (cells), row by row along x."""

    stride: int = 1
    _order: list[tuple[int, int]] | None = field(default=None, init=False)
    _k: int = field(default=0, init=False)

    def next_cell(self, shape: tuple[int, int], explored: np.ndarray | None = None) -> tuple[int, int] | None:
        if self._order is None:
            nx, ny = shape
            s = max(1, int(self.stride))
            off_x, off_y = (nx - 1) % s // 2, (ny - 1) % s // 2
            order = []
            for n, iy in enumerate(range(off_y, ny, s)):
                xs = list(range(off_x, nx, s))
                order.extend((ix, iy) for ix in (xs if n % 2 == 0 else xs[::-1]))
            self._order = order
        if self._k >= len(self._order):
            return None
        self._k += 1
        return self._order[self._k - 1]


@dataclass
class RandomCells:
    """Uniformly random cells, preferring cells not yet explored; seeded."""

    seed: int = 0
    _rng: np.random.Generator | None = field(default=None, init=False)

    def next_cell(self, shape: tuple[int, int], explored: np.ndarray | None = None) -> tuple[int, int] | None:
        if self._rng is None:
            self._rng = np.random.default_rng(self.seed)
        nx, ny = shape
        if explored is not None:
            free = np.argwhere(~np.asarray(explored, dtype=bool))  # rows of (iy, ix)
            if len(free):
                iy, ix = free[self._rng.integers(len(free))]
                return int(ix), int(iy)
        return int(self._rng.integers(nx)), int(self._rng.integers(ny))


def make_policy(name: str, *, cells: list[tuple[int, int]] | None = None, repeats: int = 1, seed: int = 0,
                stride: int = 1):
    """Build a policy by name: "predefined" (needs cells), "raster" or "random"."""
    if name == "predefined":
        return Predefined(list(cells or []), repeats)
    if name == "raster":
        return Raster(stride)
    if name == "random":
        return RandomCells(seed)
    raise ValidationError(f"unknown exploration policy {name!r}; known: predefined, raster, random")
