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

import math
from dataclasses import dataclass, field

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.mapping.neighbourhood import NEIGHBOURS_8, box3_sum, shift_slices
from palpate.core.planning.expected_accuracy import expected_accuracy_gain

#: A cell counts as "certain" when its entropy is at most this fraction of the largest possible (log_b M).
CERTAIN_FRACTION = 0.05
#: Same floor on entropies as the maps' post-processing: certain neighbours dominate without a division by zero.
_H_MIN = 1e-12
_TIE = 1e-9


@dataclass(frozen=True)
class Target:
    """The next press: the map column (ix, iy), 0-based, the depth to reach (m; None = the run's planned depth,
    always None on 2-D maps) and the policy's score for it (entropy units; None for list-driven policies)."""

    ix: int
    iy: int
    depth: float | None = None
    score: float | None = None


# --------------------------------------------------------------------------------------------------------------
# map views shared by the policies


def _is_voxel(grid) -> bool:
    return len(grid.probabilities.shape) == 4


def _plane_shape(grid) -> tuple[int, int]:
    """(nx, ny) of the columns a policy chooses among."""
    return tuple(int(v) for v in grid.shape[:2])  # type: ignore[return-value]


def _entropy(p: np.ndarray, base: float) -> np.ndarray:
    """Entropy along the last axis of already-valid probabilities (no checks: this is the hot path)."""
    plogp = np.log(p, out=np.zeros_like(p), where=p > 0)
    plogp *= p
    h = plogp.sum(axis=-1)
    h *= -1.0 / math.log(base)
    return np.maximum(h, 0.0)


def _h_max(grid) -> float:
    return math.log(len(grid.materials)) / math.log(grid.base)


def _layers(grid, max_depth: float | None) -> int:
    """Voxel layers a press to ``max_depth`` (m) reaches (all of them when None)."""
    nz = grid.shape[2]
    if max_depth is None:
        return nz
    return grid.layers_reached(max_depth)


def _post(grid, passes: int | None = 1):
    """The post-processed map the run reports: eq. 6.15 repeated ``passes`` times on a 2-D map; a voxel map's
    own post-processing (``passes`` does not apply to it)."""
    return grid.postprocessed() if _is_voxel(grid) else grid.postprocessed(passes=passes)


def column_entropy(grid, post=None, max_depth: float | None = None) -> np.ndarray:
    """Entropy a press could act on per column, shape (ny, nx): the cell's entropy on a 2-D map, the sum over the
    reachable voxels of a column on a voxel map; of ``post`` (the post-processed map) when given."""
    m = grid if post is None else post
    h = _entropy(np.asarray(m.probabilities), m.base)
    if _is_voxel(grid):
        return h[:, :, :_layers(grid, max_depth)].sum(axis=-1).T
    return h


def _certain(grid, post, max_depth) -> np.ndarray:
    """(ny, nx) mask of columns that are explored and certain in the post-processed map."""
    h = column_entropy(grid, post, max_depth)
    n = _layers(grid, max_depth) if _is_voxel(grid) else 1
    explored = _explored2d(grid)
    return explored & (h <= CERTAIN_FRACTION * _h_max(grid) * n)


def _explored2d(grid) -> np.ndarray:
    e = np.asarray(grid.explored)
    return e.any(axis=2).T if e.ndim == 3 else e


def _distance_mm(shape_yx: tuple[int, int], cell_size: float, last) -> np.ndarray:
    """Distance of every cell centre from the last press's cell, mm, shape (ny, nx)."""
    ny, nx = shape_yx
    if last is None:
        return np.zeros((ny, nx))
    iy, ix = np.mgrid[0:ny, 0:nx]
    return np.hypot(ix - last[0], iy - last[1]) * cell_size * 1e3


def _argmax_cell(score: np.ndarray, allowed: np.ndarray) -> tuple[int, int] | None:
    """(ix, iy) of the best allowed cell; ties go to the first in row order (deterministic)."""
    if not allowed.any():
        return None
    s = np.where(allowed, score, -np.inf)
    iy, ix = np.unravel_index(int(np.argmax(s)), s.shape)
    return int(ix), int(iy)


