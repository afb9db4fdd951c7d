"""Finger description files, kinematics (FK/IK round trip, Jacobian) and statics of the planar finger."""

from __future__ import annotations

import math

import numpy as np
import pytest

from palpate.core.errors import ValidationError
from palpate.hardware.dynamixel.finger import (
    check_joint_limits,
    finger_from_dict,
    forward_kinematics,
    inverse_kinematics,
    jacobian,
    joints_to_ticks,
    load_finger,
    surface_load_model,
    ticks_to_joints,
    tip_force_from_torques,
)


@pytest.fixture(params=["planar2", "planar3"])
def finger(request, repo_dir):
    return load_finger(repo_dir / "models" / "fingers" / f"{request.param}.toml")


def _doc(**over):
    doc = {
        "name": "f",
        "base": [0.0, 0.0, 0.1],
        "servo": {"model": "XM430-W350", "current_limit": 800},
        "press": {"current_threshold": 400},
        "joints": [
            {"name": "a", "servo_id": 1, "link_length": 0.05, "limits": [-1.0, 1.0]},
            {"name": "b", "servo_id": 2, "link_length": 0.04, "limits": [0.0, 2.0], "direction": -1},
        ],
    }
    doc.update(over)
    return doc


def test_shipped_fingers_load(finger):
    assert finger.ids == list(range(1, len(finger.joints) + 1))
    assert finger.model.number == 1020
    assert 0 < finger.press_current < finger.current_limit


def test_fk_of_a_straight_finger_is_the_sum_of_the_links(finger):
    q = np.zeros(len(finger.joints))
    tip, pitch = forward_kinematics(finger, q)
    np.testing.assert_allclose(tip, finger.base + [finger.lengths.sum(), 0, 0])
    assert pitch == 0.0
    # a quarter turn of the first joint points the whole finger down
    q[0] = math.pi / 2
    tip, _ = forward_kinematics(finger, q)
    np.testing.assert_allclose(tip, finger.base - [0, 0, finger.lengths.sum()], atol=1e-15)


def test_ik_fk_round_trip(finger, rng):
    lo, hi = finger.lower, finger.upper
    checked = 0
    for _ in range(200):
        q = lo + rng.random(len(lo)) * (hi - lo)
        tip, pitch = forward_kinematics(finger, q)
        q_ik = inverse_kinematics(finger, tip[0], tip[2], pitch=pitch)
        tip_ik, pitch_ik = forward_kinematics(finger, q_ik)
        np.testing.assert_allclose(tip_ik, tip, atol=1e-9)
        check_joint_limits(finger, q_ik)
        if len(q) == 3:
            assert pitch_ik == pytest.approx(pitch, abs=1e-6)  # the sampled pitch is feasible, so it is kept
        checked += 1
    assert checked == 200


def test_three_link_ik_keeps_the_pitch_closest_to_the_preferred_one(repo_dir):
    finger = load_finger(repo_dir / "models" / "fingers" / "planar3.toml")
    x, z = 0.07, 0.03
    q = inverse_kinematics(finger, x, z, pitch=0.3)  # 0.3 rad needs q3 < 0, outside [0, 1.6]
    tip, pitch = forward_kinematics(finger, q)
    np.testing.assert_allclose(tip[[0, 2]], [x, z], atol=1e-9)
    assert q[2] == pytest.approx(0.0, abs=1e-6)  # pinned at the limit it hit
    # no feasible pitch nearer 0.3: a small step towards it leaves the limits
    from palpate.hardware.dynamixel.finger import _three_link_candidates

    u, w = x - finger.base[0], finger.base[2] - z
    nearer = _three_link_candidates(finger, u, w, np.array([pitch - 1e-4]))
    assert not np.any(np.all((nearer >= finger.lower) & (nearer <= finger.upper), axis=-1))


def test_ik_out_of_reach_is_refused(finger):
    with pytest.raises(ValidationError, match="out of reach"):
        inverse_kinematics(finger, finger.base[0] + finger.lengths.sum() + 0.01, finger.base[2])


def test_jacobian_matches_finite_differences(finger, rng):
    q = finger.lower + rng.random(len(finger.joints)) * (finger.upper - finger.lower)
    h = 1e-7
    num = np.column_stack([
        (forward_kinematics(finger, q + h * e)[0][[0, 2]] - forward_kinematics(finger, q - h * e)[0][[0, 2]]) / (2 * h)
        for e in np.eye(len(q))
    ])
    np.testing.assert_allclose(jacobian(finger, q), num, atol=1e-7)


def test_force_from_torques_inverts_the_surface_load(finger):
    surface_z, k = 0.03, 2.0 / 0.003**1.5
    q = inverse_kinematics(finger, 0.07, surface_z - 0.002)
    servo_angles = finger.directions * (q - finger.offsets)
    external = surface_load_model(finger, surface_z, k)(servo_angles)  # servo frame
    motor_joint = -finger.directions * external  # the motors hold the load
    force = tip_force_from_torques(finger, q, motor_joint)
    np.testing.assert_allclose(force, [0.0, k * 0.002**1.5], atol=1e-9)


def test_ticks_round_trip_and_direction(finger):
    q = 0.5 * (finger.lower + finger.upper)
    ticks = joints_to_ticks(finger, q)
    np.testing.assert_allclose(ticks_to_joints(finger, ticks), q, atol=math.pi / 4096)
    step = joints_to_ticks(finger, q + 0.1) - ticks
    assert np.all(np.sign(step) == finger.directions)


def test_joint_limits_name_the_joint(finger):
    q = 0.5 * (finger.lower + finger.upper)
    q[-1] = finger.upper[-1] + 0.01
    with pytest.raises(ValidationError, match=finger.joints[-1].name):
        check_joint_limits(finger, q)
    q[-1] = np.nan
    with pytest.raises(ValidationError, match="nan"):
        check_joint_limits(finger, q)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"servo": {"model": "XM430-W350", "current_limit": 5000}}, "current_limit 5000"),
        ({"servo": {"model": "AX-12"}}, "servo.model"),
        ({"press": {"current_threshold": 900}}, "current_threshold"),
        ({"base": [0, 0]}, "'base'"),
        ({"joints": [{"servo_id": 1, "link_length": 0.05, "limits": [0, 1]}]}, "2 or 3 joints"),
        ({"colour": "red"}, "unknown key"),
    ],
)
def test_bad_descriptions_are_refused_with_the_key(change, message):
    with pytest.raises(ValidationError, match=message):
        finger_from_dict(_doc(**change), "bad.toml")


@pytest.mark.parametrize(
    ("joint_change", "message"),
    [
        ({"link_length": 50}, r"joints\[1\].link_length"),
        ({"limits": [1.0, 0.5]}, "lower < upper"),
        ({"limits": [0.0, 4.0]}, "outside the servo"),
        ({"direction": 2}, "direction"),
        ({"servo_id": 1}, "unique"),
        ({"servo_id": 300}, "servo_id"),
    ],
)
def test_bad_joints_are_refused_with_the_key(joint_change, message):
    doc = _doc()
    doc["joints"][1].update(joint_change)
    with pytest.raises(ValidationError, match=message):
        finger_from_dict(doc, "bad.toml")


def test_unreadable_and_invalid_files_name_the_file(tmp_path):
    with pytest.raises(ValidationError, match="missing.toml"):
        load_finger(tmp_path / "missing.toml")
    bad = tmp_path / "broken.toml"
    bad.write_text("name = \n")
    with pytest.raises(ValidationError, match="broken.toml"):
        load_finger(bad)
