"""Put taxel frames and pose samples on one timeline: the taxel clock.

The tactile array and the pose tracker run on their own clocks at their own rates (e.g. 50 Hz and ~30 Hz).
:func:`synchronise` shifts pose timestamps by a known clock offset and interpolates the pose at every taxel time:
position linearly, orientation by spherical linear interpolation (slerp). A taxel frame gets a pose only when
it lies inside the pose time span and not inside a pose dropout longer than ``max_gap``; other frames are kept
(their counts are still real) but marked invalid, and every dropout is reported as a :class:`Gap`, so nothing is
bridged silently. :func:`estimate_clock_offset` recovers an unknown offset from the data themselves.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.perception.streams import (
    PoseSample,
    TaxelFrame,
    frames_to_arrays,
    pose_times_positions,
)

# Below this angle between two quaternions slerp's sin(theta) denominator loses precision; the chord (normalised
# linear interpolation) is then exact to ~1e-12 rad.
_SLERP_LINEAR_BELOW = 1e-6


@dataclass(frozen=True)
class Gap:
    """A pose dropout longer than the allowed gap, on the taxel clock.

    Attributes:
        t_start: time of the last pose sample before the dropout, s.
        t_end: time of the first pose sample after it, s.
        duration: t_end - t_start, s.
    """

    t_start: float
    t_end: float
    duration: float


class SyncedStream:
    """Taxel frames with the fingertip pose interpolated at their times.

    Attributes:
        t: taxel times, s, shape (n,), strictly increasing (taxel clock).
        counts: raw counts, shape (n, rows, cols), uint8.
        sensel_area: area of one sensel, m^2.
        position: fingertip position at each taxel time, m, shape (n, 3), world frame.
        quaternion: fingertip orientation (w, x, y, z) at each taxel time, unit norm, shape (n, 4). Nothing in the
            contact features reads it, so :func:`synchronise` passes a function that interpolates it (slerp) the
            first time it is read; an array may be given as well.
        valid: True where the pose is interpolated between two pose samples at most ``max_gap`` apart;
            False outside the pose time span or inside a gap. Pose values of invalid frames are placeholders
            (the nearest interpolation, always finite) and must not be used.
        gaps: pose dropouts longer than ``max_gap`` that overlap the taxel time span, in time order.
        clock_offset: offset added to pose timestamps, s.
    """

    def __init__(self, t: np.ndarray, counts: np.ndarray, sensel_area: float, position: np.ndarray,
                 quaternion: np.ndarray | Callable[[], np.ndarray], valid: np.ndarray, gaps: list[Gap] | None = None,
                 clock_offset: float = 0.0):
        self.t = t
        self.counts = counts
        self.sensel_area = sensel_area
        self.position = position
        self._quaternion = quaternion
        self.valid = valid
        self.gaps = [] if gaps is None else gaps
        self.clock_offset = clock_offset

    @property
    def quaternion(self) -> np.ndarray:
        """Orientation at each taxel time, (n, 4) (interpolated on first access)."""
        if callable(self._quaternion):
            self._quaternion = self._quaternion()
        return self._quaternion

    def __len__(self) -> int:
        return len(self.t)

    def __repr__(self) -> str:
        return (f"SyncedStream({len(self)} frames, {self.n_invalid} without pose, {len(self.gaps)} gap(s), "
                f"clock_offset={self.clock_offset!r} s)")

    @property
    def n_invalid(self) -> int:
        """Number of frames without a usable pose."""
        return int(np.count_nonzero(~self.valid))


def slerp(q0: np.ndarray, q1: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Spherical linear interpolation between unit quaternions, row by row.

    Args:
        q0, q1: unit quaternions (w, x, y, z), shape (n, 4).
        s: interpolation fractions in [0, 1], shape (n,); 0 gives q0, 1 gives q1.

    Returns:
        Unit quaternions, shape (n, 4), along the shorter arc (q and -q are the same rotation).
    """
    q0 = np.asarray(q0, dtype=float)
    q1 = np.asarray(q1, dtype=float)
    s = np.asarray(s, dtype=float)[:, None]
    dot = np.einsum("ij,ij->i", q0, q1)
    # q and -q are the same rotation: flip to take the short way round.
    q1 = np.where(dot[:, None] < 0.0, -q1, q1)
    dot = np.abs(dot)
    theta = np.arccos(np.clip(dot, -1.0, 1.0))[:, None]
    sin_theta = np.sin(theta)
    small = theta < _SLERP_LINEAR_BELOW
    safe = np.where(small, 1.0, sin_theta)
    w0 = np.where(small, 1.0 - s, np.sin((1.0 - s) * theta) / safe)
    w1 = np.where(small, s, np.sin(s * theta) / safe)
    q = w0 * q0 + w1 * q1
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def _check_scalar(name: str, value: float, *, positive: bool = False) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError) as exc:
        raise ValidationError(f"{name} must be a number in seconds, got {value!r}") from exc
    if not math.isfinite(v) or (positive and v <= 0):
        raise ValidationError(f"{name} must be a {'positive ' if positive else ''}finite time in s, got {value!r}")
    return v


