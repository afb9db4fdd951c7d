"""Synthetic press-and-release streams with known ground truth, shared by the signal-path tests.

The fingertip moves along a piecewise-linear height profile; while it is below the surface its intensity follows
the kinesthetic law c_P = n1 (c_D in mm)^1.5 exactly (before optional noise), spread over a 4x4 pad with a
footprint that widens with depth, and rounded to integer counts so that the counts still sum to round(c_P).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from palpate.core.perception.features import ContactSeries
from palpate.core.perception.streams import PoseSample, PressRecording, TaxelFrame

SENSEL_PITCH = 2.5e-3  # m
SENSEL_AREA = SENSEL_PITCH**2  # m^2
TIP_RADIUS = 0.01  # m


@dataclass(frozen=True)
class PressSpec:
    """One press-and-release: start above the surface at t_start, go down to depth, hold, come back up.

    Times in s, lengths in m, speed in m/s.
    """

    t_start: float
    depth: float
    speed: float = 0.01
    hold: float = 0.0
    approach: float = 0.002
    x: float = 0.0
    y: float = 0.0


def height_knots(presses: list[PressSpec], surface_z: float, t_end: float) -> tuple[np.ndarray, np.ndarray]:
    """Knots (t, z) of the piecewise-linear fingertip height; above the surface between presses."""
    top = surface_z + presses[0].approach
    ts, zs = [0.0], [top]
    for p in presses:
        top = surface_z + p.approach
        bottom = surface_z - p.depth
        travel = (top - bottom) / p.speed
        ts += [p.t_start, p.t_start + travel]
        zs += [top, bottom]
        if p.hold > 0:
            ts.append(p.t_start + travel + p.hold)
            zs.append(bottom)
        ts.append(p.t_start + 2 * travel + p.hold)
        zs.append(top)
    ts.append(max(t_end, ts[-1] + 1e-3))
    zs.append(zs[-1])
    t = np.asarray(ts)
    if np.any(np.diff(t) <= 0):
        raise ValueError("press specs overlap in time")
    return t, np.asarray(zs)


def xy_at(presses: list[PressSpec], t: np.ndarray) -> np.ndarray:
    """Fingertip (x, y) at times t: each press's location from its start time on (moved instantly between)."""
    starts = np.array([p.t_start for p in presses])
    k = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(presses) - 1)
    return np.stack([np.array([p.x for p in presses])[k], np.array([p.y for p in presses])[k]], axis=1)


def spread_counts(total: np.ndarray, depth: np.ndarray, rows: int = 4, cols: int = 4) -> np.ndarray:
    """Distribute integer totals over a rows x cols pad with a footprint that widens with depth.

    Largest-remainder rounding keeps each frame's sum equal to round(total). Raises if a sensel would exceed 255.
    """
    total = np.rint(np.clip(total, 0, None)).astype(np.int64)
    yy, xx = np.meshgrid((np.arange(rows) - (rows - 1) / 2) * SENSEL_PITCH,
                         (np.arange(cols) - (cols - 1) / 2) * SENSEL_PITCH, indexing="ij")
    r2 = (xx**2 + yy**2).reshape(-1)
    a2 = TIP_RADIUS * np.clip(depth, 1e-6, None)  # Hertz contact radius squared, m^2
    w = np.exp(-r2[None, :] / (2 * a2[:, None]))
    share = total[:, None] * w / w.sum(axis=1, keepdims=True)
    base = np.floor(share).astype(np.int64)
    rest = total - base.sum(axis=1)
    order = np.argsort(-(share - base), axis=1, kind="stable")
    rank = np.empty_like(order)
    np.put_along_axis(rank, order, np.arange(rows * cols)[None, :].repeat(len(total), 0), axis=1)
    counts = base + (rank < rest[:, None])
    if counts.max(initial=0) > 255:
        raise ValueError("synthetic press saturates a sensel; use a smaller n1 or depth")
    return counts.reshape(-1, rows, cols).astype(np.uint8)


