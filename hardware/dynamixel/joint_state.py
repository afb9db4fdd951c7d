"""What the driver reads from the finger's servos, and the error a servo that stops answering raises."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from palpate.core.errors import DeviceError


@dataclass(frozen=True)
class JointState:
    """Joint state of the finger at one time.

    Attributes:
        t: time, s (the driver's monotonic clock).
        position: joint angles, rad, shape (n,).
        velocity: joint velocities, rad/s, shape (n,).
        current: servo currents expressed on the joints (sign follows the joint angle), A, shape (n,).
    """

    t: float
    position: np.ndarray
    velocity: np.ndarray
    current: np.ndarray


class LostServo(DeviceError):
    """A servo stopped answering; ``servo_id`` names it."""

    def __init__(self, message: str, servo_id: int):
        super().__init__(message)
        self.servo_id = servo_id
