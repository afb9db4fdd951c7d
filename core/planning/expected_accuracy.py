"""Expected accuracy of a map: what the true material of each cell probably is, and how many cells one press
would set right.

The map's post-processing (seed 000 eq. 6.15) copies an explored neighbour's distribution into an unexplored cell
with confidence, so its entropy cannot tell a cell deep inside a measured region from one between a soft and a
hard measurement. :func:`label_belief` is a separate, deliberately humble guess at the truth, used only to plan:
each explored cell within ``reach`` says "my material continues here" with probability rho(d) = exp(-d / L)
(d in cells, L the correlation length, i.e. the typical feature size) and otherwise "anything, at the map's
material frequencies"; the votes are combined as a tempered naive Bayes (exponent ``temperature`` < 1, because
neighbouring votes are correlated, and full naive Bayes is confidently wrong next to a wall).

:func:`expected_accuracy_gain` then scores a press by the expected number of cells of the post-processed map whose
most probable material becomes the true one: the pressed cell and, through eq. 6.15, its unexplored
8-neighbours. The press's outcome is predicted from the haptic memory's confusion (its Gaussians, see
:func:`palpate.core.planning.outcomes.outcome_posteriors`). The expectation is taken under the belief updated by
the outcome, so a press that only makes the planner more confident of labels that do not change scores zero.

Arrays are laid out like :class:`~palpate.core.mapping.grids.Grid2D`: (ny, nx, M).
"""

from __future__ import annotations

import math

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.mapping.neighbourhood import NEIGHBOURS_8, box3_sum, shift_slices
from palpate.core.mapping.probability import entropy_unchecked
from palpate.core.planning.map_views import H_MIN

_UNDECIDED = 1e-9


def _check(reach: int, correlation_cells: float, temperature: float, surprise: float = 0.0) -> None:
    if isinstance(reach, bool) or not isinstance(reach, (int, np.integer)) or reach < 1:
        raise ValidationError(f"belief reach must be an integer >= 1 cell, got {reach!r}")
    if not (np.isfinite(correlation_cells) and correlation_cells > 0):
        raise ValidationError(f"correlation length must be a finite number > 0 cells, got {correlation_cells!r}")
    if not (np.isfinite(temperature) and 0 < temperature <= 1):
        raise ValidationError(f"belief temperature must be in (0, 1], got {temperature!r}")
    if not (np.isfinite(surprise) and 0 <= surprise < 1):
        raise ValidationError(f"belief surprise must be in [0, 1), got {surprise!r}")


def material_frequencies(labels: np.ndarray, explored: np.ndarray, m: int) -> np.ndarray:
    """Laplace-smoothed share of each material among the explored cells' most probable materials, (M,).

    Smoothed so that a material not met yet keeps a chance: a hidden inclusion may be of it.
    """
    counts = np.bincount(labels[explored].ravel(), minlength=m).astype(float)
    return (counts + 1.0) / (counts.sum() + m)


def _vote_weight(d: float, freq: np.ndarray, correlation_cells: float, temperature: float) -> np.ndarray:
    """Log-evidence (tempered) that an explored cell at distance d (cells) with material m adds to m, (M,):
    log(1 + rho / ((1 - rho) f_m)); the term common to all materials cancels in the normalisation."""
    rho = math.exp(-d / correlation_cells)
    return temperature * np.log1p(rho / ((1.0 - rho) * freq))


def belief_logits(labels: np.ndarray, explored: np.ndarray, freq: np.ndarray, *, reach: int,
                  correlation_cells: float, temperature: float) -> np.ndarray:
    """Unnormalised log-belief of each material per cell from the explored cells within ``reach`` (the prior
    ``log f`` not included), (ny, nx, M)."""
    from scipy.ndimage import correlate

    ny, nx = labels.shape
    m = freq.shape[0]
    dy, dx = np.mgrid[-reach:reach + 1, -reach:reach + 1]
    rho = np.exp(-np.hypot(dy, dx) / correlation_cells)
    rho[reach, reach] = 0.0  # a cell does not vote for itself
    out = np.empty((ny, nx, m))
    for k in range(m):
        # the log-evidence kernel of one material: log(1 + rho / ((1 - rho) f_k)), tempered
        kernel = temperature * np.log1p(rho / ((1.0 - rho) * freq[k]))
        out[..., k] = correlate(((labels == k) & explored).astype(float), kernel, mode="constant", cval=0.0)
    return out


def _normalise_logits(logits: np.ndarray, freq: np.ndarray, surprise: float = 0.0) -> np.ndarray:
    z = logits + np.log(freq)
    z -= z.max(axis=-1, keepdims=True)
    b = np.exp(z)
    b /= b.sum(axis=-1, keepdims=True)
    if surprise:
        b = (1.0 - surprise) * b + surprise * freq
    return b


