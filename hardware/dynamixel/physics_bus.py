"""A servo bus whose load and taxels come from MuJoCo physics: the emulator behind ``--emulate`` and the tests.

dynamixel-sdk -> pty -> :class:`~palpate.hardware.dynamixel.emulator.ServoBusEmulator` ->
:class:`palpate.sim.finger_physics.FingerPhysics` -> taxel frames, end to end. This module needs palpate's
simulation (the ``sim`` extra); the rest of the Dynamixel package does not.
"""

from __future__ import annotations

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.world.scene import Scene
from palpate.hardware.dynamixel.emulator import ServoBusEmulator
from palpate.hardware.dynamixel.finger import FingerDescription, check_joint_limits, joints_to_ticks
from palpate.sim.finger_physics import FingerPhysics


def physics_bus(finger: FingerDescription, scene: Scene, start: np.ndarray, *, baud: int = 1_000_000,
                clock=None, **physics_options):
    """A servo emulator for ``finger`` whose load and taxels come from the MuJoCo finger over ``scene``.

    Args:
        finger: the finger description; the emulated ids and model are its own.
        scene: objects, fingertip, taxel model.
        start: joint angles at power-on, rad, inside the joint limits and with the tip clear of every object
            (e.g. ``inverse_kinematics(finger, x, top + finger.approach_height)``).
        baud: the bus bit rate.
        clock: the servos' clock (:mod:`palpate.hardware.clock`; default the wall clock); give the driver the same.
        **physics_options: passed to :class:`FingerPhysics`.

    Returns:
        (emulator, physics): the emulator is not started (use it as a context manager); ``emulator.port`` is
        the pty to give DynamixelFinger once it is.

    Raises:
        ValidationError: ``start`` outside the joint limits or with the fingertip inside an object.
    """
    physics = FingerPhysics(finger, scene, **physics_options)
    q0 = check_joint_limits(finger, start)
    c = physics.contact(q0)
    if c.indentation > 0:
        raise ValidationError(f"physics_bus: at the start angles {q0.tolist()} rad the fingertip is "
                              f"{c.indentation * 1e3:.2f} mm inside an object; start above the surface")
    emulator = ServoBusEmulator(finger.ids, finger.model.number, baud, physics.load, joints_to_ticks(finger, q0),
                                clock=clock, observer=physics.observe)
    return emulator, physics
