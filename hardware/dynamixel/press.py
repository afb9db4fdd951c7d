"""Press-and-release with a Dynamixel finger: the finger as an actuator the exploration loop can drive.

A press is planned whole before anything moves (every waypoint through inverse kinematics and the joint
limits), then: approach to ``approach_height`` above the target, move the tip down along -z at the target's
speed until the depth is reached, the estimated normal force reaches the target force, or any joint current
exceeds the finger's press threshold; hold; release back to the approach height. Any failure switches torque
off (see :meth:`DynamixelFinger.safety`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from palpate.core.errors import DeviceError, ValidationError
from palpate.core.perception.force_channel import PERCEPTION
from palpate.core.perception.streams import PoseSample, PressRecording
from palpate.core.session.sources import PressTarget
from palpate.hardware.dynamixel.current_force import current_force_frames
from palpate.hardware.dynamixel.finger import (
    fingertip_pose,
    forward_kinematics,
    inverse_kinematics,
    tip_force_from_torques,
)

# How far the target may lie off the finger's plane (m): a planar finger cannot reach sideways.
PLANE_TOLERANCE = 1e-3
# A press to a depth ends when the measured tip is this close above the bottom (m): about one encoder tick
# at the end of a 7 cm finger.
DEPTH_TOLERANCE = 1.5e-4
# Longest stretch of motion one control cycle may command, s (see the press loop).
MAX_STEP_TIME = 0.005


@dataclass
class FingerPress:
    """Everything one press produced.

    Attributes:
        recording: fingertip poses (no taxel frames: the finger has no tactile pad of its own) and meta.
        joints: joint states in time order.
        stopped_by: "depth", "force" or "current": what ended the downward motion.
        depth: deepest indentation below the surface reached, m (from the measured joint angles).
        force: estimated normal force at the deepest point, N (from the joint currents).
    """

    recording: PressRecording
    joints: list = field(default_factory=list)
    stopped_by: str = "depth"
    depth: float = 0.0
    force: float = 0.0


def plan_press(finger, target: PressTarget, surface_z: float, n_check: int = 21) -> tuple[np.ndarray, float, float]:
    """Check that a press is feasible; returns (joint angles at the approach point, z_top, z_bottom), m.

    Every point of the vertical path from the approach height to the deepest allowed point is solved by IK and
    checked against the joint limits, so an unreachable press is refused before any byte is written.
    """
    if not np.isfinite(surface_z):
        raise ValidationError(f"surface_z must be finite (m), got {surface_z}")
    if abs(target.y - finger.base[1]) > PLANE_TOLERANCE:
        raise ValidationError(f"finger {finger.name!r} moves in the plane y = {finger.base[1]} m; press target "
                              f"y = {target.y} m is off that plane")
    depth = target.depth if target.depth is not None else finger.max_depth
    if target.depth is not None and target.depth > finger.max_depth:
        raise ValidationError(f"press depth {target.depth} m exceeds the finger's press.max_depth "
                              f"{finger.max_depth} m ({finger.source or finger.name})")
    z_top = surface_z + finger.approach_height
    z_bottom = surface_z - depth
    for z in np.linspace(z_top, z_bottom, n_check):
        inverse_kinematics(finger, target.x, float(z))
    return inverse_kinematics(finger, target.x, z_top), z_top, z_bottom


def press_and_release(driver, target: PressTarget, surface_z: float, *,
                      on_state: Callable | None = None, tolerance: float = 0.01, timeout: float = 10.0) -> FingerPress:
    """Press at ``target`` (x, y m; depth m or force N; speed m/s; hold s) into a surface at ``surface_z`` m.

    ``driver`` is an open :class:`~palpate.hardware.dynamixel.driver.DynamixelFinger`. ``on_state(state, pose)``
    is called for every joint state as it arrives (a recorder writes there, so nothing is lost if the press
    fails). ``tolerance`` (rad) decides when a joint has arrived; ``timeout`` (s) bounds each phase.
    """
    finger = driver.finger
    q_top, z_top, z_bottom = plan_press(finger, target, surface_z)
    states: list = []
    poses: list[PoseSample] = []

    def record(state) -> None:
        pose = fingertip_pose(finger, state.position, state.t)
        states.append(state)
        poses.append(pose)
        if on_state is not None:
            on_state(state, pose)

    def force_of(state) -> float:
        return float(tip_force_from_torques(finger, state.position, driver.joint_torques(state))[1])

    x = target.x
    stopped_by = "depth"
    with driver.safety():
        if not driver._torque_on:
            driver.enable_torque()
        driver.move_to(q_top, tolerance, timeout, on_state=record)
        n_press_start = len(states)
        t0 = t_prev = driver.clock()
        z_cmd = z_top
        while True:
            # the servos follow a goal within milliseconds, so a late cycle must not jump the goal ahead:
            # each step advances at most MAX_STEP_TIME of motion (the press is slower, never faster, than asked)
            now = driver.clock()
            z_cmd = max(z_bottom, z_cmd - target.speed * min(now - t_prev, MAX_STEP_TIME))
            t_prev = now
            q_cmd = inverse_kinematics(finger, x, z_cmd)
            driver.command_joints(q_cmd)
            state = driver.read_state()
            record(state)
            if np.max(np.abs(state.current)) >= finger.press_current:
                stopped_by = "current"
                break
            if target.force is not None and force_of(state) >= target.force:
                stopped_by = "force"
                break
            tip_z = forward_kinematics(finger, state.position)[0][2]
            if z_cmd <= z_bottom and tip_z <= z_bottom + DEPTH_TOLERANCE:
                break
            if state.t - t0 > timeout:
                raise DeviceError(f"press at x={x} m did not reach z={z_bottom} m within {timeout} s")
        # hold where the tip is (not where it was told to go) so a stop on force/current does not push on
        driver.command_joints(np.clip(state.position, finger.lower, finger.upper))
        n_pressed = len(states)
        t_hold = driver.clock()
        while driver.clock() - t_hold < target.hold:
            record(driver.read_state())
        n_held = len(states)
        z_cmd = float(forward_kinematics(finger, states[-1].position)[0][2])
        t1 = t_prev = driver.clock()
        while True:
            now = driver.clock()
            z_cmd = min(z_top, z_cmd + target.speed * min(now - t_prev, MAX_STEP_TIME))
            t_prev = now
            driver.command_joints(inverse_kinematics(finger, x, z_cmd))
            record(driver.read_state())
            if z_cmd >= z_top:
                break
            if driver.clock() - t1 > timeout:
                raise DeviceError(f"release at x={x} m did not reach z={z_top} m within {timeout} s")
        driver.move_to(q_top, tolerance, timeout, on_state=record)
    # the deepest point of the press and hold phases (the servos may settle a little past the stop)
    pressed = states[n_press_start:n_held] or states[n_press_start:n_pressed]
    deepest = min(pressed, key=lambda s: forward_kinematics(finger, s.position)[0][2])
    tip_deepest = forward_kinematics(finger, deepest.position)[0]
    meta = {
        "source": "dynamixel",
        "finger": finger.name,
        "target": {"x": target.x, "y": target.y, "depth": target.depth, "force": target.force,
                   "speed": target.speed, "hold": target.hold, "label": target.label},
        "surface_z": surface_z,
        "stopped_by": stopped_by,
    }
    return FingerPress(PressRecording(frames=[], poses=poses, meta=meta), states, stopped_by,
                       max(0.0, surface_z - float(tip_deepest[2])), force_of(deepest))


class FingerActuator:
    """A Dynamixel finger as a press source for the exploration loop: ``press(target) -> PressRecording``.

    Args:
        driver: an open DynamixelFinger.
        surface_z: height of the surface pressed, m.
        on_state: passed to :func:`press_and_release` (e.g. a recorder).
        streams: where the taxel frames come from: ``streams(t0, t1) -> (frames, truth)`` for the press's
            time span on the driver's clock (a tactile pad's reader, or the simulated finger's
            :meth:`~palpate.sim.finger_physics.FingerPhysics.actuator_streams`); None for poses only.
        force_from_currents: a finger with no pad: the press's c_P is the fingertip force from its joint currents
            (:mod:`palpate.hardware.dynamixel.current_force`); ``streams`` then only gives the truth, if any.
        pose_noise: standard deviation of Polhemus-like noise added to each fingertip position, m per axis.
        seed: seed of the pose noise.

    If a press fails (a lost servo, Ctrl-C), the error propagates after torque is off, and ``partial`` holds
    the streams received until then.
    """

    def __init__(self, driver, surface_z: float, on_state: Callable | None = None, *,
                 streams: Callable | None = None, pose_noise: float = 0.0, seed: int = 0,
                 force_from_currents: bool = False):
        if not (np.isfinite(pose_noise) and pose_noise >= 0):
            raise ValidationError(f"FingerActuator: pose_noise must be >= 0 m, got {pose_noise!r}")
        self.driver = driver
        self.surface_z = float(surface_z)
        self.on_state = on_state
        self.streams = streams
        self.force_from_currents = bool(force_from_currents)
        self.pose_noise = float(pose_noise)
        self._rng = np.random.default_rng(seed)
        self.last: FingerPress | None = None
        self.partial: PressRecording | None = None

    def press(self, target: PressTarget) -> PressRecording:
        """Press and release at ``target``; returns its raw streams (poses, and taxels if ``streams`` is set)."""
        poses: list[PoseSample] = []
        states: list = []

        def record(state, pose) -> None:
            poses.append(pose)
            states.append(state)
            if self.on_state is not None:
                self.on_state(state, pose)

        self.partial = None
        t0 = self.driver.clock()
        try:
            self.last = press_and_release(self.driver, target, self.surface_z, on_state=record)
        except BaseException:
            meta = {"source": "dynamixel", "finger": self.driver.finger.name, "incomplete": True}
            try:
                self.partial = self._recording(poses, t0, meta, states)
            except Exception:  # what was received is kept even if the pad has nothing for that span
                self.partial = PressRecording(frames=[], poses=self._noisy(poses), meta=meta)
            raise
        self.last.recording = self._recording(self.last.recording.poses, t0, self.last.recording.meta,
                                              self.last.joints)
        return self.last.recording

    def _noisy(self, poses: list[PoseSample]) -> list[PoseSample]:
        if self.pose_noise == 0 or not poses:
            return list(poses)
        noise = self.pose_noise * self._rng.standard_normal((len(poses), 3))
        return [PoseSample(p.t, p.position + e, p.quaternion, p.sensor_id) for p, e in zip(poses, noise, strict=True)]

    def _recording(self, poses: list[PoseSample], t0: float, meta: dict, states: list) -> PressRecording:
        frames, truth = [], None
        if self.streams is not None:
            # taxel frames only where there are poses to place them (the sync step rejects the others)
            t0, t1 = (poses[0].t, poses[-1].t) if len(poses) > 1 else (t0, self.driver.clock())
            frames, truth = self.streams(t0, t1)
        if self.force_from_currents:
            frames = current_force_frames(self.driver.finger, states, self.driver.joint_torques, self.surface_z)
            meta = {**meta, "session": {"perception": dict(PERCEPTION)}}
        return PressRecording(frames=list(frames), poses=self._noisy(poses), truth=truth, meta=dict(meta))