def label_belief(grid, *, reach: int = 4, correlation_cells: float = 4.0, temperature: float = 0.5,
                 freq: np.ndarray | None = None, surprise: float = 0.0) -> np.ndarray:
    """Probability of each true material per cell, (ny, nx, M): the measured distribution on explored cells, the
    tempered neighbour vote of the module docstring elsewhere (the map's material frequencies where no explored
    cell is within ``reach``).

    Args:
        grid: a :class:`~palpate.core.mapping.grids.Grid2D` (measured, not post-processed).
        reach: explored cells within this Chebyshev distance (cells) vote.
        correlation_cells: L of rho(d) = exp(-d / L), cells: about the size of the features expected.
        temperature: exponent of each vote's likelihood, (0, 1].
        freq: prior share of each material, (M,) (default: :func:`material_frequencies` of the map).
        surprise: chance that an unexplored cell is none of what its neighbours say: the belief is mixed with
            ``freq`` by this much, [0, 1).
    """
    _check(reach, correlation_cells, temperature, surprise)
    p = np.asarray(grid.probabilities, dtype=float)
    if p.ndim != 3:
        raise ValidationError(f"label_belief needs a 2-D map (ny, nx, M), got probabilities of shape {p.shape}")
    explored = np.asarray(grid.explored, dtype=bool)
    labels = np.argmax(p, axis=-1)
    if freq is None:
        freq = material_frequencies(labels, explored, p.shape[-1])
    freq = np.asarray(freq, dtype=float)
    if freq.shape != (p.shape[-1],) or not np.all(np.isfinite(freq)) or (freq <= 0).any():
        raise ValidationError(f"freq must be {p.shape[-1]} finite shares > 0, got {freq!r}")
    b = _normalise_logits(belief_logits(labels, explored, freq, reach=reach, correlation_cells=correlation_cells,
                                        temperature=temperature), freq, surprise)
    return np.where(explored[..., None], p, b)


