"""A servo bus whose load and taxels come from MuJoCo physics: the emulators behind ``--emulate`` and the tests.

dynamixel-sdk -> pty -> :class:`~palpate.hardware.dynamixel.emulator.ServoBusEmulator` ->
:class:`palpate.sim.finger_physics.FingerPhysics`, and beside it a tactile array on a second pty
(:class:`~palpate.hardware.tactile.emulator.TactileArrayEmulator`) whose counts are that physics' pad:
:func:`physics_taxels`. This module needs palpate's simulation (the ``sim`` extra); the rest of the Dynamixel
package does not.
"""

from __future__ import annotations

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.world.scene import Scene
from palpate.hardware.dynamixel import control_table as ct
from palpate.hardware.dynamixel.emulator import ServoBusEmulator
from palpate.hardware.dynamixel.finger import FingerDescription, check_joint_limits, joints_to_ticks
from palpate.sim.finger_physics import FingerPhysics
from palpate.sim.sensors import taxel_counts


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


# A taxel frame is the pad's pressure interpolated between the servo states recorded within this window before it, s
# (the emulator records one every 2 ms while the servos move; at rest the last state stands).
_TRACE_WINDOW = 0.006


def physics_taxels(physics: FingerPhysics, servos: ServoBusEmulator, seed: int = 0):
    """``(source, ready)`` for a :class:`~palpate.hardware.tactile.emulator.TactileArrayEmulator` whose pad is the
    finger's (``scene.taxels`` model: gain, noise, threshold): ``source(t)`` gives the counts at clock time t (give
    the array ``epoch=0``), ``ready(t)`` whether the servos' motion up to t is known.

    On a virtual clock a frame waits until the servos have been read past its time (their dynamics are integrated
    only then, so the array never changes how they move); on the wall clock a bus left idle is brought up to date.
    """
    rng = np.random.default_rng(seed)
    spec = physics.scene.taxels

    def ready(t: float) -> bool:
        if servos.integrated_until >= t:
            return True
        if servos.clock.virtual:
            return False
        servos.positions()  # integrates up to now
        return servos.integrated_until >= t

    def source(t: float) -> np.ndarray:
        try:
            trace = physics.trace(t - _TRACE_WINDOW, t + 1e-9)
        except ValidationError:  # the servos rested: one state covers the window
            ticks = servos.last_positions()
            angles = (ticks - ct.CENTER_TICK) * (2 * np.pi / ct.TICKS_PER_REV)
            pressure = physics.contact(physics.joints_from_servo(angles), sensels=True).sensel_pressure
            return taxel_counts(pressure, spec, rng)
        flat = trace.sensel_pressure.reshape(len(trace.t), -1)
        pressure = np.array([np.interp(t, trace.t, col) for col in flat.T]).reshape(trace.sensel_pressure.shape[1:])
        return taxel_counts(pressure, spec, rng)

    return source, ready
