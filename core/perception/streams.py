"""Stream types shared by every source (simulation, replay, hardware) and the perception stack.

All quantities are SI: seconds, metres, square metres. Raw taxel counts stay ``uint8`` exactly as a
Tekscan-like sensor reports them; calibration to force happens later, in :mod:`palpate.core.perception.features`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from operator import attrgetter

import numpy as np

from palpate.core.errors import ValidationError


@dataclass(frozen=True)
class TaxelFrame:
    """One frame of a tactile array.

    Attributes:
        t: timestamp, s (on the taxel sensor's own clock).
        counts: raw 8-bit counts, shape (rows, cols), dtype uint8.
        sensel_area: area of one sensing element, m^2.
        sensor_id: name of the array (several pads may stream at once).
    """

    t: float
    counts: np.ndarray
    sensel_area: float
    sensor_id: str = "taxels"

    def __post_init__(self) -> None:
        counts = np.asarray(self.counts)
        if counts.ndim != 2:
            raise ValidationError(f"TaxelFrame.counts must be 2-D (rows, cols), got shape {counts.shape}")
        if counts.dtype != np.uint8:
            if not np.issubdtype(counts.dtype, np.integer) or counts.min(initial=0) < 0 or counts.max(
                initial=0
            ) > 255:
                raise ValidationError(
                    f"TaxelFrame.counts must be uint8 raw counts (0..255), got dtype {counts.dtype}"
                )
            counts = counts.astype(np.uint8)
        object.__setattr__(self, "counts", counts)
        if not np.isfinite(self.t):
            raise ValidationError(f"TaxelFrame.t must be finite, got {self.t!r}")
        if not (np.isfinite(self.sensel_area) and self.sensel_area > 0):
            raise ValidationError(f"TaxelFrame.sensel_area must be a positive area in m^2, got {self.sensel_area!r}")


@dataclass(frozen=True)
class PoseSample:
    """One pose of the fingertip (e.g. a Polhemus Liberty station).

    Attributes:
        t: timestamp, s (on the pose sensor's own clock).
        position: (x, y, z), m, in the world frame; z points up, so pressing into an object lowers z.
        quaternion: unit quaternion (w, x, y, z), normalised on construction.
        sensor_id: station name.
    """

    t: float
    position: np.ndarray
    quaternion: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0, 0.0]))
    sensor_id: str = "pose"

    def __post_init__(self) -> None:
        pos = np.asarray(self.position, dtype=float).reshape(-1)
        quat = np.asarray(self.quaternion, dtype=float).reshape(-1)
        if pos.shape != (3,) or not np.all(np.isfinite(pos)):
            raise ValidationError(f"PoseSample.position must be 3 finite numbers (m), got {self.position!r}")
        if quat.shape != (4,) or not np.all(np.isfinite(quat)):
            raise ValidationError(f"PoseSample.quaternion must be 4 finite numbers (w,x,y,z), got {self.quaternion!r}")
        norm = float(np.linalg.norm(quat))
        if norm < 1e-9:
            raise ValidationError("PoseSample.quaternion has zero norm")
        if not np.isfinite(self.t):
            raise ValidationError(f"PoseSample.t must be finite, got {self.t!r}")
        object.__setattr__(self, "position", pos)
        object.__setattr__(self, "quaternion", quat / norm)


def taxel_frames(t: np.ndarray, counts: np.ndarray, sensel_area: float, sensor_id: str = "taxels") -> list[TaxelFrame]:
    """Taxel frames from arrays: times (n,) s and counts (n, rows, cols) uint8, checked once for all frames (the
    checks of :class:`TaxelFrame`); equal to building each frame alone, at a fraction of the cost for long
    streams (each frame's counts is a view of ``counts``)."""
    t = np.asarray(t, dtype=float)
    counts = np.asarray(counts)
    if counts.ndim != 3 or len(counts) != len(t):
        raise ValidationError(f"taxel_frames: counts must have shape (n, rows, cols) with n = {len(t)} times, got "
                              f"{counts.shape}")
    if counts.dtype != np.uint8:
        raise ValidationError(f"taxel_frames: counts must be uint8 raw counts (0..255), got dtype {counts.dtype}")
    if not np.all(np.isfinite(t)):
        raise ValidationError("taxel_frames: every time must be finite")
    if not (np.isfinite(sensel_area) and sensel_area > 0):
        raise ValidationError(f"TaxelFrame.sensel_area must be a positive area in m^2, got {sensel_area!r}")
    out = []
    for ts, c in zip(t.tolist(), list(counts), strict=True):
        frame = _new(TaxelFrame)
        d = frame.__dict__
        d["t"], d["counts"], d["sensel_area"], d["sensor_id"] = ts, c, sensel_area, sensor_id
        out.append(frame)
    return out


def pose_samples(t: np.ndarray, position: np.ndarray, quaternion: np.ndarray, sensor_id: str = "pose") -> list[
        PoseSample]:
    """Pose samples from arrays: times (n,) s, positions (n, 3) m, quaternions (n, 4) (w, x, y, z), checked and
    normalised once for all samples as :class:`PoseSample` does one; equal to building each sample alone."""
    t = np.asarray(t, dtype=float)
    pos = np.asarray(position, dtype=float)
    quat = np.asarray(quaternion, dtype=float)
    n = len(t)
    if pos.shape != (n, 3) or not np.all(np.isfinite(pos)):
        raise ValidationError(f"pose_samples: positions must be ({n}, 3) finite numbers (m), got shape {pos.shape}")
    if quat.shape != (n, 4) or not np.all(np.isfinite(quat)):
        raise ValidationError(f"pose_samples: quaternions must be ({n}, 4) finite numbers, got shape {quat.shape}")
    norm = np.linalg.norm(quat, axis=1)
    if np.any(norm < 1e-9):
        raise ValidationError("PoseSample.quaternion has zero norm")
    if not np.all(np.isfinite(t)):
        raise ValidationError("pose_samples: every time must be finite")
    unit = quat / norm[:, None]
    out = []
    for ts, p, q in zip(t.tolist(), list(pos), list(unit), strict=True):
        sample = _new(PoseSample)
        d = sample.__dict__
        d["t"], d["position"], d["quaternion"], d["sensor_id"] = ts, p, q, sensor_id
        out.append(sample)
    return out


#: An instance of a frozen dataclass without its __init__: the builders above fill its fields, checked in bulk.
_new = object.__new__


@dataclass(frozen=True)
class ContactSample:
    """Contact features at one taxel time (eq. 6.2-6.4 of seed 000).

    Attributes:
        t: time, s, on the common timeline.
        c_P: contact intensity: sum of counts (or force in N when calibrated).
        c_A: contact area, m^2 (active sensels x sensel area).
        c_D: indentation along the press axis relative to the height at first contact, m (positive into the object).
        xy: fingertip (x, y) position, m.
        z: fingertip height, m.
    """

    t: float
    c_P: float
    c_A: float
    c_D: float
    xy: tuple[float, float]
    z: float


@dataclass
class GroundTruth:
    """What the simulation knows beside the streams (absent for real recordings).

    Attributes:
        t: times, s, shape (n,).
        force: true normal contact force on the fingertip, N, shape (n,).
        indentation: true indentation of the tip into the undeformed surface, m, shape (n,).
        material: name of the material under the press, if one.
    """

    t: np.ndarray
    force: np.ndarray
    indentation: np.ndarray
    material: str | None = None


@dataclass
class PressRecording:
    """The raw streams of one press-and-release (or of any stretch of time).

    Attributes:
        frames: taxel frames in time order.
        poses: pose samples in time order.
        truth: ground truth from a simulation, or None for real data.
        meta: free-form provenance (source name, target, parameters), JSON-serialisable.
    """

    frames: list[TaxelFrame]
    poses: list[PoseSample]
    truth: GroundTruth | None = None
    meta: dict = field(default_factory=dict)


#: Raw count of a saturated 8-bit sensel.
SATURATED = 255


def saturated_frames(frames: list[TaxelFrame]) -> int:
    """Number of taxel frames with at least one sensel at the 8-bit ceiling (SATURATED): counted from the frames
    themselves, so real recordings are counted the same way as simulated ones."""
    if not frames:
        return 0
    try:
        counts = np.array([f.counts for f in frames])
    except ValueError:  # frames of different shapes: one at a time
        return sum(1 for f in frames if int(f.counts.max()) >= SATURATED)
    return saturated_in(counts)


def saturated_in(counts: np.ndarray) -> int:
    """:func:`saturated_frames` of frames stacked as (n, rows, cols) raw counts."""
    return int(np.count_nonzero(counts.reshape(len(counts), -1).max(axis=1) >= SATURATED)) if len(counts) else 0


def solver_warning_steps(meta: dict | None) -> int:
    """Steps of a press on which the physics engine warned without invalidating the force, from its recording's
    metadata (``solver_warning_steps``, written by the simulated source: flex's MuJoCo M + K solve running out of
    iterations); 0 when the recording does not say (real data). ValidationError on a value that is not a count."""
    value = (meta or {}).get("solver_warning_steps", 0)
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
        raise ValidationError(f"recording metadata solver_warning_steps must be a count >= 0, got {value!r}")
    return int(value)


_AREA, _COUNTS, _T = attrgetter("sensel_area"), attrgetter("counts"), attrgetter("t")


def frames_to_arrays(frames: list[TaxelFrame]) -> tuple[np.ndarray, np.ndarray, float]:
    """Stack taxel frames into arrays.

    Returns:
        (t [n] s, counts [n, rows, cols] uint8, sensel_area m^2). Raises ValidationError if the frames disagree
        on shape or sensel area, or if time does not increase.
    """
    if not frames:
        raise ValidationError("no taxel frames")
    n = len(frames)
    first = frames[0]
    area = first.sensel_area
    # Every frame was validated when it was made; what is left to check is that they agree with each other. The
    # usual case (one sensel area, one shape) costs a set and one array; a disagreement is then located.
    # attrgetter through map: the per-frame Python work of a comprehension, without its frame (about half the cost)
    if len(set(map(_AREA, frames))) > 1:
        areas = np.fromiter((f.sensel_area for f in frames), dtype=float, count=n)
        bad_area = np.abs(areas - area) > 1e-9 * abs(area)
        if bad_area.any():
            i = int(np.argmax(bad_area))
            raise ValidationError(f"taxel frame {i} has sensel area {areas[i]}, expected {area}")
    shape = first.counts.shape
    try:
        counts = np.array(list(map(_COUNTS, frames)))
    except ValueError:  # frames of different shapes
        counts = None
    if counts is None or counts.shape[1:] != shape:
        for i, f in enumerate(frames):
            if f.counts.shape != shape:
                raise ValidationError(f"taxel frame {i} has shape {f.counts.shape}, expected {shape}")
    t = np.fromiter(map(_T, frames), dtype=float, count=n)
    _check_increasing(t, "taxel frame times must increase strictly; frame")
    return t, counts, area


def _check_increasing(t: np.ndarray, what: str) -> None:
    if len(t) > 1 and not (t[1:] > t[:-1]).all():
        bad = int(np.argmax(t[1:] <= t[:-1])) + 1
        raise ValidationError(f"{what} {bad} is at t={t[bad]}")


def pose_times_positions(poses: list[PoseSample]) -> tuple[np.ndarray, np.ndarray]:
    """(t [n] s, position [n, 3] m) of pose samples; ValidationError if time does not increase strictly."""
    if not poses:
        raise ValidationError("no pose samples")
    t = np.fromiter([p.t for p in poses], dtype=float, count=len(poses))
    _check_increasing(t, "pose times must increase strictly; sample")
    return t, np.array([p.position for p in poses])


def poses_to_arrays(poses: list[PoseSample]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Stack pose samples into arrays: (t [n] s, position [n, 3] m, quaternion [n, 4]).

    Raises ValidationError if time does not increase strictly.
    """
    t, pos = pose_times_positions(poses)
    return t, pos, np.array([p.quaternion for p in poses])


def shifted_in_time(samples: list[TaxelFrame] | list[PoseSample], dt: float) -> list:
    """Copies of taxel frames or pose samples with every timestamp moved by ``dt`` s, sharing their arrays.

    The samples were validated when they were made and only their times change, so the copies are not validated
    again (rebuilding each dataclass would check every array once more); a shift that leaves a time non-finite
    is a ValidationError.
    """
    if not math.isfinite(dt):
        raise ValidationError(f"time shift must be a finite number of seconds, got {dt!r}")
    times = [s.t + dt for s in samples]
    if not all(map(math.isfinite, times)):
        raise ValidationError(f"shifting by {dt!r} s takes a timestamp out of the finite range")
    out = []
    for s, t in zip(samples, times, strict=True):
        copy = object.__new__(type(s))
        # A frozen dataclass's fields live in its __dict__; only t differs from the validated original.
        copy.__dict__.update(s.__dict__, t=t)
        out.append(copy)
    return out