def _label_decided(post: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Most probable material per cell and whether it is decided (not a tie with the runner-up, as the run's
    accuracy counts an undecided cell as wrong)."""
    label = np.argmax(post, axis=-1)
    top = np.take_along_axis(post, label[..., None], axis=-1)[..., 0]
    runner_up = np.max(np.where(np.arange(post.shape[-1]) == label[..., None], -np.inf, post), axis=-1)
    return label, (top - runner_up) > _UNDECIDED


def _decided_top(num: np.ndarray) -> np.ndarray:
    """One-hot (float) of the most probable material of unnormalised eq. 6.15 numerators laid out
    materials-first, (M, ny, nx); all zero where undecided (another material within the tie tolerance). Built
    from plane-wise max/compare/sum: numpy's argmax and choose over a short first axis are several times slower."""
    top = num.max(axis=0)
    is_top = num >= (top - _UNDECIDED * num.sum(axis=0))
    return is_top * (is_top.sum(axis=0) == 1)


def _planes(a: np.ndarray) -> np.ndarray:
    """(ny, nx, M) -> contiguous (M, ny, nx). Contiguous matters: a moveaxis view keeps M innermost in memory,
    and every reduction over the first axis of it (and of arrays computed from it) is ~10x slower."""
    return np.ascontiguousarray(np.moveaxis(a, -1, 0))


def _gather(a: np.ndarray, index: np.ndarray) -> np.ndarray:
    return np.take_along_axis(a, index[..., None], axis=-1)[..., 0]


def confusion_outcomes(table: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Group a press's predicted outcomes by the material they name: (representative posterior per named
    material (M, M), confusion (M true, M named)); a material never named keeps a uniform representative."""
    outcomes, likelihood = (np.asarray(v, dtype=float) for v in table)
    m = likelihood.shape[0]
    named = np.argmax(outcomes, axis=1)
    conf = np.zeros((m, m))
    rep = np.zeros((m, m))
    for o in range(m):
        sel = named == o
        conf[:, o] = likelihood[:, sel].sum(axis=1)
        w = likelihood[:, sel].sum(axis=0)
        rep[o] = (w @ outcomes[sel]) / w.sum() if w.sum() > 0 else np.full(m, 1.0 / m)
    return rep, conf


def expected_accuracy_gain(grid, post, table: tuple[np.ndarray, np.ndarray], *, reach: int = 4,
                           correlation_cells: float = 4.0, temperature: float = 0.5,
                           surprise: float = 0.0, freq: np.ndarray | None = None) -> np.ndarray:
    """Expected number of cells of the post-processed map that one press on each cell sets right, (ny, nx).

    Args:
        grid: the measured 2-D map.
        post: its post-processed version (one eq. 6.15 pass: a press changes only its 8-neighbours).
        table: (outcomes (U, M), likelihood (M, U)) of a press, from
            :func:`palpate.core.planning.outcomes.outcome_table`.
        reach, correlation_cells, temperature, surprise: of :func:`label_belief`.
        freq: the belief's prior share of each material (default: :func:`material_frequencies` of the map; the
            incremental scoring keeps it fixed between full rescorings).

    Can be negative where a press is expected to tip a correct extrapolation over to a wrong one.
    """
    _check(reach, correlation_cells, temperature, surprise)
    p = np.asarray(grid.probabilities, dtype=float)
    pp = np.asarray(post.probabilities, dtype=float)
    if p.ndim != 3 or pp.shape != p.shape:
        raise ValidationError(f"expected_accuracy_gain needs a 2-D map and its post-processed version of the same "
                              f"shape, got {p.shape} and {pp.shape}")
    ny, nx, m = p.shape
    rep, conf = confusion_outcomes(table)
    if rep.shape != (m, m):
        raise ValidationError(f"outcome table is for {rep.shape[0]} materials, the map has {m}")
    explored = np.asarray(grid.explored, dtype=bool)
    labels = np.argmax(p, axis=-1)
    freq = material_frequencies(labels, explored, m) if freq is None else np.asarray(freq, dtype=float)
    if freq.shape != (m,) or not np.all(np.isfinite(freq)) or (freq <= 0).any():
        raise ValidationError(f"freq must be {m} finite shares > 0, got {freq!r}")
    logits = belief_logits(labels, explored, freq, reach=reach, correlation_cells=correlation_cells,
                           temperature=temperature)
    belief = np.where(explored[..., None], p, _normalise_logits(logits, freq, surprise))

    # Eq. 6.15 as the maps compute it: each explored cell's term w * p with w = 1 / max(H, H_MIN).
    h = entropy_unchecked(p, grid.base)
    c_old = np.where(explored[..., None], p / np.maximum(h, H_MIN)[..., None], 0.0)

    pp_label, pp_decided = _label_decided(pp)
    p_named = belief @ conf  # (ny, nx, M): chance the press names material o
    # The neighbour loop runs materials-first, (M, ny, nx): reductions over M become a few whole-plane ops.
    log_b = _planes(logits + np.log(freq))
    # A per-cell shift keeps exp() in range; a press changes a neighbour's logits by at most one vote.
    log_b -= log_b.max(axis=0)
    c_old_t = _planes(c_old)
    # Each cell's eq. 6.15 numerator (its own term is 0 wherever it is unexplored, the only cells it is used for).
    num_t = box3_sum(c_old_t)
    # The vote an 8-neighbour adds, per offset (it depends on the distance only).
    neighbours = [(shift_slices(dy, dx, ny, nx),
                   _vote_weight(math.hypot(dy, dx), freq, correlation_cells, temperature)[:, None, None])
                  for dy, dx in NEIGHBOURS_8]
    mats = np.arange(m)[:, None, None]
    old_vote = (mats == labels) & explored  # (M, ny, nx): what an explored candidate votes for now
    pp_top = ((mats == pp_label) & pp_decided).astype(float)  # (M, ny, nx): each cell's decided label now
    free_f = (~explored).astype(float)
    gain = np.zeros((ny, nx))
    for o in range(m):
        # The truth given that the press named o (Bayes with the memory's confusion).
        post_t = belief * conf[:, o]
        post_t /= np.maximum(post_t.sum(axis=-1, keepdims=True), 1e-300)
        new = p * rep[o]
        new /= new.sum(axis=-1, keepdims=True)
        np.maximum(new, grid.p_min, out=new)
        new /= new.sum(axis=-1, keepdims=True)
        new_label = np.argmax(new, axis=-1)
        # the pressed cell: right after minus right before, both under the truth given the outcome
        g = _gather(post_t, new_label) - _gather(post_t, pp_label) * pp_decided
        h_new = entropy_unchecked(new, grid.base)
        c_new_t = _planes(new / np.maximum(h_new, H_MIN)[..., None])
        vote_change = (mats == new_label).astype(float) - old_vote  # (M, ny, nx): the candidate's vote, after - now
        for ((cy, cx), (ky, kx)), w in neighbours:
            free = free_f[ky, kx]
            if not free.any():
                continue
            # the neighbour's eq. 6.15 after the press: the candidate's term swapped for its new one
            num = num_t[:, ky, kx] - c_old_t[:, cy, cx] + c_new_t[:, cy, cx]
            np.maximum(num, 0.0, out=num)
            # the neighbour's belief with the candidate now voting for what it was read as
            e = np.exp(log_b[:, ky, kx] + w * vote_change[:, cy, cx])
            delta = _decided_top(num) - pp_top[:, ky, kx]
            right = (delta * e).sum(axis=0) / e.sum(axis=0)  # after - before
            if surprise:
                right = (1.0 - surprise) * right + surprise * (delta * freq[:, None, None]).sum(axis=0)
            g[cy, cx] += right * free
        gain += p_named[..., o] * g
    return gain
