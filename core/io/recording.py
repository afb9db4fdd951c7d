"""What a recording holds once read: the streams of every sensor, joint states, annotations, ground truth and the
writer's metadata; and the one taxel pad + one pose sensor the perception stack takes from it."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.perception.streams import GroundTruth, PoseSample, PressRecording, TaxelFrame


@dataclass(frozen=True)
class JointState:
    """Joint readings of an actuator (e.g. the servos of a Dynamixel finger) at one time.

    Attributes:
        t: timestamp, s.
        names: joint names, one per joint.
        position: joint positions, rad (m for a prismatic joint), shape (n,).
        velocity: joint velocities, rad/s, shape (n,).
        current: motor currents, A, shape (n,).
    """

    t: float
    names: tuple[str, ...]
    position: np.ndarray
    velocity: np.ndarray
    current: np.ndarray

    def __post_init__(self) -> None:
        names = tuple(self.names)
        if not all(isinstance(n, str) and n for n in names):
            raise ValidationError(f"JointState.names must be non-empty strings, got {self.names!r}")
        object.__setattr__(self, "names", names)
        for key in ("position", "velocity", "current"):
            arr = np.asarray(getattr(self, key), dtype=float).reshape(-1)
            if arr.shape != (len(names),):
                raise ValidationError(f"JointState.{key} must have one value per joint ({len(names)}), got {arr.shape}")
            if not np.all(np.isfinite(arr)):
                raise ValidationError(f"JointState.{key} must be finite, got {arr.tolist()}")
            object.__setattr__(self, key, arr)
        if not np.isfinite(self.t):
            raise ValidationError(f"JointState.t must be finite, got {self.t!r}")


@dataclass(frozen=True)
class Annotation:
    """A timed event in a recording (e.g. ``kind="press_start"``, data ``{"label": "Region_3"}``).

    Attributes:
        t: timestamp, s.
        kind: what happened (a short identifier).
        data: JSON-serialisable details.
    """

    t: float
    kind: str
    data: dict = field(default_factory=dict)


@dataclass
class Recording:
    """Everything read back from one recording, each stream in file order.

    Attributes:
        frames: taxel frames of every taxel sensor.
        poses: pose samples of every pose sensor.
        joints: joint states.
        annotations: annotations.
        truth: ground truth assembled from ``/truth`` (None if the recording has none, as real ones do).
        metadata: the metadata dict the writer was given.
        salvaged: True when the file was truncated or damaged and only its complete chunks were read.
        versions: software versions recorded by the writer (name -> version string).
    """

    frames: list[TaxelFrame]
    poses: list[PoseSample]
    joints: list[JointState]
    annotations: list[Annotation]
    truth: GroundTruth | None
    metadata: dict
    salvaged: bool = False
    versions: dict = field(default_factory=dict)


def recording_to_press_recording(rec: Recording, *, taxel_sensor: str | None = None,
                                 pose_sensor: str | None = None) -> PressRecording:
    """The streams the perception stack consumes: one taxel pad and one pose sensor of a recording.

    Args:
        rec: a recording from :func:`~palpate.core.io.mcap_reader.read_recording`.
        taxel_sensor, pose_sensor: which sensor to take when the recording has several (required then).

    The metadata is copied into ``meta``, with the annotations as a list of ``{"t", "kind", "data"}`` under
    ``meta["annotations"]``.
    """
    taxel = _pick(taxel_sensor, {f.sensor_id for f in rec.frames}, "taxel")
    pose = _pick(pose_sensor, {p.sensor_id for p in rec.poses}, "pose")
    frames = [f for f in rec.frames if f.sensor_id == taxel]
    poses = [p for p in rec.poses if p.sensor_id == pose]
    meta = dict(rec.metadata)
    if rec.annotations:
        meta["annotations"] = [{"t": a.t, "kind": a.kind, "data": a.data} for a in rec.annotations]
    if rec.salvaged:
        meta["salvaged"] = True
    return PressRecording(frames=frames, poses=poses, truth=rec.truth, meta=meta)


def _pick(wanted: str | None, present: set[str], what: str) -> str | None:
    if wanted is not None:
        if wanted not in present:
            raise ValidationError(f"no {what} sensor {wanted!r} in the recording; it has {sorted(present)}")
        return wanted
    if len(present) > 1:
        raise ValidationError(f"the recording has several {what} sensors {sorted(present)}; choose one")
    return next(iter(present), None)
