"""Categorical distributions over the reference materials: validation, entropy and the recursive update.

The one home of these kernels for maps, planning and figures (seed 001 eq. 2 and 4).

Conventions:
    * The last axis of every probability array indexes the M reference materials (M >= 2), unless a function
      takes an ``axis``.
    * Entropy takes a base; the seeds use log10 (``base=10``), which is the default here.
    * A map cell never reaches exactly 0 or 1: :func:`update` clamps in log space (as occupancy maps do), so
      later evidence can still move a cell that looked certain.
"""

from __future__ import annotations

import math

import numpy as np

from palpate.core.errors import ValidationError

# Rows of arrays handed to the post-processing functions must sum to one to this tolerance; it is loose on
# purpose so that tables rounded to 4 decimals (the seeds') can be fed in directly.
SUM_TOL_INPUT = 1e-3


def first_index(mask: np.ndarray) -> tuple[int, ...]:
    return tuple(int(i) for i in np.argwhere(mask)[0])


def check_probs(p, name: str, min_ndim: int = 1, normalised: bool = False) -> np.ndarray:
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
            idx = first_index(bad)
            raise ValidationError(f"{name} must be finite; found {arr[idx]} at index {idx}")
        idx = first_index(arr < 0)
        raise ValidationError(f"{name} must be non-negative; found {arr[idx]} at index {idx}")
    if normalised and arr.size:
        off = np.abs(sum_last(arr) - 1.0) > SUM_TOL_INPUT
        if off.any():
            idx = first_index(off)
            raise ValidationError(
                f"{name} must sum to one over materials (last axis); cell {idx} sums to {arr[idx].sum():.6g}"
            )
    return arr


def check_mask(mask, shape: tuple[int, ...], name: str) -> np.ndarray:
    arr = np.asarray(mask)
    if arr.shape != shape:
        raise ValidationError(f"{name} must have shape {shape} (the probability array without its last axis), got "
                              f"{arr.shape}")
    if arr.dtype != bool:
        if not (np.issubdtype(arr.dtype, np.integer) and np.isin(arr, (0, 1)).all()):
            raise ValidationError(f"{name} must be a boolean mask, got dtype {arr.dtype}")
        arr = arr.astype(bool)
    return arr


def check_base(base: float) -> float:
    try:
        b = float(base)
    except (TypeError, ValueError):
        raise ValidationError(f"entropy base must be a number > 0 and != 1, got {base!r}") from None
    if not (np.isfinite(b) and b > 0 and b != 1.0):
        raise ValidationError(f"entropy base must be a finite number > 0 and != 1, got {base!r}")
    return b