def synchronise(
    frames: list[TaxelFrame],
    poses: list[PoseSample],
    *,
    clock_offset: float = 0.0,
    max_gap: float = 0.1,
) -> SyncedStream:
    """Interpolate the fingertip pose at every taxel frame time.

    Args:
        frames: taxel frames in strictly increasing time order (taxel clock), same shape and sensel area.
        poses: pose samples in strictly increasing time order (pose clock), at least two.
        clock_offset: added to every pose timestamp to bring it onto the taxel clock, s.
        max_gap: longest interval between consecutive pose samples that is interpolated across, s. Frames
            strictly inside a longer interval are marked invalid and the interval is reported in ``gaps``.

    Returns:
        A :class:`SyncedStream` with one row per taxel frame.

    Raises:
        ValidationError: empty or unordered streams, mismatched frames, fewer than two poses, a non-finite
            offset or a non-positive ``max_gap``.
    """
    clock_offset = _check_scalar("clock_offset", clock_offset)
    max_gap = _check_scalar("max_gap", max_gap, positive=True)
    t, counts, area = frames_to_arrays(frames)
    tp, pos = pose_times_positions(poses)
    if len(tp) < 2:
        raise ValidationError(f"synchronise needs at least 2 pose samples to interpolate, got {len(tp)}")
    tp = tp + clock_offset
    # Interval i spans [tp[i], tp[i+1]]; the last sample belongs to the last interval, times before the first
    # sample to the first one (searching the inner samples counts exactly that).
    i = np.searchsorted(tp[1:-1], t, side="right")
    i1 = i + 1
    t0 = tp[i]
    dt_i = tp[i1] - t0
    s = (t - t0) / dt_i
    np.minimum(np.maximum(s, 0.0, out=s), 1.0, out=s)  # np.clip's result, without its overhead
    p0 = pos[i]
    position = p0 + s[:, None] * (pos[i1] - p0)
    dt = tp[1:] - tp[:-1]
    gap_idx = np.flatnonzero(dt > max_gap) if float(dt.max()) > max_gap else ()
    if t[0] >= tp[0] and t[-1] <= tp[-1] and not len(gap_idx):
        valid = np.ones(len(t), dtype=bool)  # every frame inside the span and no dropout
    else:
        in_span = (t >= tp[0]) & (t <= tp[-1])
        # A frame exactly on a pose sample has a measured pose even if the interval after it is a dropout.
        in_gap = (dt_i > max_gap) & (s != 0.0) & (s != 1.0)
        valid = in_span & ~in_gap
    # Only dropouts that matter for the taxel stream are reported: those overlapping its time span.
    gaps = [
        Gap(float(tp[k]), float(tp[k + 1]), float(dt[k]))
        for k in gap_idx
        if tp[k + 1] > t[0] and tp[k] < t[-1]
    ]
    return SyncedStream(t, counts, float(area), position, partial(_orientation, poses, i, s), valid, gaps,
                        clock_offset)