def _target_depth(grid, post, ix: int, iy: int, max_depth: float | None) -> float | None:
    """Voxel maps: press down to the bottom of the deepest reachable voxel that is not certain yet (m), so a
    column whose deep part is known is not pressed deeper than needed; None on 2-D maps."""
    if not _is_voxel(grid):
        return None
    k = _layers(grid, max_depth)
    h = _entropy(np.asarray(post.probabilities[ix, iy, :k]), post.base)
    uncertain = np.flatnonzero(h > CERTAIN_FRACTION * _h_max(grid))
    layers = int(uncertain[-1]) + 1 if uncertain.size else k
    depth = layers * grid.cell_size
    return depth if max_depth is None else min(depth, max_depth)


# --------------------------------------------------------------------------------------------------------------
# list-driven policies


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
        return len(self.cells) * self.repeats

    def next_target(self, grid, post=None, last=None) -> Target | None:
        """Next cell of the list, or None after the last repeat."""
        if self._k >= self.budget:
            return None
        cell = self.cells[self._k % len(self.cells)]
        nx, ny = _plane_shape(grid)
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
        nx, ny = _plane_shape(grid)
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
                certain = _certain(grid, grid, None)
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
        if self._rng is None:
            self._rng = np.random.default_rng(self.seed)
        free = ~_explored2d(grid)
        if not free.any():
            free = ~_certain(grid, grid, None)
        cells = np.argwhere(free)  # rows of (iy, ix)
        if not len(cells):
            return None
        iy, ix = cells[self._rng.integers(len(cells))]
        return Target(int(ix), int(iy))


# --------------------------------------------------------------------------------------------------------------
# map-driven policies


@dataclass
class MaxEntropy:
    """Press the column with the highest entropy of the post-processed map, less an optional travel cost.

    Args:
        travel_cost_per_mm: entropy units subtracted per mm between a cell and the last press (0 = none).
        max_depth: voxel maps: deepest press, m (None = the whole column).
        passes: eq. 6.15 passes of the post-processing computed when ``post`` is not given (2-D maps).
    """

    travel_cost_per_mm: float = 0.0
    max_depth: float | None = None
    passes: int | None = 1

    def next_target(self, grid, post=None, last=None) -> Target | None:
        """The best column, or None when every column is explored and certain."""
        post = _post(grid, self.passes) if post is None else post
        h = column_entropy(grid, post, self.max_depth)
        score = h - self.travel_cost_per_mm * _distance_mm(h.shape, grid.cell_size, last)
        cell = _argmax_cell(score, ~_certain(grid, post, self.max_depth))
        if cell is None:
            return None
        ix, iy = cell
        return Target(ix, iy, _target_depth(grid, post, ix, iy, self.max_depth), float(score[iy, ix]))


def outcome_posteriors(memory, samples_per_material: int = 6, seed: int = 0) -> np.ndarray:
    """Predicted per-press posteriors, shape (M, S, M): row [t, s] is the memory's posterior for the s-th
    parameter vector drawn from material t's Gaussians N(mu_N, Sigma_N) x N(mu_A, Sigma_A) (seed 000 eq. 6.13-6.14).

    Seeded, so a run is deterministic.
    """
    if isinstance(samples_per_material, bool) or not isinstance(samples_per_material, (int, np.integer)) \
            or samples_per_material < 1:
        raise ValidationError(f"samples_per_material must be an integer >= 1, got {samples_per_material!r}")
    if getattr(memory, "means_N", None) is None:
        raise ValidationError("info_gain needs a trained haptic memory (means and covariances per material)")
    rng = np.random.default_rng(seed)
    m = len(memory.materials)
    draws = []
    for t in range(m):
        n = rng.multivariate_normal(memory.means_N[t], memory.covs_N[t], samples_per_material)
        a = rng.multivariate_normal(memory.means_A[t], memory.covs_A[t], samples_per_material)
        draws.append(np.hstack([n, a]))
    q = memory.predict_proba(np.vstack(draws)).reshape(m, samples_per_material, m)
    return np.asarray(q, dtype=float)


