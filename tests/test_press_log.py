"""The run's timeline: presses laid one after another, their samples moved in time and nothing else, and the
recording holding exactly what the run perceived."""

from __future__ import annotations

import math

import numpy as np
import pytest

from palpate.core.errors import ValidationError
from palpate.core.io.mcap_reader import read_recording
from palpate.core.perception.streams import GroundTruth, PoseSample, PressRecording, TaxelFrame, shifted_in_time
from palpate.core.session.press_log import PressLog


def _press(rng, t0: float, n_frames: int = 30, n_poses: int = 18) -> PressRecording:
    frames = [TaxelFrame(t0 + 0.02 * i, rng.integers(0, 256, (4, 4), dtype=np.uint8), 6.25e-6)
              for i in range(n_frames)]
    poses = [PoseSample(t0 + 0.033 * i + 0.001, rng.normal(size=3), rng.normal(size=4)) for i in range(n_poses)]
    t = t0 + 0.002 * np.arange(300)
    truth = GroundTruth(t, rng.random(300), 1e-3 * rng.random(300), "soft")
    return PressRecording(frames, poses, truth, {"target": {"x": 0.01, "y": 0.02}})


def test_shifted_samples_differ_in_time_only(rng):
    rec = _press(rng, 3.7)
    for samples in (rec.frames, rec.poses):
        moved = shifted_in_time(samples, 12.25)
        for a, b in zip(samples, moved, strict=True):
            assert type(b) is type(a) and b.t == a.t + 12.25
            for name, value in vars(a).items():
                if name != "t":
                    assert getattr(b, name) is value  # the validated arrays themselves, not copies
    assert rec.frames[0].t == 3.7  # the originals keep their times


def test_a_shift_that_leaves_the_finite_range_is_refused(rng):
    rec = _press(rng, 0.0)
    with pytest.raises(ValidationError, match="finite"):
        shifted_in_time(rec.frames, math.nan)
    with pytest.raises(ValidationError, match="finite range"):
        shifted_in_time([TaxelFrame(1e308, np.zeros((4, 4), np.uint8), 1e-6)], 1e308)


def test_presses_follow_each_other_and_the_recording_holds_what_was_perceived(rng, tmp_path):
    path = tmp_path / "run.mcap"
    log = PressLog(path, {"scenario": "t"})
    recs = [_press(rng, 5.0), _press(rng, -2.0), _press(rng, 0.3)]
    shifted = [log.add(r, {"k": k}) for k, r in enumerate(recs)]
    log.close()
    starts = [min(s.frames[0].t, s.poses[0].t) for s in shifted]
    assert starts[0] == 0.0
    for prev, start in zip(shifted, starts[1:], strict=False):
        end = max(prev.frames[-1].t, prev.poses[-1].t)
        assert start == math.ceil(end + PressLog.GAP)
    for rec, s in zip(recs, shifted, strict=True):
        dt = s.frames[0].t - rec.frames[0].t
        assert [f.t for f in s.frames] == [f.t + dt for f in rec.frames]
        assert [p.t for p in s.poses] == [p.t + dt for p in rec.poses]
        np.testing.assert_array_equal(s.truth.t, rec.truth.t + dt)
        assert s.meta == rec.meta and s.meta is not rec.meta
    back = read_recording(path)
    frames = [f for s in shifted for f in s.frames]
    poses = [p for s in shifted for p in s.poses]
    assert [f.t for f in back.frames] == [f.t for f in frames]
    assert all(np.array_equal(a.counts, b.counts) for a, b in zip(back.frames, frames, strict=True))
    assert [p.t for p in back.poses] == [p.t for p in poses]
    assert all(np.array_equal(a.position, b.position) for a, b in zip(back.poses, poses, strict=True))
    assert [a.data["k"] for a in back.annotations if a.kind == "press"] == [0, 1, 2]
