"""Frames and poses built from arrays equal the ones built one by one, and bad arrays are refused alike."""

from __future__ import annotations

import numpy as np
import pytest

from palpate.core.errors import ValidationError
from palpate.core.perception.streams import PoseSample, TaxelFrame, pose_samples, taxel_frames


def test_builders_equal_one_by_one():
    rng = np.random.default_rng(3)
    t = np.cumsum(rng.uniform(0.01, 0.03, 40))
    counts = rng.integers(0, 256, (40, 4, 4)).astype(np.uint8)
    frames = taxel_frames(t, counts, 2.5e-5, "pad")
    for f, ts, c in zip(frames, t, counts, strict=True):
        one = TaxelFrame(float(ts), c, 2.5e-5, "pad")
        assert (f.t, f.sensel_area, f.sensor_id) == (one.t, one.sensel_area, one.sensor_id)
        assert f.counts.dtype == np.uint8 and np.array_equal(f.counts, one.counts)
    pos = rng.normal(0.0, 0.01, (40, 3))
    quat = np.column_stack([np.ones(40), rng.normal(0.0, 0.01, (40, 3))]) * rng.uniform(0.5, 2.0, (40, 1))
    poses = pose_samples(t, pos, quat)
    for p, ts, x, q in zip(poses, t, pos, quat, strict=True):
        one = PoseSample(float(ts), x, q)
        assert p.t == one.t and p.sensor_id == one.sensor_id
        assert np.array_equal(p.position, one.position) and np.array_equal(p.quaternion, one.quaternion)
    assert abs(np.linalg.norm(poses[0].quaternion) - 1.0) < 1e-12


def test_builders_refuse_what_one_by_one_refuses():
    t = np.arange(3) * 0.02
    with pytest.raises(ValidationError, match="uint8"):
        taxel_frames(t, np.zeros((3, 4, 4), dtype=np.int16), 1e-5)
    with pytest.raises(ValidationError, match="shape"):
        taxel_frames(t, np.zeros((2, 4, 4), dtype=np.uint8), 1e-5)
    with pytest.raises(ValidationError, match="sensel_area"):
        taxel_frames(t, np.zeros((3, 4, 4), dtype=np.uint8), 0.0)
    with pytest.raises(ValidationError, match="finite"):
        taxel_frames(np.array([0.0, np.nan, 0.04]), np.zeros((3, 4, 4), dtype=np.uint8), 1e-5)
    with pytest.raises(ValidationError, match="zero norm"):
        pose_samples(t, np.zeros((3, 3)), np.zeros((3, 4)))
    with pytest.raises(ValidationError, match="positions"):
        pose_samples(t, np.full((3, 3), np.inf), np.tile([1.0, 0, 0, 0], (3, 1)))
