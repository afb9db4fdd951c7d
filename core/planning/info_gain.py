"""The info_gain policy: press where the expected improvement of the reported (post-processed) map is largest.

Two objectives on 2-D maps: "accuracy" (default), the expected number of cells set right
(:mod:`~palpate.core.planning.expected_accuracy`), and "entropy", the expected reduction of the post-processed map's
entropy (:func:`expected_gain`) plus a boundary term. Voxel maps use the entropy gain.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.mapping.neighbourhood import NEIGHBOURS_8, box3_sum, shift_slices
from palpate.core.mapping.probability import entropy_unchecked
from palpate.core.planning.expected_accuracy import expected_accuracy_gain
from palpate.core.planning.map_views import (
    H_MIN,
    argmax_cell,
    certain_columns,
    distance_mm,
    explored_plane,
    is_voxel,
    layers_reached,
    plane_shape,
    postprocess,
    target_depth,
)
from palpate.core.planning.outcomes import outcome_posteriors, outcome_table
from palpate.core.planning.policies import Target

#: What info_gain scores on 2-D maps (see :class:`InfoGain`).
OBJECTIVES = ("accuracy", "entropy")


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
    """Press the column with the largest expected reduction of the post-processed map's entropy, less an
    optional travel cost (see :func:`expected_gain`).

    Args:
        memory: the trained haptic memory whose Gaussians predict a press's outcome.
        travel_cost_per_mm: score units (cells set right, or entropy units) subtracted per mm between a cell
            and the last press (0 = none).
        max_depth: voxel maps: deepest press, m (None = the whole column).
        samples_per_material: parameter vectors drawn per material to predict outcomes.
        seed: seed of those draws.
        passes: eq. 6.15 passes of the post-processing computed when ``post`` is not given (2-D maps).
        spread_stride: press every ``spread_stride``-th cell first (an even lattice; < 2 = no lattice).
        objective: what a press is expected to gain on 2-D maps: "accuracy" (default) = the expected number of
            cells of the post-processed map whose most probable material becomes the true one
            (:func:`palpate.core.planning.expected_accuracy.expected_accuracy_gain`, under a neighbour-vote belief of
            the truth); "entropy" = the expected reduction of the post-processed map's entropy
            (:func:`expected_gain`) plus the boundary term. Voxel maps always use the entropy gain.
        boundary_weight: "entropy" objective: score added per unit of :func:`disagreement` (0 = pure entropy gain).
        coverage_weight: 2-D maps: score added on :func:`uncovered` cells (0 = none; None = 1.0 with the
            accuracy objective, i.e. checking a hole is worth about one cell, 0.3 with the entropy one).
        correlation_mm: "accuracy" objective: correlation length of the belief, mm (about the size of the
            features to find; rho(d) = exp(-d / L)).
        belief_reach: "accuracy" objective: explored cells within this many cells vote in the belief.
        belief_temperature: "accuracy" objective: exponent of each vote, (0, 1] (1 = naive Bayes, overconfident).

    benchmarks/exploration.py (24 seeded scenes, 15 mm cells), median presses to 95% accuracy relative to raster:
    entropy objective 0.40 (lattice + boundary + coverage; 0.45 without them), accuracy objective: see
    benchmarks/exploration.py's output, quoted in the issue notes. Why accuracy: eq. 6.15 copies a neighbour's
    distribution with confidence, so the post-processed entropy is low exactly where the map is most often wrong
    (next to a wall); the accuracy objective plans on a separate, humbler belief of the truth.
    """

    memory: object
    travel_cost_per_mm: float = 0.0
    max_depth: float | None = None
    samples_per_material: int = 6
    seed: int = 0
    passes: int | None = 1
    spread_stride: int = 3
    boundary_weight: float = 1.0
    coverage_weight: float | None = None
    objective: str = "accuracy"
    correlation_mm: float = 60.0
    belief_reach: int = 4
    belief_temperature: float = 0.5
    _table: tuple[np.ndarray, np.ndarray] | None = field(default=None, init=False, repr=False)

    def __post_init__(self) -> None:
        if self.objective not in OBJECTIVES:
            raise ValidationError(f"info_gain objective must be one of {', '.join(OBJECTIVES)}, got "
                                  f"{self.objective!r}")
        if not (np.isfinite(self.correlation_mm) and self.correlation_mm > 0):
            raise ValidationError(f"correlation_mm must be a finite number > 0 mm, got {self.correlation_mm!r}")
        if self.coverage_weight is None:
            # accuracy: a press that checks an unpressed hole is worth about one cell; entropy: tuned in hartleys
            self.coverage_weight = 1.0 if self.objective == "accuracy" else 0.3

    def _accuracy_mode(self, grid) -> bool:
        return self.objective == "accuracy" and not is_voxel(grid)

    def gains(self, grid, post=None) -> np.ndarray:
        """Expected gain of every column, (ny, nx): cells set right (accuracy objective, 2-D maps) or entropy
        units (entropy objective, voxel maps)."""
        if self._table is None:
            self._table = outcome_table(outcome_posteriors(self.memory, self.samples_per_material, self.seed))
        post = postprocess(grid, self.passes) if post is None else post
        if self._accuracy_mode(grid):
            return expected_accuracy_gain(grid, post, self._table, reach=self.belief_reach,
                                          correlation_cells=self.correlation_mm * 1e-3 / grid.cell_size,
                                          temperature=self.belief_temperature)
        return expected_gain(grid, post, self._table, self.max_depth)

    def _spread_cell(self, grid, last) -> tuple[int, int] | None:
        """First an even lattice (every ``spread_stride``-th cell, centred) until each of its cells is explored:
        the entropy gain of a blank map is flat, so greedy choices cluster, while a lattice finds every feature
        at least 2 strides wide before the boundaries are refined. The nearest unexplored lattice cell to the
        last press, or None once the lattice is done (or ``spread_stride`` < 2)."""
        s = int(self.spread_stride)
        if s < 2:
            return None
        nx, ny = plane_shape(grid)
        lat = np.zeros((ny, nx), dtype=bool)
        lat[(ny - 1) % s // 2::s, (nx - 1) % s // 2::s] = True
        free = lat & ~explored_plane(grid)
        if not free.any():
            return None
        d = distance_mm((ny, nx), 1.0, last if last is not None else (0, 0))
        return argmax_cell(-d, free)

    def next_target(self, grid, post=None, last=None) -> Target | None:
        """The column with the best value (gain plus the boundary and coverage terms) less travel cost; its
        ``score`` is the best value travel aside (what the ``stop_min_gain`` rule compares). None when every
        column is explored and certain."""
        post = postprocess(grid, self.passes) if post is None else post
        gain = self.gains(grid, post)
        seed_cell = self._spread_cell(grid, last)
        if seed_cell is not None:
            return Target(seed_cell[0], seed_cell[1], target_depth(grid, post, *seed_cell, self.max_depth),
                          float(np.max(gain)))
        value = gain
        if self.boundary_weight > 0 and not is_voxel(grid) and not self._accuracy_mode(grid):
            value = value + self.boundary_weight * disagreement(grid)
        if self.coverage_weight > 0 and not is_voxel(grid):
            value = value + self.coverage_weight * uncovered(grid)
        score = value - self.travel_cost_per_mm * distance_mm(gain.shape, grid.cell_size, last)
        allowed = ~certain_columns(grid, post, self.max_depth)
        cell = argmax_cell(score, allowed)
        if cell is None:
            return None
        ix, iy = cell
        # The stop rule asks whether any cell is still worth a press, travel aside: report the best value
        # (gain plus the boundary/coverage terms: an unpressed hole where a feature can hide is worth a press).
        best = float(np.max(np.where(allowed, value, -np.inf)))
        return Target(ix, iy, target_depth(grid, post, ix, iy, self.max_depth), best)
