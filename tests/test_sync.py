"""Synchronisation of taxel frames and pose samples onto the taxel clock."""

from __future__ import annotations

import numpy as np
import pytest

from palpate.core.errors import ValidationError
from palpate.core.perception.streams import PoseSample, TaxelFrame
from palpate.core.perception.sync import estimate_clock_offset, slerp, synchronise

AREA = 6.25e-6


def _frames(t, counts=None):
    return [TaxelFrame(float(ti), np.zeros((4, 4), np.uint8) if counts is None else counts[i], AREA)
            for i, ti in enumerate(t)]


def _yaw(angle):
    return np.column_stack([np.cos(angle / 2), np.zeros_like(angle), np.zeros_like(angle), np.sin(angle / 2)])


def test_linear_motion_is_interpolated_exactly(rng):
    tp = np.sort(rng.uniform(0.0, 2.0, 40))
    tp = np.concatenate([[0.0], tp, [2.0]])
    v, p0 = np.array([0.01, -0.02, 0.005]), np.array([0.1, 0.2, 0.03])
    poses = [PoseSample(t, p0 + v * t) for t in tp]
    t = np.arange(0.0, 2.0, 0.02)
    s = synchronise(_frames(t), poses, max_gap=1.0)
    np.testing.assert_allclose(s.position, p0 + v * t[:, None], atol=1e-15, rtol=1e-12)
    assert s.valid.all() and s.gaps == [] and s.counts.shape == (len(t), 4, 4)
    assert s.sensel_area == AREA


def test_slerp_follows_constant_rotation_and_stays_unit():
    tp = np.linspace(0.0, 1.0, 11)
    rate = 2.0  # rad/s about z
    poses = [PoseSample(t, np.zeros(3), q) for t, q in zip(tp, _yaw(rate * tp), strict=True)]
    t = np.linspace(0.0, 1.0, 97)
    s = synchronise(_frames(t), poses)
    np.testing.assert_allclose(np.linalg.norm(s.quaternion, axis=1), 1.0, atol=1e-12)
    # Slerp of a constant-rate rotation is exact; nlerp would be off by up to ~1e-3 here.
    np.testing.assert_allclose(s.quaternion, _yaw(rate * t), atol=1e-12)


def test_slerp_takes_the_short_way_and_handles_identical_quaternions(rng):
    q0 = rng.standard_normal((200, 4))
    q0 /= np.linalg.norm(q0, axis=1, keepdims=True)
    q1 = rng.standard_normal((200, 4))
    q1 /= np.linalg.norm(q1, axis=1, keepdims=True)
    s = rng.uniform(0.0, 1.0, 200)
    q = slerp(q0, q1, s)
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-12)
    # Angle from q0 is s times the (short) angle between q0 and q1.
    ang = lambda a, b: 2 * np.arccos(np.clip(np.abs(np.sum(a * b, axis=1)), 0, 1))  # noqa: E731
    np.testing.assert_allclose(ang(q0, q), s * ang(q0, q1), atol=1e-6)
    # -q1 is the same rotation: the result must not change.
    np.testing.assert_allclose(np.abs(np.sum(slerp(q0, -q1, s) * q, axis=1)), 1.0, atol=1e-12)
    same = slerp(q0, q0, s)
    np.testing.assert_allclose(same, q0, atol=1e-12)


def test_clock_offset_is_added_to_pose_times():
    tp = np.linspace(0.0, 1.0, 31)
    poses = [PoseSample(t, [0.0, 0.0, t]) for t in tp]  # z equals pose-clock time
    t = np.linspace(0.5, 1.2, 15)
    s = synchronise(_frames(t), poses, clock_offset=0.25)
    # On the taxel clock the pose at time t was measured at pose time t - 0.25.
    expected = t - 0.25
    inside = t <= 1.25
    np.testing.assert_allclose(s.position[inside, 2], expected[inside], atol=1e-12)
    assert s.clock_offset == 0.25


def test_frames_outside_pose_span_are_invalid_not_extrapolated():
    poses = [PoseSample(t, [0.0, 0.0, t]) for t in np.linspace(1.0, 2.0, 11)]
    t = np.array([0.5, 0.99, 1.0, 1.5, 2.0, 2.01, 3.0])
    s = synchronise(_frames(t), poses)
    assert s.valid.tolist() == [False, False, True, True, True, False, False]
    assert np.all(np.isfinite(s.position)) and np.all(np.isfinite(s.quaternion))
    assert s.n_invalid == 4


