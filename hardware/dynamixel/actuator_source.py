"""The Dynamixel finger as the exploration actuator of ``palpate run`` (entry point ``dynamixel`` in
``palpate.actuators``; the request and the factory signature are in :mod:`palpate.core.actuators`).

Before anything is opened, every cell the policy may press is planned as a press (:func:`plan_press`: on the
finger's plane, inside its reach and joint limits along the whole vertical path, not deeper than its
``press.max_depth``), so a grid the finger cannot press is refused before any servo moves.

With ``emulate = true`` the finger presses through dynamixel-sdk -> pty -> :class:`ServoBusEmulator` -> MuJoCo
physics of the scenario's object (:func:`palpate.sim.finger_physics.physics_bus`), which also gives the taxel
frames of the simulated pad. A real bus (``port``) is refused for now: the finger has no tactile pad of its
own and palpate has no live taxel reader (Tekscan's live API is Windows-only; see
:mod:`palpate.hardware.tekscan` for the bridge contract), so its presses could not be perceived.
"""

from __future__ import annotations

import contextlib
import dataclasses

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.sources import PressTarget
from palpate.core.streams import PressRecording
from palpate.hardware.dynamixel.finger import FingerDescription, inverse_kinematics, load_finger
from palpate.hardware.dynamixel.press import PLANE_TOLERANCE, FingerActuator, plan_press

# At most this many offending cells are named in an error (a whole row off the plane would be a wall of text).
MAX_NAMED = 3


class FingerSession:
    """A :class:`FingerActuator` together with the bus (and emulator) it owns; ``close()`` releases them."""

    def __init__(self, actuator: FingerActuator, stack: contextlib.ExitStack):
        self.actuator = actuator
        self._stack = stack

    def press(self, target: PressTarget) -> PressRecording:
        """One press-and-release at ``target`` (m, N, m/s); see :meth:`FingerActuator.press`."""
        return self.actuator.press(target)

    def close(self) -> None:
        """Torque off, port closed, emulator stopped (idempotent)."""
        self._stack.close()


def finger_for(request) -> FingerDescription:
    """The request's finger description, with its approach height overridden when the scenario sets one."""
    spec = request.spec
    if spec.finger is None:
        raise ValidationError("actuator.finger: missing (a finger description, models/fingers/*.toml)")
    finger = load_finger(spec.finger)
    if spec.approach_height is not None:
        finger = dataclasses.replace(finger, approach_height=float(spec.approach_height))
    return finger


def check_reach(finger: FingerDescription, request) -> None:
    """Plan a press at every cell of ``request.cells``; ValidationError naming the object, the cells and why.

    A planar finger moves in the plane y = base y: every cell centre must lie within PLANE_TOLERANCE of it.
    """
    obj = request.obj
    surface_z = obj.height
    y0 = float(finger.base[1])
    where = f"actuator dynamixel, object {obj.name!r}"
    src = finger.source or finger.name
    targets = np.asarray(request.targets, dtype=float).reshape(-1, 2)
    off = np.nonzero(np.abs(targets[:, 1] - y0) > PLANE_TOLERANCE)[0]
    if len(off):
        named = ", ".join(f"[{request.cells[i][0] + 1}, {request.cells[i][1] + 1}] at y = {targets[i, 1] * 1e3:.1f} mm"
                          for i in off[:MAX_NAMED])
        more = f" and {len(off) - MAX_NAMED} more" if len(off) > MAX_NAMED else ""
        half = request.cell_size * 1e3 / 2
        raise ValidationError(
            f"{where}: {len(off)} of the {len(targets)} cells the exploration may press lie off the plane of finger "
            f"{finger.name!r} ({src}), y = {y0 * 1e3:.1f} mm: cell(s) {named}{more}. A planar finger presses one row: "
            f"give the object grid_cells = [N, 1] and grid_origin_mm = [x0, {y0 * 1e3 - half:.1f}]")
    for (ix, iy), (x, y) in zip(request.cells, targets, strict=True):
        try:
            plan_press(finger, PressTarget(float(x), float(y), depth=request.depth, force=request.max_force,
                                           speed=request.speed), surface_z)
        except ValidationError as exc:
            raise ValidationError(f"{where}: cell [{ix + 1}, {iy + 1}] at x = {x * 1e3:.1f} mm cannot be pressed "
                                  f"{request.depth * 1e3:.1f} mm deep from a top at z = {surface_z * 1e3:.1f} mm: "
                                  f"{exc}") from None


def dynamixel_actuator(request, *, check_only: bool = False):
    """Factory of kind ``dynamixel`` (see :mod:`palpate.core.actuators` for the signature).

    Checks the finger file and the reach of every cell; with ``check_only`` stops there. Otherwise starts the
    physics-backed emulator over ``request.scene`` (``emulate``), opens the bus and returns a
    :class:`FingerSession` whose presses carry the pad's taxel frames, the fingertip poses (plus
    ``pose_noise``) and the physics' ground truth.
    """
    spec = request.spec
    finger = finger_for(request)
    check_reach(finger, request)
    if not spec.emulate:
        raise ValidationError(
            f"actuator.port = {spec.port!r}: a real Dynamixel finger has no tactile pad of its own and palpate has "
            "no live taxel reader yet (Tekscan's live API is Windows-only; see palpate.hardware.tekscan for the "
            "bridge contract), so its presses could not be perceived. Use emulate = true, or record the session "
            "(palpate record dynamixel, the pad's bridge) and run palpate replay")
    if request.obj.shape not in ("box", "cylinder"):
        raise ValidationError(f"actuator dynamixel, object {request.obj.name!r}: the emulated finger presses boxes "
                              f"and cylinders (a flat top), not a {request.obj.shape}")
    if check_only:
        return None
    from palpate.hardware.dynamixel.driver import DynamixelFinger
    from palpate.sim.finger_physics import physics_bus

    surface_z = request.obj.height
    # power on above the first cell the exploration may press: the first move is then short
    start = inverse_kinematics(finger, float(request.targets[0, 0]), surface_z + finger.approach_height)
    stack = contextlib.ExitStack()
    try:
        emulator, physics = physics_bus(finger, request.scene, start, baud=spec.baud)
        stack.enter_context(emulator)
        driver = stack.enter_context(DynamixelFinger(emulator.port, spec.baud, finger))
        actuator = FingerActuator(driver, surface_z, streams=physics.actuator_streams(request.seed),
                                  pose_noise=spec.pose_noise, seed=request.seed)
    except BaseException:
        stack.close()
        raise
    return FingerSession(actuator, stack)