def check_h(h, shape: tuple[int, ...]) -> np.ndarray:
    arr = np.asarray(h, dtype=float)
    if arr.shape != shape:
        raise ValidationError(f"h (entropies) must have shape {shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)) or (arr < 0).any():
        raise ValidationError("h (entropies) must be finite and >= 0")
    return arr


def check_h_min(h_min: float) -> float:
    if not (np.isfinite(h_min) and h_min > 0):
        raise ValidationError(f"h_min must be a finite entropy > 0, got {h_min!r}")
    return float(h_min)


def entropy(p, base: float = 10.0, axis: int = -1) -> np.ndarray:
    """Shannon entropy of categorical distributions (seed 001 eq. 4), with 0 log 0 = 0.

    Args:
        p: probabilities, entries in [0, 1], materials along ``axis``.
        base: logarithm base; the seeds use 10 (a uniform distribution over 3 materials has H = log10 3 = 0.4771).
        axis: the materials axis.

    Returns:
        Entropy per distribution (``p`` without ``axis``), in units of the base (e.g. hartleys for base 10).
    """
    b = check_base(base)
    arr = check_probs(p, "p")
    if (arr > 1.0 + 1e-9).any():
        idx = first_index(arr > 1.0 + 1e-9)
        raise ValidationError(f"p must be probabilities in [0, 1]; found {arr[idx]} at index {idx}")
    return entropy_unchecked(arr, b, axis)


def entropy_unchecked(arr: np.ndarray, base: float, axis: int = -1) -> np.ndarray:
    """Entropy of an already validated float array (the hot path of post-processing skips re-validation)."""
    if arr.size and arr.min() > 0:  # a map's cells never reach 0: a plain log is ~3x faster than a masked one
        plogp = np.log(arr)
    else:  # log only where p > 0, so that 0 log 0 = 0 without a divide-by-zero warning.
        plogp = np.log(arr, out=np.zeros_like(arr), where=arr > 0)
    plogp *= arr
    h = sum_last(plogp) if axis in (-1, arr.ndim - 1) else plogp.sum(axis=axis)
    h *= -1.0 / math.log(base)
    # p log p <= 0 for p in [0, 1]; a tiny negative is rounding of a certain distribution.
    return np.maximum(h, 0.0)


def sum_last(a: np.ndarray) -> np.ndarray:
    """``a.sum(axis=-1)`` to the bit, several times faster on a short last axis (materials).

    numpy adds fewer than eight terms of a reduction one after the other, left to right, but loops over them cell
    by cell; adding whole planes in the same order gives the same floats. From eight terms on it sums pairwise,
    so it is left to do that.
    """
    m = a.shape[-1]
    if m >= 8 or m < 2:
        return a.sum(axis=-1)
    out = a[..., 0] + a[..., 1]
    for k in range(2, m):
        out += a[..., k]
    return out


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
    pr = check_probs(prior, "prior")
    meas = check_probs(likelihood_or_posterior, "likelihood_or_posterior")
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
    return update_unchecked(pr, meas, p_min)


def update_unchecked(pr: np.ndarray, meas: np.ndarray, p_min: float) -> np.ndarray:
    """:func:`update` of a validated prior (finite, non-negative, M >= 2; p_min in (0, 1/M)) and a measurement
    that broadcasts to it: what a map does with its own cells. A measurement holding NaN, inf or a negative value
    shows in the log-space maximum, and only then is it checked, so the error is :func:`update`'s."""
    with np.errstate(divide="ignore", invalid="ignore"):
        logp = np.log(pr) + np.log(meas)
    top = logp.max(axis=-1, keepdims=True)
    if not math.isfinite(float(top.sum())):
        check_probs(meas, "likelihood_or_posterior")
        empty = ~np.isfinite(top[..., 0])
        idx = first_index(empty) if empty.ndim else ()
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


#: Updates fused per block by :func:`update_cells_inplace`: a block's planes stay in the CPU cache.
_BATCH_BLOCK = 8192


def update_cells_inplace(cells: np.ndarray, index: np.ndarray, meas: np.ndarray, p_min: float) -> None:
    """Fuse measurement ``meas[i]`` into row ``index[i]`` of ``cells``, in the order given: :func:`update` of
    every row, the same floats as one :func:`update_unchecked` call per measurement, vectorised.

    A row listed several times receives its measurements one after another (in rounds: the k-th occurrence of
    every row in round k), since each update is clamped.

    Args:
        cells: (n_cells, M) validated distributions (a map's probabilities viewed as rows), updated in place.
        index: (n,) row of each measurement, in range.
        meas: (n, M) finite, non-negative measurements, each with a material the row's prior has too.
        p_min: clamping floor, in (0, 1/M).
    """
    n = len(index)
    # Does any row repeat? Counting every row is linear in the map, sorting the batch in the batch.
    repeats = n and (len(np.unique(index)) < n if 8 * n < len(cells)
                     else np.bincount(index, minlength=len(cells)).max() > 1)
    if repeats:
        rounds, rest = [], np.arange(n)
        while len(rest):
            first = np.full(len(cells), n)
            np.minimum.at(first, index[rest], rest)  # the earliest remaining measurement of each row
            now = first[index[rest]] == rest
            rounds.append(rest[now])
            rest = rest[~now]
    else:
        rounds = [None]  # no row repeats: one round, in the order given
    # Rows of M floats moved as one item each (gathers and scatters of whole rows are ~2x faster so).
    row = np.dtype((np.void, cells.itemsize * cells.shape[1]))
    as_rows = cells.view(row).reshape(-1)
    log_p_min = math.log(p_min)
    m = cells.shape[1]
    for sel in rounds:
        idx, mm = (index, meas) if sel is None else (index[sel], np.take(meas, sel, axis=0))
        for b in range(0, len(idx), _BATCH_BLOCK):
            ib, mb = idx[b:b + _BATCH_BLOCK], mm[b:b + _BATCH_BLOCK]
            prior = np.take(cells, ib, axis=0)
            if m < 8:
                new = _update_planes(np.ascontiguousarray(prior.T), np.ascontiguousarray(mb.T), log_p_min).T
            else:  # numpy sums eight materials or more pairwise per row: keep its rows
                new = update_unchecked(prior, mb, p_min)
            as_rows[ib] = np.ascontiguousarray(new).view(row).reshape(-1)


def _update_planes(pr: np.ndarray, meas: np.ndarray, log_p_min: float) -> np.ndarray:
    """:func:`update_unchecked` on materials-first planes (M, k): the same operations in the same order, with the
    reductions over materials written as plane-wise maxima and left-to-right sums (numpy's order for M < 8)."""
    with np.errstate(divide="ignore"):
        logp = np.log(pr)
        logp += np.log(meas)
    top = _planes_max(logp)
    logp -= top
    logp -= np.log(_planes_sum(np.exp(logp)))
    np.maximum(logp, log_p_min, out=logp)
    out = np.exp(logp, out=logp)
    out /= _planes_sum(out)
    return out


def _planes_max(a: np.ndarray) -> np.ndarray:
    top = np.maximum(a[0], a[1])
    for k in range(2, len(a)):
        np.maximum(top, a[k], out=top)
    return top


def _planes_sum(a: np.ndarray) -> np.ndarray:
    total = a[0] + a[1]
    for k in range(2, len(a)):
        total += a[k]
    return total
