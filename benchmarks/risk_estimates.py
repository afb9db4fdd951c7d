"""Candidate estimates of where a press would read other than the map says, scored by
benchmarks/risk_harness.py against the oracle's mark (benchmarks/oracle_risk.py).

Every estimate takes a :class:`MapState` (what the planner knows before a choice: the measured map and its
post-processed map) and returns a risk per cell, (ny, nx), in [0, 1] on unpressed cells (pressed cells are not
scored). None of them reads the scene's family or generator: they model shapes from the presses alone.

* :func:`post_risk`: 1 - the post-processed map's top probability (1 where it is undecided);
* :func:`belief_risk`: 1 - info_gain's neighbour-vote belief of the map's label;
* :func:`potts_risk` (a): a Potts random field over the labels with one coupling per direction (rows, columns,
  two diagonals) at distance 1 and a continuation coupling at distance 2, fitted per scene by pseudo-likelihood
  on the pressed cells, sampled by Gibbs with the pressed cells clamped; risk = share of samples not of the map's
  label;
* :func:`line_risk` (b): thin-feature hypotheses: along each row, column and diagonal through an unpressed cell,
  the nearest presses on both sides (or two presses on one side) read a material other than the map's label, so a
  line of it may pass here;
* :func:`subset_risk` (c): the post-processing rerun on random subsets of the presses; risk = share of reruns
  whose label differs from the map's;
* :func:`wall_risk` (d): walls as lines (or conics) fitted to the presses around each cell: where presses along
  a wall have located it, the fit extrapolates it past the lattice presses that the map copies.

The Potts field couples cells at most two apart, so a stripe seen at two presses four or more cells apart does not
carry into the cells between them (its samples follow the nearer lattice press); :func:`line_risk` does.
Measurements: docs/results.md, "Estimating where a press would read otherwise".
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from palpate.core.mapping.accuracy import decided_labels
from palpate.core.mapping.extrapolation import extrapolate_unexplored
from palpate.core.mapping.neighbourhood import shift_slices
from palpate.core.planning.expected_accuracy import label_belief

#: The four line directions (dy, dx): rows, columns, the two diagonals.
DIRECTIONS = ((0, 1), (1, 0), (1, 1), (1, -1))


@dataclass(frozen=True)
class MapState:
    """What the planner knows before a choice.

    Attributes:
        probabilities: (ny, nx, M) the measured map (uniform-ish where unpressed).
        explored: (ny, nx) bool, the pressed cells.
        post: (ny, nx, M) the post-processed map the run reports.
    """

    probabilities: np.ndarray
    explored: np.ndarray
    post: np.ndarray

    @property
    def readings(self) -> np.ndarray:
        """(ny, nx) the material each pressed cell read, -1 elsewhere."""
        return np.where(self.explored, self.probabilities.argmax(-1), -1)

    @property
    def label(self) -> np.ndarray:
        return self.post.argmax(-1)


def post_risk(s: MapState) -> np.ndarray:
    """1 - the post-processed top probability; 1 where the map is undecided."""
    _, decided = decided_labels(s.post)
    return np.where(decided, 1.0 - s.post.max(-1), 1.0)


def belief_risk(s: MapState, *, reach: int = 2, temperature: float = 0.5) -> np.ndarray:
    """1 - info_gain's belief (one-cell correlation length) of the map's label; 1 where undecided."""
    b = label_belief(s, reach=reach, correlation_cells=1.0, temperature=temperature)
    _, decided = decided_labels(s.post)
    got = np.take_along_axis(b, s.label[..., None], -1)[..., 0]
    return np.where(decided, 1.0 - got, 1.0)


def _shifted(a: np.ndarray, dy: int, dx: int, fill) -> np.ndarray:
    """out[y, x] = a[y + dy, x + dx] (``fill`` off the grid)."""
    ny, nx = a.shape[:2]
    out = np.full(a.shape, fill, dtype=a.dtype)
    cand, nb = shift_slices(dy, dx, ny, nx)
    out[cand] = a[nb]
    return out


def _rays(readings: np.ndarray, dy: int, dx: int, reach: int) -> tuple[np.ndarray, ...]:
    """Along (dy, dx) from every cell: (first pressed reading, its distance, second pressed reading, its distance),
    -1 / reach + 1 where none within ``reach`` cells."""
    first = np.full(readings.shape, -1)
    d1 = np.full(readings.shape, reach + 1)
    second = np.full(readings.shape, -1)
    d2 = np.full(readings.shape, reach + 1)
    for k in range(1, reach + 1):
        r = _shifted(readings, k * dy, k * dx, -1)
        new2 = (r >= 0) & (first >= 0) & (second < 0)
        second[new2], d2[new2] = r[new2], k
        new1 = (r >= 0) & (first < 0)
        first[new1], d1[new1] = r[new1], k
    return first, d1, second, d2


def line_risk(s: MapState, *, reach: int = 6, length_cells: float = 3.0) -> np.ndarray:
    """Thin-feature hypotheses (module docstring): the largest, over the four directions, of the evidence that a
    one-cell line of a material other than the map's label continues through the cell: presses on both sides
    reading it (a line bridged), or the two nearest presses on one side reading it (a line extended), weighted by
    exp(-gap / ``length_cells``) with gap the cells the line must cross unseen. Undecided cells: 1."""
    r = s.readings
    label = s.label
    best = np.zeros(label.shape)
    for dy, dx in DIRECTIONS:
        f1, e1, f2, _ = _rays(r, dy, dx, reach)
        b1, g1, b2, _ = _rays(r, -dy, -dx, reach)
        bridge = (f1 >= 0) & (f1 == b1) & (f1 != label)
        best = np.maximum(best, np.where(bridge, np.exp(-(e1 + g1 - 2) / length_cells), 0.0))
        for a1, c1, a2, other, od in ((f1, e1, f2, b1, g1), (b1, g1, b2, f1, e1)):
            # two presses on one side read the same other material; the other side does not contradict nearer
            ext = (a1 >= 0) & (a1 == a2) & (a1 != label) & ~((other >= 0) & (other != a1) & (od <= c1))
            best = np.maximum(best, np.where(ext, 0.5 * np.exp(-(c1 - 1) / length_cells), 0.0))
    _, decided = decided_labels(s.post)
    return np.where(decided, best, 1.0)


def subset_risk(s: MapState, *, keep: float = 0.7, draws: int = 24, seed: int = 0) -> np.ndarray:
    """Share of eq. 6.15 reruns on random subsets of the presses (each kept with probability ``keep``) whose
    decided label differs from the map's (an undecided rerun, a cell that lost its pressed neighbours, is no
    evidence of another material and counts nothing); undecided cells: 1."""
    rng = np.random.default_rng(seed)
    label = s.label
    flips = np.zeros(label.shape)
    for _ in range(draws):
        kept = s.explored & (rng.random(label.shape) < keep)
        p = extrapolate_unexplored(s.probabilities, kept)
        lab, dec = decided_labels(p)
        flips += dec & (lab != label)
    _, decided = decided_labels(s.post)
    return np.where(decided, flips / draws, 1.0)


#: Potts offsets: distance 1 and distance 2 along each direction, one coupling each (8 in all).
POTTS_OFFSETS = tuple((k * dy, k * dx) for k in (1, 2) for dy, dx in DIRECTIONS)


def _agreement(onehot: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """(C, ny, nx, M): per coupling, the count of each material among a cell's two in-grid neighbours at that
    offset (+ and -), only neighbours in ``mask``."""
    ny, nx, m = onehot.shape
    a = onehot * mask[..., None]
    out = np.zeros((len(POTTS_OFFSETS), ny, nx, m))
    for c, (dy, dx) in enumerate(POTTS_OFFSETS):
        for sgn in (1, -1):
            cand, nb = shift_slices(sgn * dy, sgn * dx, ny, nx)
            out[c][cand] += a[nb]
    return out


def fit_potts(s: MapState, *, iters: int = 60, ridge: float = 1.0) -> np.ndarray:
    """Couplings (C,) maximising the pseudo-likelihood of the pressed cells' readings given their pressed
    neighbours at the :data:`POTTS_OFFSETS`, with a ridge towards a prior of 1 (where few pressed pairs exist),
    by Newton steps on the concave objective; clipped to [0, 4]."""
    m = s.post.shape[-1]
    r = s.readings
    onehot = np.eye(m)[np.maximum(r, 0)]
    agree = _agreement(onehot, s.explored)[:, s.explored]  # (C, n, M)
    own = onehot[s.explored]  # (n, M)
    x_true = np.einsum("cnm,nm->nc", agree, own)
    x_all = np.moveaxis(agree, 0, -1)  # (n, M, C)
    beta = np.ones(len(POTTS_OFFSETS))
    prior = np.ones_like(beta)
    for _ in range(iters):
        z = x_all @ beta
        z -= z.max(-1, keepdims=True)
        p = np.exp(z)
        p /= p.sum(-1, keepdims=True)
        mean = np.einsum("nm,nmc->nc", p, x_all)
        grad = (x_true - mean).sum(0) - ridge * (beta - prior)
        second = np.einsum("nm,nmc,nmd->ncd", p, x_all, x_all) - np.einsum("nc,nd->ncd", mean, mean)
        hess = -second.sum(0) - ridge * np.eye(beta.size)
        step = np.linalg.solve(hess, grad)
        beta = np.clip(beta - step, 0.0, 4.0)
        if np.max(np.abs(step)) < 1e-6:
            break
    return beta


def potts_risk(s: MapState, *, sweeps: int = 40, burn: int = 10, chains: int = 8, seed: int = 0,
               beta: np.ndarray | None = None) -> np.ndarray:
    """Share of Gibbs samples of the fitted Potts field (module docstring) whose label at a cell differs from the
    map's; pressed cells are clamped to their readings, unpressed ones start at the map's labels. The 3 x 3
    colouring (y mod 3, x mod 3) updates cells that share no coupling together. Undecided cells: 1."""
    rng = np.random.default_rng(seed)
    m = s.post.shape[-1]
    beta = fit_potts(s) if beta is None else beta
    ny, nx = s.explored.shape
    label = s.label
    x = np.repeat(label[None], chains, 0)
    x[:, s.explored] = s.readings[s.explored]
    freq = np.bincount(s.readings[s.explored], minlength=m) + 1.0
    log_prior = np.log(freq / freq.sum())
    yy, xx = np.mgrid[0:ny, 0:nx]
    colour = (yy % 3) * 3 + xx % 3
    counts = np.zeros((chains, ny, nx))
    for sweep in range(sweeps):
        for c in range(9):
            sel = (colour == c) & ~s.explored
            if not sel.any():
                continue
            onehot = np.eye(m)[x]  # (chains, ny, nx, M)
            field = np.zeros((chains, ny, nx, m)) + log_prior
            for b, (dy, dx) in zip(beta, POTTS_OFFSETS, strict=True):
                for sgn in (1, -1):
                    cand, nb = shift_slices(sgn * dy, sgn * dx, ny, nx)
                    field[:, cand[0], cand[1]] += b * onehot[:, nb[0], nb[1]]
            f = field[:, sel]
            f -= f.max(-1, keepdims=True)
            p = np.exp(f)
            p /= p.sum(-1, keepdims=True)
            u = rng.random(p.shape[:2])[..., None]
            x[:, sel] = (p.cumsum(-1) < u).sum(-1).clip(0, m - 1)
        if sweep >= burn:
            counts += x != label
    _, decided = decided_labels(s.post)
    risk = counts.sum(0) / (chains * (sweeps - burn))
    return np.where(decided, risk, 1.0)


def wall_risk(s: MapState, *, radius: int = 4, slope_penalty: float = 0.3, decay_cells: float = 3.0,
              curvature: bool = True, iters: int = 12) -> np.ndarray:
    """Walls as lines fitted to the presses around each cell: a logistic regression of "this press read other
    than the cell's map label" on the press's offset (dx, dy) (and, with ``curvature``, its squares and product),
    over the presses within ``radius`` cells, weighted by exp(-distance / ``decay_cells``), slopes penalised by
    ``slope_penalty``; the risk is its probability at the cell itself. A wall located by presses along it
    elsewhere is extrapolated to where the presses have not been; one-sided evidence leaves the risk low.
    Undecided cells: 1. Every cell is fitted at once (batched Newton steps on the padded window). The defaults
    were chosen on the harness's tuning seeds 0-71 (docs/results.md)."""
    ny, nx = s.explored.shape
    dy, dx = np.mgrid[-radius:radius + 1, -radius:radius + 1]
    cols = [np.ones(dy.size), dx.ravel() / radius, dy.ravel() / radius]
    if curvature:
        cols += [(dx.ravel() / radius) ** 2, (dy.ravel() / radius) ** 2, dx.ravel() * dy.ravel() / radius**2]
    x = np.stack(cols, -1)  # (K, P)
    weight0 = np.exp(-np.hypot(dy, dx).ravel() / decay_cells)
    r = np.pad(s.readings, radius, constant_values=-1)
    label = s.label
    n = ny * nx
    w = np.empty((n, dy.size))
    z = np.empty((n, dy.size))
    for k, (oy, ox) in enumerate(zip(dy.ravel(), dx.ravel(), strict=True)):
        v = r[radius + oy:radius + oy + ny, radius + ox:radius + ox + nx]
        w[:, k] = ((v >= 0) * weight0[k]).ravel()
        z[:, k] = ((v >= 0) & (v != label)).ravel()
    pen = np.full(x.shape[1], slope_penalty)
    pen[0] = 1e-3
    theta = np.zeros((n, x.shape[1]))
    for _ in range(iters):
        p = 1.0 / (1.0 + np.exp(-(theta @ x.T)))
        grad = ((z - p) * w) @ x - pen * theta
        hess = np.einsum("nk,kp,kq->npq", w * p * (1 - p), x, x) + np.diag(pen)
        theta += np.linalg.solve(hess, grad[..., None])[..., 0]
    risk = (1.0 / (1.0 + np.exp(-theta[:, 0]))).reshape(ny, nx)
    _, decided = decided_labels(s.post)
    return np.where(decided, risk, 1.0)
