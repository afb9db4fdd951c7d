"""Errors raised across palpate. Each says what was wrong and, where it can, what to change."""

from __future__ import annotations


class PalpateError(Exception):
    """Base class of every error palpate raises on purpose."""


class ValidationError(PalpateError, ValueError):
    """Input (a file, an array, a parameter) is not what was expected; the message names it."""


class FitError(PalpateError, ValueError):
    """An interaction fit cannot be made from the data given (too few samples, constant x, all zero)."""


class SegmentationError(PalpateError, ValueError):
    """A stream could not be segmented into presses."""


class SimulationDiverged(PalpateError, RuntimeError):
    """The physics diverged (NaN, MuJoCo warning, runaway penetration or energy).

    The message names the parameter to change (timestep, stiffness, speed).
    """


class PressShortfall(SimulationDiverged):
    """A simulated press did not reach its commanded depth or force (within 2%); the message names what limits it
    (drive stiffness, speed) and what to change."""


class DeviceError(PalpateError, RuntimeError):
    """A device did not answer, answered wrongly, or reported an error."""


class RecordingError(PalpateError, ValueError):
    """A recording file is truncated, corrupt or not a palpate recording.

    Attributes:
        salvaged: how many messages could still be read before the damage (0 if none).
    """

    def __init__(self, message: str, salvaged: int = 0):
        super().__init__(message)
        self.salvaged = salvaged


class NotFittedError(ValidationError):
    """A model was asked to predict before it was fitted (or loaded)."""


class Terminated(BaseException):
    """SIGTERM or SIGHUP reached a process that unwinds on them (a sweep ending its workers on the way out).

    Like KeyboardInterrupt, not an Exception: nothing that catches errors swallows it.

    Attributes:
        signum: the signal's number (the command exits with 128 + signum).
    """

    def __init__(self, signum: int, name: str):
        super().__init__(name)
        self.signum = signum