def outcome_table(q: np.ndarray, resolution: float = 0.02) -> tuple[np.ndarray, np.ndarray]:
    """Merge predicted outcomes that differ by less than ``resolution`` in every probability.

    A well-separated memory predicts nearly the same posterior for most draws of a material; merging them keeps
    the expectation the same to that resolution and makes :func:`expected_gain` several times cheaper.

    Args:
        q: (M, S, M) from :func:`outcome_posteriors`.
        resolution: probability bin width.

    Returns:
        (outcomes (U, M): the mean posterior of each merged group, rows summing to 1;
         likelihood (M, U): fraction of material t's draws that fell in group u, rows summing to 1).
    """
    q = np.asarray(q, dtype=float)
    if q.ndim != 3 or q.shape[0] != q.shape[2] or q.shape[1] < 1:
        raise ValidationError(f"outcome posteriors must have shape (M, S, M), got {q.shape}")
    if not np.all(np.isfinite(q)) or (q < 0).any():
        raise ValidationError("outcome posteriors must be finite and non-negative")
    m, s, _ = q.shape
    flat = q.reshape(m * s, m)
    _, group = np.unique(np.round(flat / resolution), axis=0, return_inverse=True)
    group = group.reshape(-1)
    u = int(group.max()) + 1
    outcomes = np.zeros((u, m))
    np.add.at(outcomes, group, flat)
    outcomes /= np.bincount(group, minlength=u)[:, None]
    outcomes /= outcomes.sum(axis=1, keepdims=True)
    likelihood = np.zeros((m, u))
    np.add.at(likelihood, (np.repeat(np.arange(m), s), group), 1.0 / s)
    return outcomes, likelihood


