"""The Dynamixel finger end to end against MuJoCo physics.

dynamixel-sdk (DynamixelFinger) -> pty -> ServoBusEmulator -> FingerPhysics (MuJoCo finger, local-Hertz contact)
-> joint torques back into the servo currents, and taxel frames beside the fingertip poses, through the core
signal path. The presses run in real time on the emulator's clock (a few seconds in all).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from palpate.core.errors import DeviceError, ValidationError
from palpate.core.perception.fit import fit_power_law, fit_press
from palpate.core.perception.memory import HapticMemory
from palpate.core.perception.pipeline import PipelineConfig, presses_from_recording
from palpate.core.session.sources import PressTarget
from palpate.core.world.scene import Material, ObjectSpec, Scene
from palpate.hardware.clock import StepClock
from palpate.hardware.dynamixel import control_table as ct
from palpate.hardware.dynamixel.driver import DynamixelFinger, LostServo
from palpate.hardware.dynamixel.emulator import ServoBusEmulator
from palpate.hardware.dynamixel.finger import (
    forward_kinematics,
    inverse_kinematics,
    jacobian,
    joints_to_ticks,
    load_finger,
    tip_force_from_torques,
)
from palpate.hardware.dynamixel.physics_bus import physics_bus
from palpate.hardware.dynamixel.press import FingerActuator
from palpate.sim.analytic import law_sensel_pressure
from palpate.sim.contact.stack import object_law
from palpate.sim.finger_physics import FingerPhysics
from palpate.sim.fingertip import sensel_bounds
from palpate.sim.hertz import sneddon_sphere_force_at_depth
from palpate.sim.reference.bonded_layer import dimitriadis_factor
from palpate.sim.source import SimSource

BAUD = 1_000_000
X = 0.07  # press point, m (in the finger's plane y = 0)
TOP = 0.03  # block top, m
R = 0.008  # default fingertip radius, m
# Pa; 2 MPa would saturate the inner sensels (255 counts) from about 1 N on, flattening c_P: not a 3/2 profile
MATERIALS = {"soft": 2e4, "medium": 1e5, "firm": 5e5}
# Poses arrive at ~200 Hz, but on a loaded machine a thread can stall for 0.1 s (the default pose gap limit);
# the press is slow (6 mm/s), so interpolating across such a stall is harmless.
CONFIG = PipelineConfig(max_gap=0.3)
TARGET = dict(depth=0.004, force=8.0, speed=0.006)  # 4 mm or 8 N, whichever first, at 6 mm/s


@pytest.fixture
def finger(repo_dir):
    # start 3 mm above the surface instead of 10 mm: the same press, in less wall time
    return dataclasses.replace(load_finger(repo_dir / "models" / "fingers" / "planar2.toml"), approach_height=0.003)


def _scene(young: float, top: float = TOP, name: str = "block") -> Scene:
    return Scene((ObjectSpec("block", "box", (0.06, 0.04, top), (X, 0.0), Material(name, young)),))


def _down(q1: float) -> np.ndarray:
    """Joint angles of planar2 with the last link pointing straight down (pitch pi/2)."""
    return np.array([q1, math.pi / 2 - q1])


def _hinge_torque(finger, q, point_x: float, force_z: float) -> np.ndarray:
    """Closed form: a vertical force F on a point at x, applied through hinges about +y, gives each joint the
    torque -F (x - x_axis) (positive angles curl the finger down)."""
    axes_x = finger.base[0] + np.concatenate([[0.0], np.cumsum(finger.lengths * np.cos(np.cumsum(q)))[:-1]])
    return -force_z * (point_x - axes_x)


# ---- the physics alone (no wire) -----------------------------------------------------------------------------

def test_mujoco_finger_follows_the_kinematics_and_its_contact_is_hertz(finger):
    q = _down(0.3)
    tip, pitch = forward_kinematics(finger, q)
    assert pitch == pytest.approx(math.pi / 2)
    depth = 0.001
    top = tip[2] + depth  # the pad centre is the sphere's lowest point when the finger points down
    physics = FingerPhysics(finger, Scene((ObjectSpec("b", "box", (0.06, 0.04, top), (tip[0], 0.0),
                                                      Material("m", 2e5)),)))
    c = physics.contact(q, sensels=True)
    np.testing.assert_allclose(c.tip, tip, atol=1e-12)
    np.testing.assert_allclose(c.centre, tip + [0.0, 0.0, R], atol=1e-12)
    np.testing.assert_allclose(c.quaternion, [1.0, 0.0, 0.0, 0.0], atol=1e-12)  # pad frame = world frame
    assert c.indentation == pytest.approx(depth, abs=1e-12)
    # the rigid fidelity's contact model: the column's contact law (here one material, top high above the table)
    block = physics.scene.objects[0]
    law = object_law(block, tip[0], 0.0, top, R, 0.006, lateral=False)
    assert c.force[2] == pytest.approx(float(law.force_at(depth)), rel=0.005)
    # that is Sneddon's sphere stiffened by the table as the bonded-layer series says (independent, published)
    series = dimitriadis_factor(np.sqrt(R * depth) / top, 0.3)
    assert c.force[2] == pytest.approx(float(sneddon_sphere_force_at_depth(2e5 / 0.91, R, depth)) * series, rel=0.02)
    small = np.array([2e-4, 5e-4])
    f_small = np.array([FingerPhysics(finger, Scene((ObjectSpec("b", "box", (0.06, 0.04, tip[2] + d), (tip[0], 0.0),
                                                                Material("m", 2e5)),))).contact(q).force[2]
                        for d in small])
    assert np.log(f_small[1] / f_small[0]) / np.log(small[1] / small[0]) == pytest.approx(1.5, abs=0.03)
    ref = law_sensel_pressure(law, np.array([depth]), sensel_bounds(physics.scene.fingertip))[0]
    np.testing.assert_allclose(c.sensel_pressure, ref, rtol=0, atol=0.03 * ref.max())
    # J^T F through MuJoCo's Jacobian equals the hinge closed form; the servo of a mirrored joint sees it negated
    np.testing.assert_allclose(c.joint_torque, _hinge_torque(finger, q, tip[0], c.force[2]), rtol=1e-9, atol=1e-12)
    servo = finger.directions * (q - finger.offsets)
    np.testing.assert_allclose(physics.load(servo), finger.directions * c.joint_torque, rtol=1e-12)
    # out of contact: nothing
    up = physics.contact(inverse_kinematics(finger, tip[0], top + 0.002), sensels=True)
    assert up.force[2] == 0.0 and up.indentation == 0.0 and not up.sensel_pressure.any()


def test_a_tilted_fingertip_shifts_the_pressure_on_its_pad(finger):
    alpha = 0.1
    q = _down(0.3) + [0.0, alpha]  # pitch pi/2 + alpha
    physics = FingerPhysics(finger, _scene(2e5, top=1.0))  # placeholder top, replaced below
    centre = physics.contact(q).centre
    physics = FingerPhysics(finger, Scene((ObjectSpec("b", "box", (0.06, 0.04, centre[2] - R + 0.0015),
                                                      (centre[0], 0.0), Material("m", 2e5)),)))
    c = physics.contact(q, sensels=True)
    assert c.indentation == pytest.approx(0.0015, abs=1e-12)  # the lowest point of the sphere, whatever the pitch
    u = physics.scene.fingertip.sensel_centres()[..., 0]
    centroid = float((c.sensel_pressure * u).sum() / c.sensel_pressure.sum())
    # the contact point sits at R sin(alpha) along the pad's x axis
    assert centroid == pytest.approx(R * math.sin(alpha), rel=0.15)
    # the force acts under the sphere's centre, not at the pad centre: both joints now carry a torque
    np.testing.assert_allclose(c.joint_torque, _hinge_torque(finger, q, c.centre[0], c.force[2]), rtol=1e-9)
    assert abs(c.joint_torque[1]) > 0.05 * abs(c.joint_torque[0])


def test_bad_setups_are_clear_errors(finger):
    with pytest.raises(ValidationError, match="mesh"):
        FingerPhysics(finger, Scene((ObjectSpec("ball", "mesh", (1.0, 1.0, 1.0), (X, 0.0), Material("m", 1e5),
                                                mesh_path="ball.stl"),)))
    with pytest.raises(ValidationError, match="no object"):
        FingerPhysics(finger, Scene(()))
    physics = FingerPhysics(finger, _scene(2e5))
    with pytest.raises(ValidationError, match="2 finite joint angles"):
        physics.contact([0.1, float("nan")])
    with pytest.raises(ValidationError, match="observer"):
        physics.trace()
    with pytest.raises(ValidationError, match="pose_noise"):
        FingerActuator(None, TOP, pose_noise=-1.0)
    with pytest.raises(ValidationError, match="inside an object"):
        physics_bus(finger, _scene(2e5), inverse_kinematics(finger, X, TOP - 0.002))
    with pytest.raises(ValidationError, match="outside its limits"):
        physics_bus(finger, _scene(2e5), finger.upper + 0.1)


# ---- through the wire ----------------------------------------------------------------------------------------

def _bus(finger, young, name="block"):
    return physics_bus(finger, _scene(young, name=name), inverse_kinematics(finger, X, TOP + 0.003), clock=StepClock())


def test_presses_through_the_wire_fit_the_three_halves_law_and_match_a_memory_trained_in_simulation(finger):
    n1, stopped, peaks, wire_params = {}, {}, {}, []
    for k, (name, young) in enumerate(MATERIALS.items()):
        emu, physics = _bus(finger, young, name)
        with emu, DynamixelFinger(emu.port, BAUD, finger, clock=emu.clock) as drv:
            act = FingerActuator(drv, TOP, streams=physics.actuator_streams(seed=k), pose_noise=5e-5, seed=k)
            rec = act.press(PressTarget(X, 0.0, **TARGET))
        stopped[name] = act.last.stopped_by
        peaks[name] = (rec.truth.force.max(), rec.truth.indentation.max(), act.last.force)
        assert max(int(f.counts.max()) for f in rec.frames) < 255  # no saturated sensel
        assert rec.truth.material == name
        t_frames = np.array([f.t for f in rec.frames])
        assert rec.poses[0].t <= t_frames[0] and t_frames[-1] <= rec.poses[-1].t
        # the core stack sees one normal press
        seg = presses_from_recording(rec, CONFIG)
        assert len(seg.presses) == 1, seg.rejected
        press = seg.presses[0]
        assert press.n_samples >= 7
        c_d = np.asarray(press.c_D) * 1e3  # mm
        c_p = np.asarray(press.c_P)
        fit = fit_power_law(c_d, c_p)
        r2 = 1.0 - fit.phi / np.sum((c_p - c_p.mean()) ** 2)
        assert r2 > 0.95, (name, r2)
        n1[name] = fit.k1
        wire_params.append(fit_press(press).params)
    assert stopped == {"soft": "depth", "medium": "depth", "firm": "force"}
    assert 3 * n1["soft"] < n1["medium"] and 3 * n1["medium"] < n1["firm"], n1
    # the soft and medium blocks reached the depth, the firm one stopped near the force read from the currents
    for name in ("soft", "medium"):
        assert peaks[name][1] == pytest.approx(0.004, abs=2e-4)
    force, depth, estimated = peaks["firm"]
    assert depth < 0.003
    assert estimated >= 8.0 and force == pytest.approx(estimated, abs=0.5)
    # what the simulation taught is what the wire shows: a haptic memory trained on simulated presses
    # (rigid fidelity, human-like, same materials and target) recognises each press made through the wire
    params, labels = [], []
    for k, (name, young) in enumerate(MATERIALS.items()):
        source = SimSource(_scene(young, name=name), fidelity="rigid", seed=k, variability="human")
        for _ in range(5):
            rec = source.press(PressTarget(X, 0.0, **TARGET))
            params.append(fit_press(presses_from_recording(rec).presses[0]).params)
            labels.append(name)
    memory = HapticMemory().fit(np.array(params), labels)
    assert memory.predict(np.array(wire_params)) == list(MATERIALS)


def test_currents_read_back_are_the_physics_force_within_the_current_resolution(finger):
    emu, physics = _bus(finger, 2e5)
    unit = finger.model.current_unit
    kt = finger.model.torque_constant
    with emu, DynamixelFinger(emu.port, BAUD, finger, clock=emu.clock) as drv:
        drv.enable_torque()
        for depth in (0.0005, 0.0015, 0.003):
            drv.move_to(inverse_kinematics(finger, X, TOP - depth), tolerance=1e-3, timeout=5.0)
            state = drv.read_state()
            c = physics.contact(state.position)
            assert c.indentation == pytest.approx(depth, abs=2e-4)  # ~1 tick of either servo
            # the servos hold the load: current = -(J^T F) / kt, rounded to the register's unit
            np.testing.assert_allclose(state.current, -c.joint_torque / kt, rtol=0, atol=0.5 * unit + 1e-12)
            assert np.abs(state.current).max() > 4 * unit  # a real load, not a zero matched to zero
            # the driver's force estimate (the kinematic tip's Jacobian) is the physics force to that resolution
            # plus the lever of the contact point against the pad centre (R cos(pitch))
            jt_inv = np.linalg.pinv(jacobian(finger, state.position).T)  # F = -pinv(J^T) tau
            bound = np.abs(jt_inv[1]).sum() * 0.5 * unit * kt
            est = tip_force_from_torques(finger, state.position, drv.joint_torques(state))[1]
            pitch = forward_kinematics(finger, state.position)[1]
            lever = R * abs(math.cos(pitch)) / 0.04  # relative, against a lever arm of at least 4 cm
            assert est == pytest.approx(c.force[2], abs=bound + lever * c.force[2] + 1e-9)
        drv.move_to(inverse_kinematics(finger, X, TOP + 0.003), tolerance=1e-3, timeout=5.0)
        assert not drv.read_state().current.any()  # off the surface: no load


def test_a_servo_going_silent_mid_press_stops_cleanly_and_keeps_the_streams(finger):
    emu, physics = _bus(finger, 2e5)
    lost = finger.ids[-1]
    seen = []

    def cut_cable(state, pose):
        seen.append(pose)
        if pose.position[2] < TOP - 0.0015:  # 1.5 mm into the block
            emu.silence(lost)

    with emu, DynamixelFinger(emu.port, BAUD, finger, clock=emu.clock) as drv:
        act = FingerActuator(drv, TOP, on_state=cut_cable, streams=physics.actuator_streams())
        with pytest.raises(LostServo, match=f"servo {lost} .*stopped answering") as info:
            act.press(PressTarget(X, 0.0, depth=0.004, speed=0.01))
        assert isinstance(info.value, DeviceError)
        for sid in finger.ids[:-1]:
            assert emu.register(sid, ct.TORQUE_ENABLE) == 0
    part = act.partial
    assert part is not None and part.meta["incomplete"]
    assert len(part.poses) == len(seen)  # every state received before the loss is kept
    assert part.frames and part.frames[-1].t <= part.poses[-1].t
    # the taxels kept show the press that was under way, as deep as the poses say it went
    assert sum(int(f.counts.sum()) for f in part.frames[-3:]) > 0
    assert part.truth.indentation.max() == pytest.approx(TOP - min(p.position[2] for p in part.poses), abs=3e-4)


def test_the_emulator_observer_sees_every_substep_in_time_order(finger):
    times, angles = [], []
    clock = [0.0]
    q0 = inverse_kinematics(finger, X, TOP + 0.003)
    emu = ServoBusEmulator(finger.ids, finger.model.number, BAUD, None, joints_to_ticks(finger, q0),
                           clock=lambda: clock[0], observer=lambda t, a: (times.append(t), angles.append(a)))
    for sid in finger.ids:
        emu.set_register(sid, ct.TORQUE_ENABLE, 1)
    goal = joints_to_ticks(finger, inverse_kinematics(finger, X, TOP - 0.003))
    for sid, g in zip(finger.ids, goal, strict=True):
        emu.set_register(sid, ct.GOAL_POSITION, int(g))
    clock[0] = 0.05
    final = emu.positions()
    assert np.all(np.diff(times) > 0) and times[-1] == pytest.approx(0.05)
    assert len(times) == math.ceil(0.05 / 0.002)  # one call per 2 ms substep
    np.testing.assert_allclose(angles[-1], (final - ct.CENTER_TICK) * 2 * math.pi / ct.TICKS_PER_REV)


def test_recorded_history_is_bounded_and_keeps_the_newest_states(finger):
    physics = FingerPhysics(finger, _scene(2e5), max_states=10)
    q = inverse_kinematics(finger, X, TOP + 0.002)
    servo = finger.directions * (q - finger.offsets)
    for k in range(25):
        physics.observe(0.01 * k, servo)
    physics.observe(0.2, servo)  # a repeated or earlier stamp is ignored
    trace = physics.trace()
    assert 5 <= len(trace.t) <= 10
    assert trace.t[-1] == pytest.approx(0.24)
    assert np.all(np.diff(trace.t) > 0)
    assert not trace.force.any()  # 2 mm above the block
