"""Probabilistic material maps: a categorical distribution over the reference materials per 2-D cell or voxel.

Array functions come first (seed 001 eq. 2-5, seed 000 eq. 6.15); :class:`Grid2D` and :class:`VoxelGrid` hold
the arrays and their geometry on top of them.

Conventions:
    * The last axis of every probability array indexes the M reference materials (M >= 2).
    * Entropy takes a base; the seeds use log10 (``base=10``), which is the default here.
    * A map cell never reaches exactly 0 or 1: :func:`update` clamps in log space (as occupancy maps do), so
      later evidence can still move a cell that looked certain.
    * Post-processing (extrapolation, continuity) never changes which cells count as explored: an extrapolated
      cell is an estimate, not a measurement.
"""

from __future__ import annotations

import json
import math
import zipfile
from pathlib import Path

import numpy as np

from palpate.core.errors import ValidationError

FORMAT_NAME = "palpate.map"
FORMAT_VERSION = 1

# Rows of arrays handed to the post-processing functions must sum to one to this tolerance; it is loose on
# purpose so that tables rounded to 4 decimals (the seeds') can be fed in directly.
_SUM_TOL_INPUT = 1e-3
# Files written by this module are normalised to float64 precision; a file further off than this was edited.
_SUM_TOL_FILE = 1e-6


# --------------------------------------------------------------------------------------------------------------
# validation helpers


def _first_index(mask: np.ndarray) -> tuple[int, ...]:
    return tuple(int(i) for i in np.argwhere(mask)[0])


