"""One session from a taxel stream and a pose stream recorded apart: poses on the taxel clock, in the grid frame.

The session keeps the taxel clock (the pad's frames are the perception's timeline) and moves the poses onto it
with a :class:`~palpate.core.alignment.clock.ClockMap`, into the workspace grid with a
:class:`~palpate.core.alignment.calibration.WorkspaceTransform`. Poses that fall outside the taxel span (with a
margin) or before time 0 (a recording's times are >= 0) are dropped; nothing else is changed or invented.
The press axis is then taken from each press's motion (``SESSION_PIPELINE``), since a person rarely presses
along the tracker's z.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from palpate.core.alignment.calibration import IDENTITY, WorkspaceTransform
from palpate.core.alignment.clock import ClockMap, check_overlap
from palpate.core.errors import ValidationError
from palpate.core.perception.pipeline import PipelineConfig
from palpate.core.perception.streams import PoseSample, TaxelFrame, frames_to_arrays, poses_to_arrays

#: Poses kept beyond each end of the taxel span, s (the approach to the first press, the retreat from the last).
MARGIN = 1.0
#: How a session is perceived (recorded in its metadata as ``perception``): press axis from the motion.
SESSION_PIPELINE = {"press_axis_from_motion": True}


@dataclass(frozen=True)
class MergedSession:
    """Streams on one clock and in one frame.

    Attributes:
        frames: the taxel frames, unchanged.
        poses: the poses, on the taxel clock and in the grid frame.
        clock: the clock map used.
        transform: the workspace transform used.
        dropped_poses: poses outside the kept span.
    """

    frames: list[TaxelFrame]
    poses: list[PoseSample]
    clock: ClockMap
    transform: WorkspaceTransform
    dropped_poses: int

    def metadata(self) -> dict:
        """What the session file records about how it was made (JSON-ready)."""
        return session_metadata(self.clock, self.transform, self.dropped_poses)


def session_metadata(clock: ClockMap, transform: WorkspaceTransform, dropped_poses: int) -> dict:
    """What a session file records about how it was made (JSON-ready): clock map, transform, dropped poses and
    how to perceive it."""
    return {"clock": clock.to_dict(), "workspace": transform.to_dict(), "dropped_poses": dropped_poses,
            "perception": dict(SESSION_PIPELINE)}


def merge_session(frames: list[TaxelFrame], poses: list[PoseSample], clock: ClockMap,
                  transform: WorkspaceTransform = IDENTITY, *, sensor_id: str | None = None) -> MergedSession:
    """Poses mapped onto the taxel clock and into the grid frame beside the unchanged frames.

    Args:
        frames: one pad's frames (taxel clock).
        poses: one station's poses (pose clock, tracker frame).
        clock: pose clock -> taxel clock.
        transform: tracker frame -> grid frame.
        sensor_id: rename the poses (None keeps their id).

    Raises:
        ValidationError: the streams do not overlap once mapped, or fewer than two poses remain.
    """
    t, _, _ = frames_to_arrays(frames)
    kept, dropped = map_poses(t[0], t[-1], poses, clock, transform, sensor_id=sensor_id)
    return MergedSession(list(frames), kept, clock, transform, dropped)


def map_poses(t_first: float, t_last: float, poses: list[PoseSample], clock: ClockMap,
              transform: WorkspaceTransform = IDENTITY, *, sensor_id: str | None = None
              ) -> tuple[list[PoseSample], int]:
    """The poses on the taxel clock and in the grid frame that fall within the taxel span ``t_first``..``t_last``
    (s, with ``MARGIN``), and how many were dropped; see :func:`merge_session`."""
    t = np.array([t_first, t_last], dtype=float)
    tp, _, _ = poses_to_arrays(poses)
    check_overlap(clock, tp, t)
    mapped = clock.to_taxel(tp)
    keep = (mapped >= max(t[0] - MARGIN, 0.0)) & (mapped <= t[-1] + MARGIN)
    if np.count_nonzero(keep) < 2:
        raise ValidationError("after the clock map fewer than 2 poses fall inside the taxel stream's span")
    if np.any(np.diff(mapped[keep]) <= 0):
        raise ValidationError("the clock map puts pose times out of order (a drift near -1?)")
    kept = [PoseSample(float(tm), p.position, p.quaternion, sensor_id or p.sensor_id)
            for p, tm, k in zip(poses, mapped, keep, strict=True) if k]
    return transform.apply(kept), int(np.count_nonzero(~keep))


def perception_of(metadata) -> dict | None:
    """The ``session.perception`` a recording's (or a press's) metadata asks for, or None."""
    session = metadata.get("session") if isinstance(metadata, dict) else None
    wanted = session.get("perception") if isinstance(session, dict) else None
    return wanted if isinstance(wanted, dict) else None


def pipeline_for(perception: dict | None, base: PipelineConfig | None = None) -> PipelineConfig:
    """``base`` (default settings when None) with what ``perception`` asks for (see ``SESSION_PIPELINE``)."""
    base = base or PipelineConfig()
    if not perception:
        return base
    from_motion = perception.get("press_axis_from_motion", base.press_axis_from_motion)
    if not isinstance(from_motion, bool):
        raise ValidationError(f"recording metadata session.perception.press_axis_from_motion must be true or false, "
                              f"got {from_motion!r}")
    features = perception.get("features", base.features)
    gain = perception.get("calibration_n_per_count")
    if gain is not None and not (isinstance(gain, int | float) and not isinstance(gain, bool) and gain > 0):
        raise ValidationError(f"recording metadata session.perception.calibration_n_per_count must be a number > 0, "
                              f"got {gain!r}")
    return replace(base, press_axis_from_motion=from_motion, features=features,
                   calibration=base.calibration if gain is None else float(gain))


def session_pipeline(metadata: dict, base: PipelineConfig | None = None) -> PipelineConfig:
    """The pipeline a recording asks for in its ``session.perception`` metadata (``base`` otherwise)."""
    return pipeline_for(perception_of(metadata), base)
