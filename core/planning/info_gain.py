"""The info_gain policy: press where the expected improvement of the reported (post-processed) map is largest.

Two objectives on 2-D maps: "accuracy" (default), the expected number of cells set right
(:mod:`~palpate.core.planning.expected_accuracy`), and "entropy", the expected reduction of the post-processed map's
entropy (:mod:`~palpate.core.planning.entropy_gain`) plus a boundary term. Voxel maps: see
:mod:`~palpate.core.planning.voxel_accuracy`.

A one-press lookahead trusts what the map and the belief already say, and both are confident where a feature
smaller than the pressed cells' spacing, or a wall between two pressed cells, hides. So the accuracy objective
adds what a press can reveal that the map cannot know yet: an *uncovered* cell (no pressed cell among itself and its
four neighbours) is worth about one cell, and the post-processed map's own entropy (normalised to [0, 1]) adds
where eq. 6.15 mixes disagreeing neighbours. Both fade as presses check them; both were chosen on
benchmarks/exploration_families.py's tuning seeds.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.mapping.probability import entropy_unchecked
from palpate.core.planning.entropy_gain import disagreement, expected_gain
from palpate.core.planning.expected_accuracy import expected_accuracy_gain
from palpate.core.planning.incremental import GainCache
from palpate.core.planning.map_views import (
    CERTAIN_FRACTION,
    argmax_cell,
    certain_columns,
    distance_mm,
    explored_plane,
    h_max,
    is_voxel,
    plane_shape,
    postprocess,
    target_depth,
)
from palpate.core.planning.outcomes import outcome_posteriors, outcome_table
from palpate.core.planning.policies import Target
from palpate.core.planning.voxel_accuracy import voxel_accuracy_gain

#: What info_gain scores (see :class:`InfoGain`).
OBJECTIVES = ("accuracy", "entropy")

__all__ = ["OBJECTIVES", "InfoGain", "disagreement", "expected_gain", "uncovered"]


def uncovered(grid) -> np.ndarray:
    """1.0 on a cell that neither it nor any of its 4-neighbours has been pressed, else 0.0, (ny, nx).

    The holes a stride-3 lattice leaves are 2 x 2 blocks of such cells; a feature two cells wide can hide in one
    (eq. 6.15 fills it confidently from the lattice), so one press per hole is worth more than entropy says.
    """
    e = explored_plane(grid)
    near = e.copy()
    near[1:] |= e[:-1]
    near[:-1] |= e[1:]
    near[:, 1:] |= e[:, :-1]
    near[:, :-1] |= e[:, 1:]
    return (~near).astype(float)


@dataclass
class InfoGain:
    """Press the column with the largest expected gain of the post-processed map, plus what a press can reveal
    that the map cannot know yet (module docstring), less an optional travel cost.

    Args:
        memory: the trained haptic memory whose Gaussians predict a press's outcome.
        travel_cost_per_mm: score units (cells set right, or entropy units) subtracted per mm between a cell
            and the last press (0 = none).
        max_depth: voxel maps: deepest press, m (None = the whole column).
        samples_per_material: parameter vectors drawn per material to predict outcomes.
        seed: seed of those draws.
        passes, certainty, lateral: of the post-processing computed when ``post`` is not given (see
            ``Grid2D.postprocessed`` and ``VoxelGrid.postprocessed``); ``lateral`` also tells the voxel accuracy
            objective that a press spreads to its layer's neighbours.
        spread_stride: press every ``spread_stride``-th cell first (an even lattice; < 2 = no lattice).
        objective: "accuracy" (default) = the expected number of cells of the post-processed map whose most
            probable material becomes the true one (2-D:
            :func:`palpate.core.planning.expected_accuracy.expected_accuracy_gain`, under a neighbour-vote belief of
            the truth; voxels: :func:`palpate.core.planning.voxel_accuracy.voxel_accuracy_gain`); "entropy" = the
            expected reduction of the post-processed map's entropy (:func:`expected_gain`), plus the boundary term
            on 2-D maps.
        boundary_weight: "entropy" objective: score added per unit of :func:`disagreement` (0 = pure entropy gain).
        coverage_weight: 2-D maps: score added on :func:`uncovered` cells (None = 1.0 with the accuracy objective,
            i.e. checking a hole is worth about one cell, 0.3 with the entropy one).
        entropy_weight: "accuracy" objective on 2-D maps: score added per unit of the post-processed map's
            normalised entropy (H / log M).
        correlation_mm: "accuracy" objective: correlation length L of the belief, mm (rho(d) = exp(-d / L));
            None = one cell.
        belief_reach: "accuracy" objective: explored cells within this many cells vote in the belief.
        belief_temperature: "accuracy" objective: exponent of each vote, (0, 1] (1 = naive Bayes, overconfident).
        belief_surprise: "accuracy" objective: chance that an unpressed cell is none of what its neighbours say.
        incremental: rescore only the cells a press can have changed (False: every cell, each choice; the choices
            are the same, see :class:`palpate.core.planning.incremental.GainCache`).

    Why accuracy: eq. 6.15 copies a neighbour's distribution with confidence, so the post-processed entropy is
    low exactly where the map is most often wrong (next to a wall); the accuracy objective plans on a separate,
    humbler belief of the truth. The defaults were chosen on the tuning seeds of benchmarks/exploration_families.py;
    its report-only seeds show what they do elsewhere.
    """

    memory: object
    travel_cost_per_mm: float = 0.0
    max_depth: float | None = None
    samples_per_material: int = 6
    seed: int = 0
    passes: int | None = 1
    certainty: float = 1.0
    lateral: bool = False
    spread_stride: int = 3
    boundary_weight: float = 1.0
    coverage_weight: float | None = None
    entropy_weight: float = 2.0
    objective: str = "accuracy"
    correlation_mm: float | None = None
    belief_reach: int = 2
    belief_temperature: float = 0.5
    belief_surprise: float = 0.0
    incremental: bool = True
    _table: tuple[np.ndarray, np.ndarray] | None = field(default=None, init=False, repr=False)
    _cache: GainCache | None = field(default=None, init=False, repr=False)
    _terms: tuple[np.ndarray, np.ndarray, np.ndarray] | None = field(default=None, init=False, repr=False)

    def __post_init__(self) -> None:
        if self.objective not in OBJECTIVES:
            raise ValidationError(f"info_gain objective must be one of {', '.join(OBJECTIVES)}, got "
                                  f"{self.objective!r}")
        if self.correlation_mm is not None and not (np.isfinite(self.correlation_mm) and self.correlation_mm > 0):
            raise ValidationError(f"correlation_mm must be a finite number > 0 mm, got {self.correlation_mm!r}")
        for key in ("coverage_weight", "entropy_weight", "boundary_weight"):
            v = getattr(self, key)
            if v is not None and not (np.isfinite(v) and v >= 0):
                raise ValidationError(f"info_gain {key} must be a finite number >= 0, got {v!r}")
        if self.coverage_weight is None:
            # accuracy: a press that checks an unpressed hole is worth about one cell; entropy: tuned in hartleys
            self.coverage_weight = 1.0 if self.objective == "accuracy" else 0.3

    def _accuracy_mode(self, grid) -> bool:
        return self.objective == "accuracy" and not is_voxel(grid)

    def table(self) -> tuple[np.ndarray, np.ndarray]:
        """The memory's predicted press outcomes, (outcomes (U, M), likelihood (M, U)), computed once."""
        if self._table is None:
            self._table = outcome_table(outcome_posteriors(self.memory, self.samples_per_material, self.seed))
        return self._table

    def correlation_cells(self, grid) -> float:
        return 1.0 if self.correlation_mm is None else self.correlation_mm * 1e-3 / grid.cell_size

    def gains(self, grid, post=None) -> np.ndarray:
        """Expected gain of every column, (ny, nx): cells set right (accuracy objective) or entropy units (entropy
        objective), computed afresh for every cell."""
        post = postprocess(grid, self.passes, self.certainty, self.lateral) if post is None else post
        if is_voxel(grid):
            if self.objective == "accuracy":
                return voxel_accuracy_gain(grid, post, self.table(), self.max_depth, reach=self.belief_reach,
                                           correlation_cells=self.correlation_cells(grid),
                                           temperature=self.belief_temperature, lateral=self.lateral)
            return expected_gain(grid, post, self.table(), self.max_depth)
        if self._accuracy_mode(grid):
            return expected_accuracy_gain(grid, post, self.table(), reach=self.belief_reach,
                                          correlation_cells=self.correlation_cells(grid),
                                          temperature=self.belief_temperature, surprise=self.belief_surprise)
        return expected_gain(grid, post, self.table(), self.max_depth)

    def _cache_for(self, grid) -> GainCache:
        if self._cache is None or not self._cache.fits(grid):
            self._cache = GainCache(self.table(), reach=self.belief_reach,
                                    correlation_cells=self.correlation_cells(grid),
                                    temperature=self.belief_temperature, surprise=self.belief_surprise)
        return self._cache

    def lattice_cell(self, grid, last) -> tuple[int, int] | None:
        """First an even lattice (every ``spread_stride``-th cell, centred) until each of its cells is explored:
        the gain of a blank map is flat, so greedy choices cluster, while a lattice finds every feature at least
        2 strides wide before the boundaries are refined. The nearest unexplored lattice cell to the last press,
        or None once the lattice is done (or ``spread_stride`` < 2)."""
        s = int(self.spread_stride)
        if s < 2:
            return None
        nx, ny = plane_shape(grid)
        ly = np.arange((ny - 1) % s // 2, ny, s)
        lx = np.arange((nx - 1) % s // 2, nx, s)
        free = ~explored_plane(grid)[np.ix_(ly, lx)]
        if not free.any():
            return None
        # only the lattice's cells are looked at: a choice on a huge map stays cheap
        ref = last if last is not None else (0, 0)
        d = np.hypot(lx[None, :] - ref[0], ly[:, None] - ref[1])
        d[~free] = np.inf
        j, i = np.unravel_index(int(np.argmin(d)), d.shape)
        return int(lx[i]), int(ly[j])

    def value_terms(self, grid, post) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(value: gain plus the terms of what a press can reveal (module docstring); the part of it in cells, the
        gain and hole bonus, which the stop rule compares; the columns a press may go to), each (ny, nx)."""
        allowed = None
        if self._accuracy_mode(grid):
            cache = self._cache_for(grid)
            gain = cache.update(grid, post, local=self.incremental)
            return self._accuracy_terms(grid, post, gain, cache.window)
        gain = self.gains(grid, post)
        allowed = ~certain_columns(grid, post, self.max_depth)
        if is_voxel(grid):
            return gain, gain, allowed
        cells = gain + self.coverage_weight * uncovered(grid) if self.coverage_weight > 0 else gain
        value = cells + self.boundary_weight * disagreement(grid) if self.boundary_weight > 0 else cells
        return value, cells, allowed

    def _accuracy_terms(self, grid, post, gain: np.ndarray, window) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Value, cells and allowed columns of the accuracy objective on a 2-D map, refreshed only in ``window``
        (rows, columns) when the gains were (every term is as local as the gain: module
        :mod:`~palpate.core.planning.incremental`), everywhere when ``window`` is None."""
        if window is None or self._terms is None or self._terms[0].shape != gain.shape:
            ny, nx = gain.shape
            self._terms = (np.empty((ny, nx)), np.empty((ny, nx)), np.empty((ny, nx), dtype=bool))
            window = (slice(0, ny), slice(0, nx))
        value, cells, allowed = self._terms
        ys, xs = window
        if ys.stop <= ys.start or xs.stop <= xs.start:
            return value, cells, allowed
        ny, nx = gain.shape
        explored = np.asarray(grid.explored)
        # uncovered() of the window needs the explored cells one row/column beyond it
        cy0, cy1, cx0, cx1 = max(0, ys.start - 1), min(ny, ys.stop + 1), max(0, xs.start - 1), min(nx, xs.stop + 1)
        around = uncovered(_Explored(explored[cy0:cy1, cx0:cx1]))
        unc = around[ys.start - cy0:ys.stop - cy0, xs.start - cx0:xs.stop - cx0]
        h = entropy_unchecked(np.asarray(post.probabilities)[ys, xs], post.base)
        c = gain[ys, xs] + self.coverage_weight * unc if self.coverage_weight > 0 else gain[ys, xs]
        cells[ys, xs] = c
        value[ys, xs] = c + self.entropy_weight / h_max(grid) * h if self.entropy_weight > 0 else c
        allowed[ys, xs] = ~(explored[ys, xs] & (h <= CERTAIN_FRACTION * h_max(grid)))
        return value, cells, allowed

    def next_target(self, grid, post=None, last=None) -> Target | None:
        """The column with the best value less travel cost, or the next lattice cell. Its ``score`` is the best
        expected gain in cells (hole bonus included, travel and the entropy term aside): what the
        ``stop_min_gain`` rule compares. None when every column is explored and certain."""
        post = postprocess(grid, self.passes, self.certainty, self.lateral) if post is None else post
        value, cells, allowed = self.value_terms(grid, post)
        best = float(np.max(np.where(allowed, cells, -np.inf))) if allowed.any() else None
        seed_cell = self.lattice_cell(grid, last)
        if seed_cell is not None:
            return Target(seed_cell[0], seed_cell[1], target_depth(grid, post, *seed_cell, self.max_depth), best)
        score = value
        if self.travel_cost_per_mm > 0:
            score = value - self.travel_cost_per_mm * distance_mm(value.shape, grid.cell_size, last)
        cell = argmax_cell(score, allowed)
        if cell is None:
            return None
        ix, iy = cell
        return Target(ix, iy, target_depth(grid, post, ix, iy, self.max_depth), best)


@dataclass(frozen=True)
class _Explored:
    """Just the explored mask of a map (what :func:`uncovered` reads)."""

    explored: np.ndarray
