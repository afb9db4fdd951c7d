"""Where to press next: exploration policies over a map (map in, next target out), and the stop rules.

Every policy has one method, ``next_target(grid, post=None, last=None) -> Target | None``: ``grid`` is the map
as measured (:class:`~palpate.core.mapping.grids.Grid2D` or :class:`~palpate.core.mapping.grids.VoxelGrid`),
``post`` its post-processed version (computed when not given), ``last`` the (ix, iy) of the previous press. A target
is a column of the map, (ix, iy) 0-based, plus for voxel maps the depth to reach (m); None means the policy has
nothing left to propose. Policies hold only their own small state (a queue, a generator, a table of predicted
press outcomes); the map is passed in on each call.

Scores are in entropy units of the map's base (hartleys for base 10). ``max_entropy`` and ``info_gain`` plan on
the post-processed map, because that is the map the run reports: a cell between two certain neighbours is
already estimated, so pressing it first would waste a press.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.planning.map_views import (
    argmax_cell,
    certain_columns,
    column_entropy,
    distance_mm,
    explored_plane,
    plane_shape,
    postprocess,
    target_depth,
)


@dataclass(frozen=True)
class Target:
    """The next press: the map column (ix, iy), 0-based, the depth to reach (m; None = the run's planned depth,
    always None on 2-D maps), the policy's score for it (entropy units; None for list-driven policies) and,
    optionally, the point to press inside the column's cell ((x, y), m; None = the cell's centre)."""

    ix: int
    iy: int
    depth: float | None = None
    score: float | None = None
    xy: tuple[float, float] | None = None


@dataclass
class Predefined:
    """Press a fixed list of cells, cycling through the list ``repeats`` times (seed 000 Table 6.8: 5 regions x 2).

    Cells are 0-based (ix, iy). The k-th press goes to cells[k % len(cells)], so one "exploration cycle" visits every
    region once, as the seed's Tables 6.9-6.11 report it. The list is the protocol being reproduced, so cells are
    revisited even when certain; a cell outside the map is an error, never pressed.
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
        """Presses the list makes: its cells times its repeats."""
        return len(self.cells) * self.repeats

    def next_target(self, grid, post=None, last=None) -> Target | None:
        """Next cell of the list, or None after the last repeat."""
        if self._k >= self.budget:
            return None
        cell = self.cells[self._k % len(self.cells)]
        nx, ny = plane_shape(grid)
        if not (0 <= cell[0] < nx and 0 <= cell[1] < ny):
            raise ValidationError(f"predefined cell {cell[0] + 1},{cell[1] + 1} (1-based column, row) is outside "
                                  f"the {nx}x{ny} grid")
        self._k += 1
        return Target(int(cell[0]), int(cell[1]))


@dataclass
class Raster:
    """Boustrophedon raster over the grid with a stride (cells), row by row along x; skips columns that are
    already explored and certain (e.g. pressed before the raster started)."""

    stride: int = 1
    _order: list[tuple[int, int]] | None = field(default=None, init=False)
    _k: int = field(default=0, init=False)

    def next_target(self, grid, post=None, last=None) -> Target | None:
        """Next cell of the raster that is not already certain, or None at the end of the raster."""
        nx, ny = plane_shape(grid)
        if self._order is None:
            s = max(1, int(self.stride))
            off_x, off_y = (nx - 1) % s // 2, (ny - 1) % s // 2
            order = []
            for n, iy in enumerate(range(off_y, ny, s)):
                xs = list(range(off_x, nx, s))
                order.extend((ix, iy) for ix in (xs if n % 2 == 0 else xs[::-1]))
            self._order = order
        certain = None
        while self._k < len(self._order):
            ix, iy = self._order[self._k]
            self._k += 1
            if certain is None:
                certain = certain_columns(grid, grid, None)
            if not certain[iy, ix]:
                return Target(ix, iy)
        return None


@dataclass
class RandomCells:
    """Uniformly random cells, seeded: first among unexplored columns, then among those not yet certain; None
    once every column is explored and certain."""

    seed: int = 0
    _rng: np.random.Generator | None = field(default=None, init=False)

    def next_target(self, grid, post=None, last=None) -> Target | None:
        """A random unexplored cell (then a random uncertain one), or None when every cell is certain."""
        if self._rng is None:
            self._rng = np.random.default_rng(self.seed)
        free = ~explored_plane(grid)
        if not free.any():
            free = ~certain_columns(grid, grid, None)
        cells = np.argwhere(free)  # rows of (iy, ix)
        if not len(cells):
            return None
        iy, ix = cells[self._rng.integers(len(cells))]
        return Target(int(ix), int(iy))


@dataclass
class MaxEntropy:
    """Press the column with the highest entropy of the post-processed map, less an optional travel cost.

    Args:
        travel_cost_per_mm: entropy units subtracted per mm between a cell and the last press (0 = none).
        max_depth: voxel maps: deepest press, m (None = the whole column).
        passes: eq. 6.15 passes of the post-processing computed when ``post`` is not given (2-D maps).
        certainty: that post-processing's extrapolation certainty (see ``Grid2D.postprocessed``).
        lateral: voxel maps: that post-processing also fills voxels from their layer's neighbours.
    """

    travel_cost_per_mm: float = 0.0
    max_depth: float | None = None
    passes: int | None = 1
    certainty: float = 1.0
    lateral: bool = False

    def next_target(self, grid, post=None, last=None) -> Target | None:
        """The best column, or None when every column is explored and certain."""
        post = postprocess(grid, self.passes, self.certainty, self.lateral) if post is None else post
        h = column_entropy(grid, post, self.max_depth)
        score = h - self.travel_cost_per_mm * distance_mm(h.shape, grid.cell_size, last)
        cell = argmax_cell(score, ~certain_columns(grid, post, self.max_depth))
        if cell is None:
            return None
        ix, iy = cell
        return Target(ix, iy, target_depth(grid, post, ix, iy, self.max_depth), float(score[iy, ix]))