def _entropy0(p: np.ndarray, log_base: float) -> np.ndarray:
    """Entropy over the FIRST axis (materials first: the sum is a few whole-array adds, the hot path's layout)."""
    plogp = np.log(p, out=np.zeros_like(p), where=p > 0)
    plogp *= p
    h = plogp.sum(axis=0)
    h *= -1.0 / log_base
    return np.maximum(h, 0.0, out=h)


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
    h_new = _entropy0(new, lb)  # (U, ny, nx)
    h_post = _entropy0(pp, lb)  # (ny, nx)
    gain = h_post - (w_o * h_new).sum(axis=0)
    if not spread:
        return gain
    ny, nx = h_post.shape
    w_raw = np.where(explored, 1.0 / np.maximum(_entropy0(pr, lb), _H_MIN), 0.0)
    c_old = w_raw * pr  # each explored cell's term of eq. 6.15 (zero if unexplored)
    num_all = box3_sum(c_old)
    w_new = 1.0 / np.maximum(h_new, _H_MIN)
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
    if _is_voxel(grid):
        k = _layers(grid, max_depth)
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
    e = _explored2d(grid)
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
        return self.objective == "accuracy" and not _is_voxel(grid)

    def gains(self, grid, post=None) -> np.ndarray:
        """Expected gain of every column, (ny, nx): cells set right (accuracy objective, 2-D maps) or entropy
        units (entropy objective, voxel maps)."""
        if self._table is None:
            self._table = outcome_table(outcome_posteriors(self.memory, self.samples_per_material, self.seed))
        post = _post(grid, self.passes) if post is None else post
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
        nx, ny = _plane_shape(grid)
        lat = np.zeros((ny, nx), dtype=bool)
        lat[(ny - 1) % s // 2::s, (nx - 1) % s // 2::s] = True
        free = lat & ~_explored2d(grid)
        if not free.any():
            return None
        d = _distance_mm((ny, nx), 1.0, last if last is not None else (0, 0))
        return _argmax_cell(-d, free)

    def next_target(self, grid, post=None, last=None) -> Target | None:
        """The column with the best value (gain plus the boundary and coverage terms) less travel cost; its
        ``score`` is the best value travel aside (what the ``stop_min_gain`` rule compares). None when every
        column is explored and certain."""
        post = _post(grid, self.passes) if post is None else post
        gain = self.gains(grid, post)
        seed_cell = self._spread_cell(grid, last)
        if seed_cell is not None:
            return Target(seed_cell[0], seed_cell[1], _target_depth(grid, post, *seed_cell, self.max_depth),
                          float(np.max(gain)))
        value = gain
        if self.boundary_weight > 0 and not _is_voxel(grid) and not self._accuracy_mode(grid):
            value = value + self.boundary_weight * disagreement(grid)
        if self.coverage_weight > 0 and not _is_voxel(grid):
            value = value + self.coverage_weight * uncovered(grid)
        score = value - self.travel_cost_per_mm * _distance_mm(gain.shape, grid.cell_size, last)
        allowed = ~_certain(grid, post, self.max_depth)
        cell = _argmax_cell(score, allowed)
        if cell is None:
            return None
        ix, iy = cell
        # The stop rule asks whether any cell is still worth a press, travel aside: report the best value
        # (gain plus the boundary/coverage terms: an unpressed hole where a feature can hide is worth a press).
        best = float(np.max(np.where(allowed, value, -np.inf)))
        return Target(ix, iy, _target_depth(grid, post, ix, iy, self.max_depth), best)


# --------------------------------------------------------------------------------------------------------------
# building policies and stopping


POLICY_NAMES = ("predefined", "raster", "random", "max_entropy", "info_gain")
#: What info_gain scores on 2-D maps (see :class:`InfoGain`).
OBJECTIVES = ("accuracy", "entropy")


def make_policy(name: str, *, cells: list[tuple[int, int]] | None = None, repeats: int = 1, seed: int = 0,
                stride: int = 1, memory=None, travel_cost_per_mm: float = 0.0, max_depth: float | None = None,
                samples_per_material: int = 6, passes: int | None = 1, objective: str = "accuracy",
                feature_size: float = 0.06):
    """Build a policy by name (one of :data:`POLICY_NAMES`); ``predefined`` needs ``cells``, ``info_gain`` a
    trained ``memory``; ``passes`` is the post-processing's eq. 6.15 passes (see ``Grid2D.postprocessed``);
    ``objective`` and ``feature_size`` (m, the belief's correlation length) are info_gain's (see :class:`InfoGain`)."""
    if not (np.isfinite(travel_cost_per_mm) and travel_cost_per_mm >= 0):
        raise ValidationError(f"travel_cost_per_mm must be a finite number >= 0, got {travel_cost_per_mm!r}")
    if name == "predefined":
        return Predefined(list(cells or []), repeats)
    if name == "raster":
        return Raster(stride)
    if name == "random":
        return RandomCells(seed)
    if name == "max_entropy":
        return MaxEntropy(travel_cost_per_mm, max_depth, passes)
    if name == "info_gain":
        if memory is None:
            raise ValidationError("the info_gain policy needs a trained haptic memory")
        return InfoGain(memory, travel_cost_per_mm, max_depth, samples_per_material, seed, passes,
                        objective=objective, correlation_mm=feature_size * 1e3)
    raise ValidationError(f"unknown exploration policy {name!r}; known: {', '.join(POLICY_NAMES)}")


def stop_reason(post, *, mean_entropy: float | None = None, max_entropy: float | None = None) -> str | None:
    """Which entropy stop rule the post-processed map meets ("mean_entropy" or "max_entropy"), or None.

    Args:
        post: the post-processed map (the one the run reports).
        mean_entropy: stop once the mean cell entropy is at most this (map's base units).
        max_entropy: stop once every cell's entropy is at most this.
    """
    if mean_entropy is None and max_entropy is None:
        return None
    h = _entropy(np.asarray(post.probabilities), post.base)
    if mean_entropy is not None and float(h.mean()) <= mean_entropy:
        return "mean_entropy"
    if max_entropy is not None and float(h.max()) <= max_entropy:
        return "max_entropy"
    return None
