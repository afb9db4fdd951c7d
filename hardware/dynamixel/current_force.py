"""A finger with no tactile pad: its joint currents give the fingertip force, which stands in for c_P.

The motors hold the fingertip against the surface with torques ``tau = kt * I`` (kt the servo model's torque
constant); statics give the force on the tip, ``F = -pinv(J^T) tau``
(:func:`~palpate.hardware.dynamixel.finger.tip_force_from_torques`). Its normal part, less what the joints carry with
the tip in the air (gravity, friction: the median over the press's states above half the approach height), is the
press's c_P in newtons, carried as the force channel of :mod:`palpate.core.perception.force_channel` (c_P calibrated
in N, kinesthetic law only). One current step (2.69 mA on X-series) is ~5 mN m: ~0.1 N at the tip of a 5 cm finger.
"""

from __future__ import annotations

import numpy as np

from palpate.core.perception.force_channel import force_frames
from palpate.core.perception.streams import TaxelFrame
from palpate.hardware.dynamixel.finger import forward_kinematics, tip_force_from_torques


def current_force_frames(finger, states, torques_of, surface_z: float) -> list[TaxelFrame]:
    """The force channel of a press from its joint states (``t``, ``position``, in time order).

    Args:
        finger: the finger description.
        states: the press's joint states.
        torques_of: ``state -> joint torques`` (N m), e.g. ``DynamixelFinger.joint_torques``.
        surface_z: height of the surface, m.
    """
    if not states:
        return []
    fz = np.array([tip_force_from_torques(finger, s.position, torques_of(s))[1] for s in states])
    tip_z = np.array([forward_kinematics(finger, s.position)[0][2] for s in states])
    free = tip_z >= surface_z + 0.5 * finger.approach_height
    baseline = float(np.median(fz[free])) if free.any() else 0.0
    t = np.array([s.t for s in states])
    keep = np.concatenate([[True], np.diff(t) > 0])
    return force_frames(t[keep], (fz - baseline)[keep])
