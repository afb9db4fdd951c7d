"""The streaming path (one taxel frame or pose at a time) finds exactly the presses of the batch path, to the bit,
on clean and noisy streams, with a pose dropout, a clock offset, a tilted press axis and any interleaving."""

from __future__ import annotations

import numpy as np
import pytest
from synthetic_streams import PressSpec, make_recording

from palpate.core.errors import ValidationError
from palpate.core.perception.pipeline import PipelineConfig, presses_from_recording
from palpate.core.perception.stream_pipeline import StreamingPipeline
from palpate.core.perception.streams import PoseSample, TaxelFrame
from palpate.core.perception.sync import synchronise

SPECS = [
    PressSpec(0.3, 0.004, hold=0.3, x=0.00, y=0.00),
    PressSpec(1.9, 0.003, x=0.02, y=0.00),
    PressSpec(2.95, 0.002, approach=0.001, x=0.02, y=0.02),  # a short pause before it
    PressSpec(3.8, 0.0003, x=0.0, y=0.02),  # too shallow: rejected
    PressSpec(4.6, 0.005, speed=0.02, x=0.01, y=0.01),
]

STREAMS = {
    "clean": dict(),
    "noisy": dict(sensel_noise=0.7, pose_noise=3e-5, intensity_noise=4.0),
    "dropout": dict(pose_gap=(2.0, 2.25), sensel_noise=0.4),
    "offset, 240 Hz poses": dict(clock_offset=0.07, pose_rate=240.0, pose_noise=1e-5),
    "ends in contact": dict(t_end=4.9),
}


def _feed(pipe: StreamingPipeline, frames, poses, order: np.ndarray):
    """Feed frames and poses in the order given by ``order`` (0 = next frame, 1 = next pose)."""
    got, fi, pi = [], 0, 0
    for k in order:
        if k == 0:
            got += pipe.feed_frame(frames[fi])
            fi += 1
        else:
            got += pipe.feed_pose(poses[pi])
            pi += 1
    return got + pipe.finish()


def _orders(rng, frames, poses):
    """In time order (as a live session), all frames first, all poses first, and a random interleaving."""
    tf = np.array([f.t for f in frames])
    tp = np.array([p.t for p in poses])
    by_time = np.argsort(np.concatenate([tf, tp]), kind="stable") >= len(tf)
    shuffled = np.r_[np.zeros(len(tf), int), np.ones(len(tp), int)]
    rng.shuffle(shuffled)
    return {"time": by_time.astype(int), "frames first": np.r_[np.zeros(len(tf), int), np.ones(len(tp), int)],
            "poses first": np.r_[np.ones(len(tp), int), np.zeros(len(tf), int)], "random": shuffled}


def _assert_same(got, want):
    assert len(got) == len(want)
    for p, q in zip(got, want, strict=True):
        for name, value in vars(q).items():
            other = getattr(p, name)
            if isinstance(value, np.ndarray):
                assert other.dtype == value.dtype and np.array_equal(other, value), name
            else:
                assert other == value, name


@pytest.mark.parametrize("name", list(STREAMS))
@pytest.mark.parametrize("axis", [(0.0, 0.0, -1.0), (0.1, -0.05, -1.0)])
def test_streaming_presses_are_the_batch_presses_bit_for_bit(rng, name, axis):
    kw = dict(STREAMS[name])
    t_end = kw.pop("t_end", 5.6)
    offset = kw.get("clock_offset", 0.0)
    rec = make_recording(SPECS, rng=rng, t_end=t_end, n1=80.0, **kw).recording
    config = PipelineConfig(clock_offset=offset, press_axis=axis)
    batch = presses_from_recording(rec, config)
    assert len(batch.presses) >= 3
    for label, order in _orders(rng, rec.frames, rec.poses).items():
        pipe = StreamingPipeline(batch.thresholds, config)
        got = _feed(pipe, rec.frames, rec.poses, order)
        _assert_same(got, batch.presses)
        assert [(r.index, r.reason, r.t_onset, r.t_end) for r in pipe.rejected] == \
               [(r.index, r.reason, r.t_onset, r.t_end) for r in batch.rejected], label
        sync = synchronise(rec.frames, rec.poses, clock_offset=offset, max_gap=config.max_gap)
        assert pipe.gaps == sync.gaps, label


def test_presses_come_out_when_they_are_released(rng):
    rec = make_recording(SPECS[:2], rng=rng, t_end=3.0, n1=80.0, pose_rate=240.0).recording
    batch = presses_from_recording(rec)
    pipe = StreamingPipeline(batch.thresholds)
    frames = iter(rec.frames)
    released_at = []
    for pose in rec.poses:  # poses at 240 Hz, each frame fed once the pose stream has passed it
        for p in pipe.feed_pose(pose):
            released_at.append((p.index, pose.t))
        while (f := next(frames, None)) is not None:
            for p in pipe.feed_frame(f):
                released_at.append((p.index, pose.t))
            if f.t > pose.t:
                break
    pipe.finish()
    assert [i for i, _ in released_at] == [p.index for p in batch.presses]
    for (_, t), p in zip(released_at, batch.presses, strict=True):
        assert p.t_release <= t < p.t_release + 0.05  # within a frame and a pose of the release


def test_a_stream_starting_in_contact_and_bad_input(rng):
    rec = make_recording(SPECS[:2], rng=rng, t_end=3.0, n1=80.0).recording
    start = next(i for i, f in enumerate(rec.frames) if f.t > 0.6)  # inside the first press
    frames = rec.frames[start:]
    poses = [p for p in rec.poses if p.t > 0.5]
    batch = presses_from_recording(type(rec)(frames, poses))
    pipe = StreamingPipeline(batch.thresholds)
    got = _feed(pipe, frames, poses, np.r_[np.ones(len(poses), int), np.zeros(len(frames), int)])
    _assert_same(got, batch.presses)
    assert pipe.rejected[0].reason.startswith("partial: stream starts in contact")
    pipe = StreamingPipeline(batch.thresholds)
    pipe.feed_frame(frames[1])
    with pytest.raises(ValidationError, match="increase strictly"):
        pipe.feed_frame(frames[0])
    with pytest.raises(ValidationError, match="shape"):
        pipe.feed_frame(TaxelFrame(frames[2].t, np.zeros((3, 3), np.uint8), frames[2].sensel_area))
    pipe.feed_pose(PoseSample(0.0, (0, 0, 0.03)))
    with pytest.raises(ValidationError, match="at least 2 pose samples"):
        pipe.finish()
    with pytest.raises(ValidationError, match="noise_threshold"):
        StreamingPipeline(batch.thresholds, PipelineConfig(noise_threshold=300))