@dataclass
class SyntheticRecording:
    recording: PressRecording
    surface_z: float
    n1: float
    taxel_t: np.ndarray
    true_depth: np.ndarray  # indentation at taxel times, m (0 when not touching)


def make_recording(
    presses: list[PressSpec],
    *,
    rng: np.random.Generator,
    t_end: float,
    n1: float = 60.0,
    surface_z: float = 0.03,
    taxel_rate: float = 50.0,
    pose_rate: float = 30.0,
    clock_offset: float = 0.0,
    pose_noise: float = 0.0,
    intensity_noise: float = 0.0,
    sensel_noise: float = 0.0,
    pose_gap: tuple[float, float] | None = None,
    rotate: bool = False,
    knots: tuple[np.ndarray, np.ndarray] | None = None,
) -> SyntheticRecording:
    """A recording of presses with known n1 (counts/mm^1.5).

    Args:
        clock_offset: the value palpate must add to pose timestamps (pose clock = true time - clock_offset).
        pose_noise: Gaussian noise on pose positions, m.
        intensity_noise: Gaussian noise on c_P before rounding, counts.
        sensel_noise: Gaussian noise on every sensel (clipped at 0, rounded), counts.
        pose_gap: (start, end) true-time interval with no pose samples.
        rotate: make the orientation turn steadily about z (for slerp checks).
        knots: (t, z) of a piecewise-linear height profile replacing the one built from ``presses`` (which
            then only give the x, y locations).
    """
    tk, zk = height_knots(presses, surface_z, t_end) if knots is None else knots
    t = np.arange(0.0, t_end, 1.0 / taxel_rate)
    depth = np.clip(surface_z - np.interp(t, tk, zk), 0.0, None)
    total = n1 * (depth * 1e3) ** 1.5 + intensity_noise * rng.standard_normal(len(t)) * (depth > 0)
    counts = spread_counts(total, depth).astype(float)
    if sensel_noise > 0:
        counts = counts + sensel_noise * rng.standard_normal(counts.shape)
    counts = np.clip(np.rint(counts), 0, 255).astype(np.uint8)
    frames = [TaxelFrame(float(ti), c, SENSEL_AREA) for ti, c in zip(t, counts, strict=True)]

    tp = np.arange(0.0, t_end + 0.2, 1.0 / pose_rate) - 0.1
    if pose_gap is not None:
        tp = tp[(tp < pose_gap[0]) | (tp > pose_gap[1])]
    z = np.interp(tp, tk, zk)
    xy = xy_at(presses, tp)
    pos = np.column_stack([xy, z]) + pose_noise * rng.standard_normal((len(tp), 3))
    angle = 0.5 * tp if rotate else np.zeros_like(tp)
    quat = np.column_stack([np.cos(angle / 2), np.zeros_like(tp), np.zeros_like(tp), np.sin(angle / 2)])
    poses = [PoseSample(float(ti - clock_offset), p, q) for ti, p, q in zip(tp, pos, quat, strict=True)]
    rec = PressRecording(frames=frames, poses=poses, meta={"n1": n1, "surface_z": surface_z})
    return SyntheticRecording(rec, surface_z, n1, t, depth)


def series_from_arrays(t, c_P, height, *, c_A=None, xy=None, valid=None) -> ContactSeries:
    """A ContactSeries straight from arrays (c_A defaults to one sensel per 50 counts, xy to 0, valid to True)."""
    t = np.asarray(t, dtype=float)
    c_P = np.asarray(c_P, dtype=float)
    n = len(t)
    if c_A is None:
        c_A = np.minimum(np.ceil(c_P / 50.0), 16) * SENSEL_AREA
    return ContactSeries(
        t=t,
        c_P=c_P,
        c_A=np.asarray(c_A, dtype=float),
        height=np.asarray(height, dtype=float),
        xy=np.zeros((n, 2)) if xy is None else np.asarray(xy, dtype=float),
        valid=np.ones(n, dtype=bool) if valid is None else np.asarray(valid, dtype=bool),
    )