def test_gap_is_reported_and_frames_inside_it_are_invalid():
    tp = np.concatenate([np.arange(0.0, 1.0, 0.03), np.arange(1.5, 3.0, 0.03)])
    last_before = tp[tp < 1.0][-1]
    poses = [PoseSample(t, [t, 0.0, 0.0]) for t in tp]
    t = np.arange(0.0, 2.9, 0.02)
    s = synchronise(_frames(t), poses, max_gap=0.1)
    assert len(s.gaps) == 1
    g = s.gaps[0]
    assert g.t_start == pytest.approx(last_before) and g.t_end == pytest.approx(1.5)
    assert g.duration == pytest.approx(1.5 - last_before)
    in_gap = (t > last_before) & (t < 1.5)
    assert np.array_equal(~s.valid, in_gap)
    # A frame exactly on a pose sample keeps its measured pose.
    s2 = synchronise(_frames(np.array([last_before, 1.2, 1.5])), poses, max_gap=0.1)
    assert s2.valid.tolist() == [True, False, True]


def test_gap_detection_is_on_the_shifted_clock_and_ignores_gaps_outside_the_frames():
    tp = np.concatenate([np.arange(0.0, 1.0, 0.03), np.arange(1.5, 5.0, 0.03)])
    poses = [PoseSample(t, [t, 0.0, 0.0]) for t in tp]
    s = synchronise(_frames(np.arange(3.0, 4.0, 0.02)), poses, max_gap=0.1)
    assert s.gaps == [] and s.valid.all()
    s = synchronise(_frames(np.arange(3.0, 4.0, 0.02)), poses, max_gap=0.1, clock_offset=2.2)
    assert len(s.gaps) == 1 and s.gaps[0].t_end == pytest.approx(3.7)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [({"clock_offset": float("nan")}, "clock_offset"), ({"max_gap": 0.0}, "max_gap"),
     ({"max_gap": "x"}, "max_gap")],
)
def test_bad_parameters_are_named(kwargs, match):
    poses = [PoseSample(t, [0.0, 0.0, 0.0]) for t in (0.0, 1.0)]
    with pytest.raises(ValidationError, match=match):
        synchronise(_frames(np.array([0.5])), poses, **kwargs)


def test_bad_streams_are_rejected():
    poses = [PoseSample(t, [0.0, 0.0, 0.0]) for t in (0.0, 1.0)]
    with pytest.raises(ValidationError, match="at least 2 pose"):
        synchronise(_frames(np.array([0.5])), poses[:1])
    with pytest.raises(ValidationError, match="increase"):
        synchronise(_frames(np.array([0.5, 0.5])), poses)
    with pytest.raises(ValidationError, match="no taxel"):
        synchronise([], poses)


def test_estimate_clock_offset_recovers_a_known_offset(rng):
    # One press: the finger goes down 4 mm below the surface and back; counts grow with indentation.
    t = np.arange(0.0, 3.0, 0.02)
    z = 0.03 + 0.002 - 0.006 * np.clip(1 - np.abs(t - 1.5) / 0.8, 0, 1)
    depth_mm = np.clip(0.03 - z, 0, None) * 1e3
    counts = np.zeros((len(t), 4, 4), np.uint8)
    counts[:, 1:3, 1:3] = np.clip(np.rint(15 * depth_mm**1.5), 0, 255).astype(np.uint8)[:, None, None]
    true_offset = 0.137
    tp = np.arange(-0.5, 3.5, 1 / 30)
    zp = 0.03 + 0.002 - 0.006 * np.clip(1 - np.abs(tp - 1.5) / 0.8, 0, 1)
    poses = [PoseSample(ti - true_offset, [0.0, 0.0, zi + 2e-5 * rng.standard_normal()])
             for ti, zi in zip(tp, zp, strict=True)]
    est = estimate_clock_offset(_frames(t, counts), poses, max_offset=0.5)
    assert est == pytest.approx(true_offset, abs=0.01)


def test_estimate_clock_offset_needs_contact():
    poses = [PoseSample(t, [0.0, 0.0, t]) for t in np.linspace(0.0, 1.0, 10)]
    with pytest.raises(ValidationError, match="contact"):
        estimate_clock_offset(_frames(np.linspace(0.0, 1.0, 20)), poses)


def test_ranks_match_scipy_with_ties():
    from scipy.stats import rankdata

    from palpate.core.perception.sync import _ranks

    rng = np.random.default_rng(7)
    for n in (1, 2, 17, 300):
        x = rng.integers(0, 6, n).astype(float)  # many ties
        np.testing.assert_array_equal(_ranks(x), rankdata(x))
