"""Press events seen by each device on its own clock: contacts in the taxel stream, reversals in the pose stream.

A press is, to the tactile pad, a contact: c_P rises from its baseline, peaks and falls back; to the tracker, a
reversal: the fingertip moves one way, stops at the deepest point (perhaps holding there) and comes back. The
middle of the c_P peak (where c_P is within ``PEAK_FRACTION`` of its maximum) and the middle of the reversal are the
same instant up to the press's asymmetry, so the two lists of times differ by the clock offset; a coarse estimate
that needs no prior knowledge of it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from palpate.core.perception.segment import contact_intervals, estimate_thresholds

#: c_P within this fraction of a contact's maximum counts as its peak.
PEAK_FRACTION = 0.9
#: A reversal needs the fingertip to travel this far (m) on either side of it: well above tracker noise (~0.1 mm),
#: below a palpation press (a few mm).
REVERSAL_TRAVEL = 0.001
#: How far back and forth a reversal is looked for, s: a slow press with a hold still reverses within this.
REVERSAL_WINDOW = 3.0
#: The directions before and after a reversal make at least this angle (cosine below -0.7: 135 degrees).
REVERSAL_COS = -0.7
#: Poses are thinned to at most this rate for finding reversals, Hz (the coarse match needs ~20 ms).
REVERSAL_RATE = 50.0


@dataclass(frozen=True)
class Contact:
    """One contact in a taxel stream (sample indices into the frames, times on the taxel clock, s)."""

    onset: int
    release: int
    peak: int
    t_peak: float
    c_max: float


@dataclass(frozen=True)
class Reversal:
    """One reversal of the fingertip's motion (time on the pose clock, s; unit direction of motion before it)."""

    t: float
    direction: np.ndarray


def contacts(t: np.ndarray, c_p: np.ndarray) -> list[Contact]:
    """Finished contacts of a c_P series (the segmentation's hysteresis levels), in time order."""
    t = np.asarray(t, dtype=float)
    c_p = np.asarray(c_p, dtype=float)
    if len(c_p) < 3:
        return []
    th = estimate_thresholds(c_p)
    out = []
    for onset, release in contact_intervals(c_p, th.on, th.off):
        if onset < 0 or release is None or release - onset < 2:
            continue
        seg = c_p[onset:release]
        top = np.flatnonzero(seg >= th.baseline + PEAK_FRACTION * (seg.max() - th.baseline))
        peak = onset + int(np.argmax(seg))
        out.append(Contact(onset, release, peak, float(0.5 * (t[onset + top[0]] + t[onset + top[-1]])),
                           float(seg.max())))
    return out


def reversals(t: np.ndarray, position: np.ndarray, *, travel: float = REVERSAL_TRAVEL) -> list[Reversal]:
    """Reversals of a fingertip path (times s, positions m (n, 3)), in time order.

    At each sample the direction of motion before it is the displacement from the last earlier sample at least
    ``travel`` away, and after it the displacement to the first later one; where the two point in opposite
    directions (angle over 135 degrees) the fingertip turned back. Each run of such samples is one reversal,
    placed at the middle of the run (a hold at the deepest point stays inside the run); two runs that turn the same
    way with the path staying within ``travel`` between them are one run split by noise.
    """
    t = np.asarray(t, dtype=float)
    p = np.asarray(position, dtype=float)
    if len(t) < 3:
        return []
    # thin to REVERSAL_RATE: the coarse match needs tens of ms, and the search below is quadratic in the rate
    step = max(1, int(np.floor((len(t) - 1) / max(t[-1] - t[0], 1e-9) / REVERSAL_RATE)))
    t, p = t[::step], p[::step]
    n = len(t)
    horizon = max(1, int(np.ceil(REVERSAL_WINDOW * (n - 1) / max(t[-1] - t[0], 1e-9))))
    before = _first_at_distance(p, travel, horizon, -1)
    after = _first_at_distance(p, travel, horizon, +1)
    ok = (before >= 0) & (after >= 0)
    idx = np.arange(n)
    d_in = np.where(ok[:, None], p - p[np.where(ok, before, idx)], 0.0)
    d_out = np.where(ok[:, None], p[np.where(ok, after, idx)] - p, 0.0)
    norm = np.linalg.norm(d_in, axis=1) * np.linalg.norm(d_out, axis=1)
    cos = np.where(ok & (norm > 0), np.einsum("ij,ij->i", d_in, d_out) / np.where(norm > 0, norm, 1.0), 1.0)
    turning = cos < REVERSAL_COS
    runs: list[list] = []  # [first sample, last sample, unit direction before]
    edges = np.flatnonzero(np.diff(np.concatenate([[0], turning.astype(np.int8), [0]])))
    for a, b in zip(edges[::2], edges[1::2], strict=True):
        mid = (a + b - 1) // 2
        d = d_in[mid] / np.linalg.norm(d_in[mid])
        # noise near a slow turn can break its run in two: a neighbour that turns the same way, reached without
        # going more than the travel away (no lift between two presses), is the same reversal
        if runs and float(runs[-1][2] @ d) > 0.0 and _stays_near(p, runs[-1][1], a, travel):
            runs[-1][1] = b - 1
        else:
            runs.append([a, b - 1, d])
    return [Reversal(float(0.5 * (t[a] + t[b])), d) for a, b, d in runs]


def _stays_near(p: np.ndarray, i: int, j: int, travel: float) -> bool:
    """True if rows i..j of the path all lie within ``travel`` of row i."""
    return bool(np.all(np.sum((p[i:j + 1] - p[i]) ** 2, axis=1) < travel * travel))


def _first_at_distance(p: np.ndarray, travel: float, horizon: int, sign: int) -> np.ndarray:
    """For each row, the index of the nearest row ``sign`` ward at least ``travel`` away (within ``horizon`` rows),
    or -1."""
    n = len(p)
    found = np.full(n, -1, dtype=np.int64)
    todo = np.arange(n)
    for lag in range(1, horizon + 1):
        j = todo + sign * lag
        inside = (j >= 0) & (j < n)
        todo, j = todo[inside], j[inside]
        if len(todo) == 0:
            break
        far = np.sum((p[j] - p[todo]) ** 2, axis=1) >= travel * travel
        found[todo[far]] = j[far]
        todo = todo[~far]
    return found


def press_windows(t: np.ndarray, c_p: np.ndarray) -> list[tuple[float, float]]:
    """One time window per contact of a c_P series, s: each reaches half-way to its neighbours' contacts (the
    first from -inf, the last to +inf), so the approach and retreat of each press stay with it. One window
    (-inf, inf) when there are fewer than two contacts."""
    found = contacts(t, c_p)
    if len(found) < 2:
        return [(-np.inf, np.inf)]
    t = np.asarray(t, dtype=float)
    cuts = [0.5 * (t[a.release] + t[b.onset]) for a, b in zip(found[:-1], found[1:], strict=True)]
    edges = [-np.inf, *cuts, np.inf]
    return list(zip(edges[:-1], edges[1:], strict=True))