def _orientation(poses: list[PoseSample], i: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Orientation between pose samples i and i + 1 at fractions s (slerp), (n, 4)."""
    quat = np.array([p.quaternion for p in poses])
    return slerp(quat[i], quat[i + 1], s)


def estimate_clock_offset(
    frames: list[TaxelFrame],
    poses: list[PoseSample],
    *,
    max_offset: float = 0.5,
    resolution: float = 1e-3,
    press_axis: tuple[float, float, float] = (0.0, 0.0, -1.0),
) -> float:
    """Estimate the offset (s) to add to pose timestamps so that they match the taxel clock.

    While the fingertip touches an object, contact intensity grows monotonically with indentation, so with the
    right offset the sum of counts and the height below the pose track are monotonically related. The estimate
    maximises the rank (Spearman) correlation between the two over the in-contact frames, first on a coarse grid
    over [-max_offset, max_offset] and then refined around the best value down to ``resolution``. It needs at
    least one press with pose motion during contact.

    Args:
        frames, poses: the two streams on their own clocks.
        max_offset: largest offset magnitude searched, s.
        resolution: final step of the search, s.
        press_axis: direction the finger presses in (world frame); height is measured against it.

    Raises:
        ValidationError: when the frames show no contact or the pose does not move during contact.
    """
    max_offset = _check_scalar("max_offset", max_offset, positive=True)
    resolution = _check_scalar("resolution", resolution, positive=True)
    t, counts, _ = frames_to_arrays(frames)
    tp, pos = pose_times_positions(poses)
    axis = np.asarray(press_axis, dtype=float)
    axis = axis / np.linalg.norm(axis)
    depth_p = pos @ axis  # grows as the finger moves into the object
    c_p = counts.reshape(len(t), -1).sum(axis=1, dtype=np.int64).astype(float)
    contact = c_p > 0
    if np.count_nonzero(contact) < 5:
        raise ValidationError("estimate_clock_offset: fewer than 5 taxel frames show contact; cannot align clocks")
    t_c, p_c = t[contact], _ranks(c_p[contact])

    def score(offset: float) -> float:
        d = np.interp(t_c, tp + offset, depth_p)
        inside = (t_c >= tp[0] + offset) & (t_c <= tp[-1] + offset)
        if np.count_nonzero(inside) < 5:
            return -np.inf
        r_d = _ranks(d[inside])
        r_p = p_c[inside]
        sd, sp = r_d.std(), r_p.std()
        if sd == 0 or sp == 0:
            return -np.inf
        return float(np.mean((r_d - r_d.mean()) * (r_p - r_p.mean())) / (sd * sp))

    step = max(resolution, max_offset / 100.0)
    centre, half = 0.0, max_offset
    best = None
    while True:
        grid = np.arange(centre - half, centre + half + 0.5 * step, step)
        scores = np.array([score(o) for o in grid])
        if not np.any(np.isfinite(scores)):
            raise ValidationError(
                "estimate_clock_offset: the pose does not overlap or does not move during contact for any offset "
                f"within +-{max_offset} s"
            )
        best = float(grid[int(np.argmax(scores))])
        if step <= resolution:
            return best
        centre, half = best, 2 * step
        step = max(resolution, step / 10.0)


def _ranks(x: np.ndarray) -> np.ndarray:
    """Ranks of x, 1-based, ties given their mean rank (as scipy.stats.rankdata, without importing scipy.stats,
    which costs a worker process most of a second at start-up)."""
    x = np.asarray(x)
    order = np.argsort(x, kind="mergesort")
    xs = x[order]
    # first index of each run of equal values, and the mean 1-based rank of that run
    starts = np.flatnonzero(np.concatenate(([True], xs[1:] != xs[:-1])))
    ends = np.append(starts[1:], len(xs))
    mean_rank = (starts + ends + 1) / 2.0
    ranks = np.empty(len(x), dtype=float)
    ranks[order] = np.repeat(mean_rank, ends - starts)
    return ranks