def _check_probs(p, name: str, min_ndim: int = 1, normalised: bool = False) -> np.ndarray:
    """Return ``p`` as a float array after checking it is finite and non-negative (and sums to one if asked)."""
    try:
        arr = np.asarray(p, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValidationError(f"{name} must be a numeric array, got {type(p).__name__}: {exc}") from None
    if arr.ndim < min_ndim:
        raise ValidationError(f"{name} must have at least {min_ndim} dimension(s) (last = materials), got {arr.shape}")
    if arr.shape[-1] < 1:
        raise ValidationError(f"{name} has an empty materials axis, shape {arr.shape}")
    # Two allocation-free reductions first (NaN propagates through min); locate the culprit only on failure.
    if arr.size and not (arr.min() >= 0 and np.isfinite(arr.max())):
        bad = ~np.isfinite(arr)
        if bad.any():
            idx = _first_index(bad)
            raise ValidationError(f"{name} must be finite; found {arr[idx]} at index {idx}")
        idx = _first_index(arr < 0)
        raise ValidationError(f"{name} must be non-negative; found {arr[idx]} at index {idx}")
    if normalised and arr.size:
        off = np.abs(arr.sum(axis=-1) - 1.0) > _SUM_TOL_INPUT
        if off.any():
            idx = _first_index(off)
            raise ValidationError(
                f"{name} must sum to one over materials (last axis); cell {idx} sums to {arr[idx].sum():.6g}"
            )
    return arr


def _check_mask(mask, shape: tuple[int, ...], name: str) -> np.ndarray:
    arr = np.asarray(mask)
    if arr.shape != shape:
        raise ValidationError(f"{name} must have shape {shape} (the probability array without its last axis), got "
                              f"{arr.shape}")
    if arr.dtype != bool:
        if not (np.issubdtype(arr.dtype, np.integer) and np.isin(arr, (0, 1)).all()):
            raise ValidationError(f"{name} must be a boolean mask, got dtype {arr.dtype}")
        arr = arr.astype(bool)
    return arr


def _check_base(base: float) -> float:
    try:
        b = float(base)
    except (TypeError, ValueError):
        raise ValidationError(f"entropy base must be a number > 0 and != 1, got {base!r}") from None
    if not (np.isfinite(b) and b > 0 and b != 1.0):
        raise ValidationError(f"entropy base must be a finite number > 0 and != 1, got {base!r}")
    return b


def _check_h(h, shape: tuple[int, ...]) -> np.ndarray:
    arr = np.asarray(h, dtype=float)
    if arr.shape != shape:
        raise ValidationError(f"h (entropies) must have shape {shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)) or (arr < 0).any():
        raise ValidationError("h (entropies) must be finite and >= 0")
    return arr


def _check_h_min(h_min: float) -> float:
    if not (np.isfinite(h_min) and h_min > 0):
        raise ValidationError(f"h_min must be a finite entropy > 0, got {h_min!r}")
    return float(h_min)


# --------------------------------------------------------------------------------------------------------------
# array functions


def entropy(p, base: float = 10.0, axis: int = -1) -> np.ndarray:
    """Shannon entropy of categorical distributions (seed 001 eq. 4), with 0 log 0 = 0.

    Args:
        p: probabilities, entries in [0, 1], materials along ``axis``.
        base: logarithm base; the seeds use 10 (a uniform distribution over 3 materials has H = log10 3 = 0.4771).
        axis: the materials axis.

    Returns:
        Entropy per distribution (``p`` without ``axis``), in units of the base (e.g. hartleys for base 10).
    """
    b = _check_base(base)
    arr = _check_probs(p, "p")
    if (arr > 1.0 + 1e-9).any():
        idx = _first_index(arr > 1.0 + 1e-9)
        raise ValidationError(f"p must be probabilities in [0, 1]; found {arr[idx]} at index {idx}")
    return _entropy_checked(arr, b, axis)


def _entropy_checked(arr: np.ndarray, base: float, axis: int = -1) -> np.ndarray:
    """Entropy of an already validated float array (the hot path of post-processing skips re-validation)."""
    # log only where p > 0, so that 0 log 0 = 0 without a divide-by-zero warning.
    plogp = np.log(arr, out=np.zeros_like(arr), where=arr > 0)
    plogp *= arr
    h = plogp.sum(axis=axis)
    h *= -1.0 / math.log(base)
    # p log p <= 0 for p in [0, 1]; a tiny negative is rounding of a certain distribution.
    return np.maximum(h, 0.0)


def update(prior, likelihood_or_posterior, p_min: float = 1e-6) -> np.ndarray:
    """Recursive Bayesian update of map cells (seed 001 eq. 2): p_new ∝ p_meas * p_old, in log space, clamped.

    ``p_meas`` is what a press says about the cell: a likelihood over materials (any non-negative scale) or a
    per-press posterior computed with a uniform prior (eq. 2 multiplies posteriors; a non-uniform per-press prior
    would be counted once per press). The product is normalised with log-sum-exp, then every probability is
    clamped to at least ``p_min`` in log space and the distribution renormalised, so no entry is ever exactly
    0 or 1 (every entry is >= p_min / (1 + (M-1) p_min) ~ p_min) and later evidence can still change the cell.

    Args:
        prior: current cell distributions, shape (..., M); non-negative, finite (any scale).
        likelihood_or_posterior: shape broadcastable to ``prior`` (e.g. (M,) for one press applied to many cells,
            or the same shape as ``prior``); non-negative, finite. Zeros are allowed as long as each cell keeps
            one material with non-zero probability in both.
        p_min: clamping floor, 0 < p_min < 1/M.

    Returns:
        New distributions, same shape as ``prior``, rows summing to 1.

    Raises:
        ValidationError: NaN/inf/negative input, shapes that do not broadcast, M < 2, bad p_min, or a cell where
            prior and measurement have no material in common (the product would be all zero).
    """
    pr = _check_probs(prior, "prior")
    meas = _check_probs(likelihood_or_posterior, "likelihood_or_posterior")
    m = pr.shape[-1]
    if m < 2:
        raise ValidationError(f"prior must have at least 2 materials on its last axis, got shape {pr.shape}")
    try:
        shape = np.broadcast_shapes(meas.shape, pr.shape)
    except ValueError:
        shape = None
    if shape != pr.shape:
        raise ValidationError(
            f"likelihood_or_posterior of shape {meas.shape} does not broadcast to the prior's shape {pr.shape}"
        )
    if not (np.isfinite(p_min) and 0 < p_min < 1.0 / m):
        raise ValidationError(f"p_min must be in (0, 1/M) = (0, {1.0 / m:.4g}), got {p_min!r}")
    with np.errstate(divide="ignore"):
        logp = np.log(pr) + np.log(meas)
    top = logp.max(axis=-1, keepdims=True)
    empty = ~np.isfinite(top[..., 0])
    if empty.any():
        idx = _first_index(empty) if empty.ndim else ()
        raise ValidationError(
            f"cell {idx}: prior and likelihood_or_posterior have no material with non-zero probability in common "
            "(their product is all zero)"
        )
    logp -= top
    logp -= np.log(np.exp(logp).sum(axis=-1, keepdims=True))
    np.maximum(logp, math.log(p_min), out=logp)
    out = np.exp(logp)
    out /= out.sum(axis=-1, keepdims=True)
    return out


def _inverse_entropy_weights(p: np.ndarray, h, base: float, h_min: float) -> np.ndarray:
    """1/H per distribution, with H floored at ``h_min`` so a certain cell gets a huge but finite weight."""
    hh = _entropy_checked(p, _check_base(base)) if h is None else _check_h(h, p.shape[:-1])
    return 1.0 / np.maximum(hh, h_min)


def extrapolate_unexplored(p, explored, base: float = 10.0, h_min: float = 1e-12, h=None,
                           passes: int | None = 1) -> np.ndarray:
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
        passes: how many times to repeat eq. 6.15 (see :func:`_extrapolate_passes`): 1 (default) is the seed's
            single step; k > 1 lets each pass treat the cells filled by the previous passes as sources, so an
            estimate reaches k cells from the explored ones; None repeats until no unexplored cell that can be
            reached is left.

    Returns:
        A new array: unexplored cells within ``passes`` cells (8-connected, in-grid) of an explored cell get the
        weighted mean of their already-known neighbours; explored cells and unexplored cells further away keep
        their values.
    """
    arr = _check_probs(p, "p", min_ndim=3, normalised=True)
    mask = _check_mask(explored, arr.shape[:-1], "explored")
    n = _check_passes(passes)
    h_min = _check_h_min(h_min)
    w = _inverse_entropy_weights(arr, h, base, h_min)
    return _extrapolate_passes(arr, mask, w, n, _check_base(base), h_min)


def _check_passes(passes) -> int | None:
    if passes is None:
        return None
    if isinstance(passes, bool) or not isinstance(passes, (int, np.integer)) or passes < 1:
        raise ValidationError(f"passes must be an integer >= 1 or None (until every reachable cell is filled), "
                              f"got {passes!r}")
    return int(passes)


def _extrapolate_passes(arr: np.ndarray, mask: np.ndarray, w: np.ndarray, passes: int | None, base: float,
                        h_min: float) -> np.ndarray:
    """Eq. 6.15 repeated: pass k fills the unfilled cells next to a cell known after pass k - 1 (explored or
    filled), each weighted by 1/H of its current values; stops after ``passes`` passes or when a pass fills
    nothing. One pass is exactly :func:`_extrapolate_plane`."""
    out = _extrapolate_plane(arr, mask, w)
    if passes == 1:
        return out
    known = mask | (_box3(mask.astype(float)) > 0)
    k = 1
    while passes is None or k < passes:
        if known.all():
            break
        grown = known | (_box3(known.astype(float)) > 0)
        if not (grown & ~known).any():
            break  # the remaining cells have no known cell anywhere in their plane
        w = 1.0 / np.maximum(_entropy_checked(out, base), h_min)
        out, known = _extrapolate_plane(out, known, w), grown
        k += 1
    return out


def _box3(a: np.ndarray) -> np.ndarray:
    """Sum over each cell's in-grid 3x3 neighbourhood (itself included) on axes 0 and 1, separably."""
    rows = a.copy()
    rows[:, 1:] += a[:, :-1]
    rows[:, :-1] += a[:, 1:]
    out = rows.copy()
    out[1:] += rows[:-1]
    out[:-1] += rows[1:]
    return out


def _extrapolate_plane(arr: np.ndarray, mask: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Kernel of :func:`extrapolate_unexplored` on validated arrays; ``w`` = 1/H per cell."""
    w = np.where(mask, w, 0.0)
    # Unexplored cells have zero weight, so for them the 3x3 box sum is exactly the sum over the 8 neighbours
    # (no subtraction of a huge certain centre, no cancellation); explored cells are not written. Off-grid
    # neighbours never enter the sums, which is the edge/corner rule.
    acc_num = _box3(w[..., None] * arr)
    acc_den = _box3(w)
    target = ~mask & (acc_den > 0)
    out = arr.copy()
    np.divide(acc_num, acc_den[..., None], out=out, where=target[..., None])
    return out


def _vertical_gaps(mask: np.ndarray) -> np.ndarray:
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
    arr = _check_probs(p, "p", min_ndim=2, normalised=True)
    mask = _check_mask(explored, arr.shape[:-1], "explored")
    w = _inverse_entropy_weights(arr, h, base, _check_h_min(h_min))
    return _extrapolate_vertical(arr, mask, w)


def _pair_mean(arr: np.ndarray, w: np.ndarray, idx_a: tuple, idx_b: tuple) -> np.ndarray:
    """1/H-weighted mean of the distributions at two index sets (each a tuple of index arrays)."""
    wa, wb = w[idx_a][:, None], w[idx_b][:, None]
    return (wa * arr[idx_a] + wb * arr[idx_b]) / (wa + wb)


def _extrapolate_vertical(arr: np.ndarray, mask: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Kernel of :func:`extrapolate_vertical` on validated arrays; only the gap voxels are computed."""
    out = arr.copy()
    idx = np.nonzero(_vertical_gaps(mask))
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
    arr = _check_probs(p, "p", min_ndim=2, normalised=True)
    mask = _check_mask(explored, arr.shape[:-1], "explored")
    w = _inverse_entropy_weights(arr, h, base, _check_h_min(h_min))
    return _verify_continuity(arr, mask, w)


def _verify_continuity(arr: np.ndarray, mask: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Kernel of :func:`verify_continuity` on validated arrays; reads only ``arr`` (Jacobi), writes a copy."""
    out = arr.copy()
    pair = np.zeros_like(mask)
    pair[..., :-1] = mask[..., :-1] & mask[..., 1:]
    idx = np.nonzero(pair)
    if idx[0].size:
        out[idx] = _pair_mean(arr, w, idx, idx[:-1] + (idx[-1] + 1,))
    return out


# --------------------------------------------------------------------------------------------------------------
# map classes


def _check_materials(materials) -> list[str]:
    if isinstance(materials, str):
        raise ValidationError("materials must be a list of names, not a single string")
    names = list(materials)
    if len(names) < 2:
        raise ValidationError(f"a map needs at least 2 materials, got {names!r}")
    if not all(isinstance(n, str) and n for n in names):
        raise ValidationError(f"materials must be non-empty strings, got {names!r}")
    if len(set(names)) != len(names):
        raise ValidationError(f"materials must be unique, got {names!r}")
    return names


def _check_positive(value, name: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValidationError(f"{name} must be a number > 0, got {value!r}") from None
    if not (np.isfinite(v) and v > 0):
        raise ValidationError(f"{name} must be a finite number > 0, got {value!r}")
    return v


def _check_finite_tuple(value, n: int, name: str) -> tuple[float, ...]:
    try:
        arr = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise ValidationError(f"{name} must be {n} numbers, got {value!r}") from None
    if arr.shape != (n,) or not np.all(np.isfinite(arr)):
        raise ValidationError(f"{name} must be {n} finite numbers, got {value!r}")
    return tuple(float(v) for v in arr)


def _check_shape(shape, n: int, name: str) -> tuple[int, ...]:
    try:
        vals = tuple(shape)
    except TypeError:
        raise ValidationError(f"{name} must be {n} positive integers, got {shape!r}") from None
    if len(vals) != n or not all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) and v > 0
                                 for v in vals):
        raise ValidationError(f"{name} must be {n} positive integers, got {shape!r}")
    return tuple(int(v) for v in vals)


def _index_along(coord: float, start: float, cell: float, n: int, axis: str) -> int:
    """Cell index containing ``coord`` on one axis; the far edge belongs to the last cell."""
    if not np.isfinite(coord):
        raise ValidationError(f"{axis} must be finite, got {coord!r}")
    end = start + n * cell
    # A small tolerance so that a point on the far edge (or a rounding hair outside) maps to the last cell.
    tol = 1e-9 * cell
    if coord < start - tol or coord > end + tol:
        raise ValidationError(f"{axis} = {coord!r} m is outside the map [{start!r}, {end!r}] m")
    return int(min(max(math.floor((coord - start) / cell), 0), n - 1))


def _read_only(arr: np.ndarray) -> np.ndarray:
    view = arr.view()
    view.flags.writeable = False
    return view


class _CategoricalMap:
    """Shared behaviour of :class:`Grid2D` and :class:`VoxelGrid`: arrays, entropy, MAP, accuracy, files."""

    _kind = ""
    _axes = ""

    def __init__(self, materials, shape: tuple[int, ...], p_min: float, base: float):
        self.materials = _check_materials(materials)
        m = len(self.materials)
        if not (np.isfinite(p_min) and 0 < p_min < 1.0 / m):
            raise ValidationError(f"p_min must be in (0, 1/M) = (0, {1.0 / m:.4g}), got {p_min!r}")
        self.p_min = float(p_min)
        self.base = _check_base(base)
        self._p = np.full(shape + (m,), 1.0 / m)
        self._explored = np.zeros(shape, dtype=bool)

    @property
    def probabilities(self) -> np.ndarray:
        """Read-only view of the per-cell distributions; see the class docstring for the axis order."""
        return _read_only(self._p)

    @property
    def explored(self) -> np.ndarray:
        """Read-only boolean mask of cells that received at least one measurement."""
        return _read_only(self._explored)

    def entropy(self, base: float | None = None) -> np.ndarray:
        """Entropy of every cell, in units of ``base`` (default: the map's base)."""
        return entropy(self._p, base=self.base if base is None else base)

    def mean_entropy(self, base: float | None = None) -> float:
        """Mean entropy over all cells (the seeds' measure of how uncertain the whole map still is)."""
        return float(self.entropy(base).mean())

    def map_estimate(self) -> np.ndarray:
        """Index of the most probable material per cell (maximum a posteriori)."""
        return self._p.argmax(axis=-1)

    def accuracy(self, truth_idx, mask=None) -> float:
        """Fraction of cells whose MAP material equals ``truth_idx``.

        Args:
            truth_idx: int array with the map's cell shape; -1 marks cells with no truth (outside the object or
                a material not in the map), which are ignored.
            mask: optional boolean array of the same shape restricting which cells count (e.g. explored only).

        Raises:
            ValidationError: wrong shape, indices outside [-1, M), or no cell left to count.
        """
        shape = self._p.shape[:-1]
        truth = np.asarray(truth_idx)
        if truth.shape != shape or not np.issubdtype(truth.dtype, np.integer):
            raise ValidationError(f"truth_idx must be an integer array of shape {shape}, got {truth.dtype} "
                                  f"{truth.shape}")
        m = len(self.materials)
        if ((truth < -1) | (truth >= m)).any():
            raise ValidationError(f"truth_idx must be in [-1, {m}) (-1 = no truth), got values outside")
        keep = truth >= 0
        if mask is not None:
            keep &= _check_mask(mask, shape, "mask")
        n = int(keep.sum())
        if n == 0:
            raise ValidationError("accuracy: no cell with a truth label (and inside mask) to count")
        return float((self.map_estimate()[keep] == truth[keep]).sum() / n)

    def _with_arrays(self, p: np.ndarray, explored: np.ndarray):
        """Install loaded (already validated) arrays; returns self."""
        self._p = p.astype(float)
        self._explored = explored.copy()
        return self

    def _update_at(self, index: tuple, p_meas) -> None:
        self._p[index] = update(self._p[index], p_meas, p_min=self.p_min)
        self._explored[index] = True

    def _meta(self) -> dict:
        return {
            "format": FORMAT_NAME,
            "version": FORMAT_VERSION,
            "kind": self._kind,
            "axes": self._axes,
            "materials": list(self.materials),
            "shape": list(self.shape),  # (nx, ny) or (nx, ny, nz), as the constructor takes it
            "cell_size_m": self.cell_size,
            "origin_m": list(self.origin),
            "base": self.base,
            "p_min": self.p_min,
        }

    def save(self, path) -> tuple[Path, Path]:
        """Write the map: arrays to ``path`` (NPZ, no pickled objects) and metadata to the same name with .json.

        Returns:
            (npz path, json path).
        """
        npz = Path(path)
        if npz.suffix != ".npz":
            raise ValidationError(f"map file must end in .npz (metadata goes beside it as .json), got {npz}")
        sidecar = npz.with_suffix(".json")
        np.savez_compressed(npz, probabilities=self._p, explored=self._explored)
        sidecar.write_text(json.dumps(self._meta(), indent=2) + "\n")
        return npz, sidecar


def _read_map_files(path, kind: str) -> tuple[dict, np.ndarray, np.ndarray]:
    """Read and validate an NPZ + JSON map pair; errors name the file and the key."""
    npz = Path(path)
    sidecar = npz.with_suffix(".json")
    if npz.suffix != ".npz":
        raise ValidationError(f"map file must end in .npz, got {npz}")
    for f in (npz, sidecar):
        if not f.is_file():
            raise ValidationError(f"map file {f} does not exist (a map is an .npz with a .json beside it)")
    try:
        meta = json.loads(sidecar.read_text())
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValidationError(f"{sidecar}: not valid JSON ({exc})") from None
    if not isinstance(meta, dict):
        raise ValidationError(f"{sidecar}: expected a JSON object at top level, got {type(meta).__name__}")
    required = ("format", "version", "kind", "materials", "shape", "cell_size_m", "origin_m", "base", "p_min")
    for key in required:
        if key not in meta:
            raise ValidationError(f"{sidecar}: missing key {key!r}")
    if meta["format"] != FORMAT_NAME:
        raise ValidationError(f"{sidecar}: key 'format' must be {FORMAT_NAME!r}, got {meta['format']!r}")
    if meta["version"] != FORMAT_VERSION:
        raise ValidationError(f"{sidecar}: key 'version' is {meta['version']!r}; this palpate reads version "
                              f"{FORMAT_VERSION}")
    if meta["kind"] != kind:
        raise ValidationError(f"{sidecar}: key 'kind' is {meta['kind']!r}, expected {kind!r}")
    try:
        arrays = np.load(npz, allow_pickle=False)
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as exc:
        raise ValidationError(f"{npz}: not a readable NPZ file ({exc})") from None
    with arrays:
        for key in ("probabilities", "explored"):
            if key not in arrays.files:
                raise ValidationError(f"{npz}: missing array {key!r} (has {arrays.files})")
        extra = sorted(set(arrays.files) - {"probabilities", "explored"})
        if extra:
            raise ValidationError(f"{npz}: unexpected arrays {extra}")
        try:
            p = arrays["probabilities"]
            explored = arrays["explored"]
        except (ValueError, OSError, zipfile.BadZipFile, EOFError) as exc:
            raise ValidationError(f"{npz}: cannot read arrays ({exc})") from None
    if p.dtype.kind != "f":
        raise ValidationError(f"{npz}: 'probabilities' must be a float array, got {p.dtype}")
    if explored.dtype != bool:
        raise ValidationError(f"{npz}: 'explored' must be a boolean array, got {explored.dtype}")
    if not np.all(np.isfinite(p)):
        raise ValidationError(f"{npz}: 'probabilities' contains NaN or infinite values")
    if (p < 0).any() or (p > 1).any():
        raise ValidationError(f"{npz}: 'probabilities' has values outside [0, 1]")
    if p.size and (np.abs(p.sum(axis=-1) - 1.0) > _SUM_TOL_FILE).any():
        idx = _first_index(np.abs(p.sum(axis=-1) - 1.0) > _SUM_TOL_FILE)
        raise ValidationError(f"{npz}: 'probabilities' cell {idx} sums to {p[idx].sum():.9g}, expected 1")
    if p.shape[:-1] != explored.shape:
        raise ValidationError(f"{npz}: 'explored' shape {explored.shape} does not match 'probabilities' "
                              f"{p.shape}")
    if not isinstance(meta["materials"], list) or p.shape[-1] != len(meta["materials"]):
        raise ValidationError(f"{sidecar}: key 'materials' must list the {p.shape[-1]} materials of {npz}")
    return meta, p, explored


def _meta_value(meta: dict, key: str, sidecar: Path, check):
    try:
        return check(meta[key])
    except (ValidationError, TypeError, ValueError) as exc:
        raise ValidationError(f"{sidecar}: key {key!r}: {exc}") from None


def _construct(sidecar: Path, build):
    """Run a constructor on loaded metadata so that its own checks (e.g. p_min < 1/M) name the file too."""
    try:
        return build()
    except ValidationError as exc:
        if str(exc).startswith(str(sidecar)):
            raise
        raise ValidationError(f"{sidecar}: {exc}") from None


def _common_meta(meta: dict, sidecar: Path) -> dict:
    """The constructor keywords every map kind reads from its JSON sidecar, each validated."""
    return {
        "origin": _meta_value(meta, "origin_m", sidecar, lambda v: _check_finite_tuple(v, 2, "origin")),
        "cell_size": _meta_value(meta, "cell_size_m", sidecar, lambda v: _check_positive(v, "cell_size")),
        "p_min": _meta_value(meta, "p_min", sidecar, _check_p_min),
        "base": _meta_value(meta, "base", sidecar, _check_base),
    }


def _check_p_min(value) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValidationError(f"p_min must be a number, got {value!r}")
    return float(value)


class Grid2D(_CategoricalMap):
    """A 2-D probabilistic material map over the workspace plane (seed 000 §6.6-6.7).

    Geometry: ``origin`` = (x0, y0) is the corner of the grid with the smallest x and y; cell (ix, iy) covers
    x in [x0 + ix c, x0 + (ix+1) c) and y in [y0 + iy c, y0 + (iy+1) c), c = ``cell_size``; the far edge belongs
    to the last cell. Arrays are indexed like images, rows along y: ``probabilities[iy, ix, m]``,
    ``explored[iy, ix]``; every method taking indices takes them as (ix, iy), 0-based.

    Seed 000 Table 6.8 lists cells as 1-based (column, row) pairs on a 1 cm grid, e.g. (20, 8). The seed cell
    (c, r) is ``cell_centre(c - 1, r - 1)``, i.e. x = x0 + (c - 0.5) * 0.01 m, y = y0 + (r - 0.5) * 0.01 m.

    Args:
        materials: names of the M >= 2 reference materials (the haptic memory's order).
        shape: (nx, ny) number of cells along x and y.
        origin: (x0, y0), m.
        cell_size: cell side, m (1 cm as in seed 000).
        p_min: clamping floor of :func:`update`.
        base: entropy base (10, as the seeds).
    """

    _kind = "grid2d"
    _axes = "probabilities[iy, ix, m]"

    def __init__(self, materials, shape, origin=(0.0, 0.0), cell_size: float = 0.01, p_min: float = 1e-6,
                 base: float = 10.0):
        nx, ny = _check_shape(shape, 2, "shape (nx, ny)")
        self.origin = _check_finite_tuple(origin, 2, "origin (x0, y0)")
        self.cell_size = _check_positive(cell_size, "cell_size")
        super().__init__(materials, (ny, nx), p_min, base)

    @classmethod
    def from_extent(cls, materials, x_range, y_range, cell_size: float = 0.01, **kwargs) -> Grid2D:
        """A grid covering [xmin, xmax] x [ymin, ymax] (m), rounded up to whole cells."""
        xmin, xmax = _check_finite_tuple(x_range, 2, "x_range")
        ymin, ymax = _check_finite_tuple(y_range, 2, "y_range")
        c = _check_positive(cell_size, "cell_size")
        if not (xmax > xmin and ymax > ymin):
            raise ValidationError(f"extent must have xmax > xmin and ymax > ymin, got {x_range}, {y_range}")
        nx = max(1, math.ceil((xmax - xmin) / c - 1e-9))
        ny = max(1, math.ceil((ymax - ymin) / c - 1e-9))
        return cls(materials, (nx, ny), origin=(xmin, ymin), cell_size=c, **kwargs)

    @property
    def shape(self) -> tuple[int, int]:
        """(nx, ny)."""
        ny, nx = self._explored.shape
        return nx, ny

    def cell_of(self, x: float, y: float) -> tuple[int, int]:
        """(ix, iy) of the cell containing the point (x, y), m; ValidationError outside the grid."""
        nx, ny = self.shape
        return (_index_along(x, self.origin[0], self.cell_size, nx, "x"),
                _index_along(y, self.origin[1], self.cell_size, ny, "y"))

    def cell_centre(self, ix: int, iy: int) -> tuple[float, float]:
        """(x, y) of the centre of cell (ix, iy), 0-based, m. Seed cell (c, r) (1-based) is (c - 1, r - 1)."""
        ix, iy = self._check_cell(ix, iy)
        return (self.origin[0] + (ix + 0.5) * self.cell_size, self.origin[1] + (iy + 0.5) * self.cell_size)

    def cell_centres(self) -> np.ndarray:
        """Centres of all cells, shape (ny, nx, 2) holding (x, y), m (same indexing as ``probabilities``)."""
        nx, ny = self.shape
        xs = self.origin[0] + (np.arange(nx) + 0.5) * self.cell_size
        ys = self.origin[1] + (np.arange(ny) + 0.5) * self.cell_size
        gx, gy = np.meshgrid(xs, ys)
        return np.stack([gx, gy], axis=-1)

    def _check_cell(self, ix, iy) -> tuple[int, int]:
        nx, ny = self.shape
        if not (isinstance(ix, (int, np.integer)) and isinstance(iy, (int, np.integer))):
            raise ValidationError(f"cell indices must be integers, got ({ix!r}, {iy!r})")
        if not (0 <= ix < nx and 0 <= iy < ny):
            raise ValidationError(f"cell ({ix}, {iy}) is outside the grid of (nx, ny) = ({nx}, {ny})")
        return int(ix), int(iy)

    def update_cell(self, ix: int, iy: int, p_meas) -> None:
        """Fuse one measurement (shape (M,)) into cell (ix, iy) with :func:`update` and mark it explored."""
        ix, iy = self._check_cell(ix, iy)
        self._check_meas(p_meas)
        self._update_at((iy, ix), p_meas)

    def update(self, x: float, y: float, p_meas) -> tuple[int, int]:
        """Fuse one press at (x, y), m, into the cell containing it; returns that cell's (ix, iy)."""
        ix, iy = self.cell_of(x, y)
        self.update_cell(ix, iy, p_meas)
        return ix, iy

    def _check_meas(self, p_meas) -> None:
        shape = np.shape(p_meas)
        if shape != (len(self.materials),):
            raise ValidationError(f"p_meas must have shape ({len(self.materials)},) (one value per material "
                                  f"{self.materials}), got {shape}")

    def postprocessed(self, h_min: float = 1e-12, passes: int | None = 1) -> Grid2D:
        """A new grid with unexplored cells extrapolated by :func:`extrapolate_unexplored`; self is untouched.

        ``passes`` repeats eq. 6.15 from the cells filled by the previous pass (1 = the seed; None = until every
        cell is filled). The explored mask is copied unchanged: extrapolated cells are estimates, not
        measurements.
        """
        out = self._empty_like()
        h_min = _check_h_min(h_min)
        w = 1.0 / np.maximum(_entropy_checked(self._p, self.base), h_min)
        out._p = _extrapolate_passes(self._p, self._explored, w, _check_passes(passes), self.base, h_min)
        out._explored = self._explored.copy()
        return out

    def _empty_like(self) -> Grid2D:
        return Grid2D(self.materials, self.shape, origin=self.origin, cell_size=self.cell_size, p_min=self.p_min,
                      base=self.base)

    @classmethod
    def load(cls, path) -> Grid2D:
        """Read a map written by :meth:`save`, validating both files; errors name the file and key."""
        meta, p, explored = _read_map_files(path, cls._kind)
        sidecar = Path(path).with_suffix(".json")
        nx, ny = _meta_value(meta, "shape", sidecar, lambda v: _check_shape(v, 2, "shape (nx, ny)"))
        if p.shape[:-1] != (ny, nx):
            raise ValidationError(f"{path}: 'probabilities' shape {p.shape} does not match {sidecar} shape "
                                  f"(nx, ny) = ({nx}, {ny}) (arrays are [iy, ix, m])")
        grid = _construct(sidecar, lambda: cls(
            _meta_value(meta, "materials", sidecar, _check_materials), (nx, ny), **_common_meta(meta, sidecar)))
        return grid._with_arrays(p, explored)


class VoxelGrid(_CategoricalMap):
    """A volumetric probabilistic material map below a surface (seed 001).

    Geometry: ``origin`` = (x0, y0) is the corner with the smallest x and y, ``z_top`` the surface height (m);
    voxel (ix, iy, iz) covers x in [x0 + ix c, x0 + (ix+1) c), y likewise, and depth below the surface in
    [iz c, (iz+1) c), i.e. z in (z_top - (iz+1) c, z_top - iz c]. iz = 0 is the surface layer and grows
    downward. Arrays are indexed ``probabilities[ix, iy, iz, m]`` and ``explored[ix, iy, iz]`` (note: x first,
    unlike :class:`Grid2D`'s image order), so ``probabilities[ix, iy]`` is a column from the surface down.

    Args:
        materials: names of the M >= 2 reference materials.
        shape: (nx, ny, nz).
        origin: (x0, y0), m.
        z_top: height of the surface, m.
        cell_size: voxel side, m (0.25 cm as in seed 001).
        p_min: clamping floor of :func:`update`.
        base: entropy base.
    """

    _kind = "voxel"
    _axes = "probabilities[ix, iy, iz, m], iz = 0 at the surface"

    def __init__(self, materials, shape, origin=(0.0, 0.0), z_top: float = 0.0, cell_size: float = 0.0025,
                 p_min: float = 1e-6, base: float = 10.0):
        shape3 = _check_shape(shape, 3, "shape (nx, ny, nz)")
        self.origin = _check_finite_tuple(origin, 2, "origin (x0, y0)")
        (self.z_top,) = _check_finite_tuple((z_top,), 1, "z_top")
        self.cell_size = _check_positive(cell_size, "cell_size")
        super().__init__(materials, shape3, p_min, base)

    @property
    def shape(self) -> tuple[int, int, int]:
        """(nx, ny, nz)."""
        return self._explored.shape  # type: ignore[return-value]

    def _meta(self) -> dict:
        meta = super()._meta()
        meta["z_top_m"] = self.z_top
        return meta

    def column_of(self, x: float, y: float) -> tuple[int, int]:
        """(ix, iy) of the column containing (x, y), m; ValidationError outside the grid."""
        nx, ny, _ = self.shape
        return (_index_along(x, self.origin[0], self.cell_size, nx, "x"),
                _index_along(y, self.origin[1], self.cell_size, ny, "y"))

    def voxel_centres(self) -> np.ndarray:
        """Centres of all voxels, shape (nx, ny, nz, 3) holding (x, y, z), m."""
        nx, ny, nz = self.shape
        c = self.cell_size
        xs = self.origin[0] + (np.arange(nx) + 0.5) * c
        ys = self.origin[1] + (np.arange(ny) + 0.5) * c
        zs = self.z_top - (np.arange(nz) + 0.5) * c
        gx, gy, gz = np.meshgrid(xs, ys, zs, indexing="ij")
        return np.stack([gx, gy, gz], axis=-1)

    def _check_voxel(self, ix, iy, iz) -> tuple[int, int, int]:
        idx = (ix, iy, iz)
        if not all(isinstance(i, (int, np.integer)) for i in idx):
            raise ValidationError(f"voxel indices must be integers, got {idx!r}")
        if not all(0 <= i < n for i, n in zip(idx, self.shape, strict=True)):
            raise ValidationError(f"voxel {idx} is outside the grid of (nx, ny, nz) = {self.shape}")
        return int(ix), int(iy), int(iz)

    def column(self, ix: int, iy: int) -> np.ndarray:
        """Copy of the column at (ix, iy) from the surface down, shape (nz, M)."""
        ix, iy, _ = self._check_voxel(ix, iy, 0)
        return self._p[ix, iy].copy()

    def update_voxel(self, ix: int, iy: int, iz: int, p) -> None:
        """Fuse one measurement (shape (M,)) into voxel (ix, iy, iz) and mark it explored."""
        idx = self._check_voxel(ix, iy, iz)
        m = len(self.materials)
        if np.shape(p) != (m,):
            raise ValidationError(f"p must have shape ({m},) (materials {self.materials}), got {np.shape(p)}")
        self._update_at(idx, p)

    def layers_reached(self, depth_reached: float) -> int:
        """How many voxels from the surface a press of indentation ``depth_reached`` (m, > 0) passes through.

        A press to depth d passes through every voxel whose top is above d: ceil(d / c), at most nz (a press
        deeper than the grid updates the whole column).
        """
        d = _check_positive(depth_reached, "depth_reached")
        # Shave a rounding hair so a press to exactly k voxels' depth does not touch voxel k + 1.
        k = math.ceil(d / self.cell_size * (1 - 1e-12))
        return int(min(max(k, 1), self.shape[2]))

    def update_press(self, x: float, y: float, depth_reached: float, p_meas) -> tuple[int, int, int]:
        """Fuse one press at (x, y), m, into the voxels it indented, from the surface to ``depth_reached``.

        Args:
            x, y: press location, m.
            depth_reached: maximum indentation below the surface, m (> 0); see :meth:`layers_reached`.
            p_meas: shape (M,) applied to every voxel passed through, or (k, M) with one row per voxel, k =
                ``layers_reached(depth_reached)``, surface first.

        Returns:
            (ix, iy, k): the column and the number of voxels updated (voxels 0..k-1 are now explored).
        """
        ix, iy = self.column_of(x, y)
        k = self.layers_reached(depth_reached)
        m = len(self.materials)
        shape = np.shape(p_meas)
        if shape not in ((m,), (k, m)):
            raise ValidationError(f"p_meas must have shape ({m},) or ({k}, {m}) (one row per voxel reached), got "
                                  f"{shape}")
        self._update_at((ix, iy, slice(0, k)), p_meas)
        return ix, iy, k

    def postprocessed(self, lateral: bool = False, h_min: float = 1e-12) -> VoxelGrid:
        """A new grid after seed 001's local-context stages; self is untouched.

        Order: (1) vertical extrapolation (eq. 3) from the measured values, then (2) continuity verification
        (eq. 5) of the explored voxels. Extrapolating first uses the neighbours as measured, as seed 001 did
        (Table 3 is reproduced from Table 2's 100% column, not its continuity column); running continuity first
        would feed the lower neighbour into a gap twice. Continuity touches only explored voxels, so it does not
        change the filled gaps. (3) If ``lateral``, unexplored voxels still not filled get the 8-neighbour
        estimate of seed 000 eq. 6.15 within their layer, from explored voxels only.
        The explored mask is copied unchanged.
        """
        h_min = _check_h_min(h_min)
        # One set of weights serves both vertical stages: stage (1) changes only unexplored voxels and stage (2)
        # reads only explored ones.
        w = 1.0 / np.maximum(_entropy_checked(self._p, self.base), h_min)
        p = _extrapolate_vertical(self._p, self._explored, w)
        p = _verify_continuity(p, self._explored, w)
        if lateral:
            filled = self._explored | _vertical_gaps(self._explored)
            w = 1.0 / np.maximum(_entropy_checked(p, self.base), h_min)
            side = _extrapolate_plane(p, self._explored, w)
            p = np.where(filled[..., None], p, side)
        out = VoxelGrid(self.materials, self.shape, origin=self.origin, z_top=self.z_top, cell_size=self.cell_size,
                        p_min=self.p_min, base=self.base)
        out._p = p
        out._explored = self._explored.copy()
        return out

    @classmethod
    def load(cls, path) -> VoxelGrid:
        """Read a voxel map written by :meth:`save`, validating both files; errors name the file and key."""
        meta, p, explored = _read_map_files(path, cls._kind)
        sidecar = Path(path).with_suffix(".json")
        if "z_top_m" not in meta:
            raise ValidationError(f"{sidecar}: missing key 'z_top_m'")
        shape = _meta_value(meta, "shape", sidecar, lambda v: _check_shape(v, 3, "shape (nx, ny, nz)"))
        if p.shape[:-1] != shape:
            raise ValidationError(f"{path}: 'probabilities' shape {p.shape} does not match {sidecar} shape {shape}")
        grid = _construct(sidecar, lambda: cls(
            _meta_value(meta, "materials", sidecar, _check_materials), shape,
            z_top=_meta_value(meta, "z_top_m", sidecar, lambda v: _check_finite_tuple((v,), 1, "z_top")[0]),
            **_common_meta(meta, sidecar)))
        return grid._with_arrays(p, explored)
