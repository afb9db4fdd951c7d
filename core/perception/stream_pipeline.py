"""The signal path fed one taxel frame or one pose sample at a time: sync -> contact features -> segmentation.

:class:`StreamingPipeline` is what :func:`~palpate.core.perception.pipeline.presses_from_recording` does to a whole
recording, done as the samples arrive (a live Tekscan + Liberty session, a recording read message by message):
each taxel frame waits only until a pose sample later than it has arrived, then gets its pose interpolated
exactly as :func:`~palpate.core.perception.sync.synchronise` would, its contact features, and goes through a
:class:`~palpate.core.perception.streaming.StreamSegmenter`. With the same thresholds (e.g. those of a batch run
or of a calibration stretch) it finds the same presses to the bit, and a sample costs the same however long the
stream has run: nothing is kept but the frames waiting for a pose, the poses from the one before the oldest
waiting frame on (two, when the streams keep pace) and the current contact.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.perception.features import check_noise_threshold, intensity_and_area, press_axis_unit
from palpate.core.perception.pipeline import DEFAULT_CONFIG, PipelineConfig
from palpate.core.perception.segment import Press, RejectedPress
from palpate.core.perception.streaming import StreamSegmenter
from palpate.core.perception.streams import PoseSample, TaxelFrame
from palpate.core.perception.sync import Gap
from palpate.core.perception.thresholds import Thresholds


class StreamingPipeline:
    """Sync, contact features and segmentation of streams fed sample by sample.

    Args:
        thresholds: hysteresis levels on c_P for the whole stream (e.g. ``presses_from_recording(...).thresholds``
            of a calibration recording, or :func:`~palpate.core.perception.thresholds.estimate_thresholds` of a
            stretch of the stream).
        config: the same knobs as the batch path (clock offset, gap, noise threshold, calibration, press axis,
            press limits; its on/off thresholds are ignored in favour of ``thresholds``). A callable calibration
            is called with one frame at a time, shape (1, rows, cols).

    Frames must come in time order, and so must poses; the two streams may interleave in any way. Rejected
    contacts accumulate in :attr:`rejected`, pose dropouts longer than ``config.max_gap`` in :attr:`gaps`.
    """

    def __init__(self, thresholds: Thresholds, config: PipelineConfig = DEFAULT_CONFIG):
        check_noise_threshold(config.noise_threshold)
        self.config = config
        self.segmenter = StreamSegmenter(thresholds, min_duration=config.min_duration, min_depth=config.min_depth,
                                         min_samples=config.min_samples, calibrated=config.calibration is not None)
        self._axis = tuple(float(a) for a in press_axis_unit(config.press_axis))
        self._vertical = self._axis == (0.0, 0.0, -1.0)
        self._frames: deque[tuple[float, float, float]] = deque()  # (t, c_P, c_A) of frames not yet placed
        # Poses from the one before the oldest waiting frame on (poses may run ahead of the frames).
        self._poses: deque[tuple[float, tuple[float, float, float]]] = deque()
        self._first_pose_t: float | None = None
        self._pose_gaps: list[Gap] = []
        self._t_pose: float | None = None
        self._t_frame: float | None = None
        self._frame_span: tuple[float, float] | None = None
        self._shape: tuple[int, ...] | None = None
        self._area = 0.0

    @property
    def rejected(self) -> list[RejectedPress]:
        """Every contact rejected so far, with its reason."""
        return self.segmenter.rejected

    @property
    def gaps(self) -> list[Gap]:
        """Pose dropouts longer than ``max_gap`` overlapping the frames so far (taxel clock)."""
        if self._frame_span is None:
            return []
        t_a, t_b = self._frame_span
        return [g for g in self._pose_gaps if g.t_end > t_a and g.t_start < t_b]

    def feed_frame(self, frame: TaxelFrame) -> list[Press]:
        """One taxel frame (taxel clock); returns the presses it completes (usually none)."""
        if self._t_frame is not None and not frame.t > self._t_frame:
            raise ValidationError(f"taxel frame times must increase strictly; frame at t={frame.t} after "
                                  f"t={self._t_frame}")
        counts = frame.counts
        if self._shape is None:
            self._shape, self._area = counts.shape, float(frame.sensel_area)
        elif counts.shape != self._shape:
            raise ValidationError(f"taxel frame at t={frame.t} has shape {counts.shape}, expected {self._shape}")
        elif abs(frame.sensel_area - self._area) > 1e-9 * abs(self._area):
            raise ValidationError(f"taxel frame at t={frame.t} has sensel area {frame.sensel_area}, expected "
                                  f"{self._area}")
        self._t_frame = frame.t
        self._frame_span = (frame.t if self._frame_span is None else self._frame_span[0], frame.t)
        self._frames.append((frame.t, *self._features(counts)))
        return self._place_frames()

    def feed_pose(self, pose: PoseSample) -> list[Press]:
        """One pose sample (pose clock); returns the presses released by the frames it lets be placed."""
        if self._t_pose is not None and not pose.t > self._t_pose:
            raise ValidationError(f"pose times must increase strictly; sample at t={pose.t} after t={self._t_pose}")
        self._t_pose = pose.t
        tp = pose.t + self.config.clock_offset
        if self._poses:
            prev = self._poses[-1][0]
            if tp - prev > self.config.max_gap:
                self._pose_gaps.append(Gap(prev, tp, tp - prev))
        else:
            self._first_pose_t = tp
        p = pose.position
        self._poses.append((tp, (float(p[0]), float(p[1]), float(p[2]))))
        return self._place_frames()

    def finish(self) -> list[Press]:
        """End of both streams: the frames after the last pose are placed on it (invalid, as in the batch path);
        a contact still open is rejected as partial."""
        if self._frames and len(self._poses) < 2:
            raise ValidationError(f"synchronise needs at least 2 pose samples to interpolate, got {len(self._poses)}")
        out = self._place_frames(final=True)
        self.segmenter.finish()
        return out

    def _features(self, counts: np.ndarray) -> tuple[float, float]:
        """(c_P, c_A m^2) of one frame, by the batch path's own function on a stack of one."""
        cfg = self.config
        c_p, c_a = intensity_and_area(counts[None], self._area, cfg.noise_threshold, cfg.calibration)
        return float(c_p[0]), float(c_a[0])

    def _place_frames(self, final: bool = False) -> list[Press]:
        """Give every waiting frame that two poses now bracket its pose (all of them when ``final``), in order,
        and segment it: :func:`~palpate.core.perception.sync.synchronise`'s interpolation and validity."""
        frames, poses, out = self._frames, self._poses, []
        max_gap, push = self.config.max_gap, self.segmenter.push
        while frames and len(poses) >= 2:
            t, c_p, c_a = frames[0]
            while len(poses) > 2 and poses[1][0] <= t:
                poses.popleft()
            (t0, p0), (t1, p1) = poses[0], poses[1]
            if not (final or t < t1):
                break  # a later pose is still to come
            frames.popleft()
            s = min(max((t - t0) / (t1 - t0), 0.0), 1.0)  # np.clip's value
            x, y, z = (a + s * (b - a) for a, b in zip(p0, p1, strict=True))
            valid = self._first_pose_t <= t <= t1 and not (t1 - t0 > max_gap and s != 0.0 and s != 1.0)
            if self._vertical:
                h = z
            else:
                ax = self._axis
                h = -(x * ax[0] + y * ax[1] + z * ax[2])
            press = push(t, c_p, c_a, h, x, y, valid)
            if press is not None:
                out.append(press)
        return out
