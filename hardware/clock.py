"""Device clocks: the wall clock a rig runs on, and a stepped clock a test (or a fast emulated run) controls.

A clock is a callable returning seconds with a ``sleep(seconds)`` method. Drivers pace their control loops with
``sleep`` and stamp readings with ``clock()``; emulators integrate their dynamics and emit their frames on the same
clock. On the :class:`WallClock` that is real time. On a :class:`StepClock` time stands still until the host sleeps
on it, so an emulated servo moves by exactly one control cycle per cycle whatever the operating system's scheduler
does: a test's outcome then depends on the messages exchanged, never on how loaded the machine is.
"""

from __future__ import annotations

import threading
import time
from typing import Protocol


class Clock(Protocol):
    """What drivers and emulators need of a clock (seconds, monotonic)."""

    virtual: bool

    def __call__(self) -> float: ...

    def sleep(self, seconds: float) -> None: ...


class WallClock:
    """The host's monotonic clock; ``sleep`` really waits."""

    virtual = False

    def __call__(self) -> float:
        return time.monotonic()

    def sleep(self, seconds: float) -> None:
        if seconds > 0:
            time.sleep(seconds)


class StepClock:
    """Virtual time that advances only when someone sleeps on it (thread-safe).

    Args:
        start: the time at creation, s.

    Every emulator and driver sharing one StepClock sees the same instants: a driver that reads its servos once
    per control cycle and sleeps out the rest of the cycle advances the emulated physics by exactly that cycle.
    """

    virtual = True

    def __init__(self, start: float = 0.0):
        self._t = float(start)
        self._lock = threading.Lock()

    def __call__(self) -> float:
        return self._t

    def sleep(self, seconds: float) -> None:
        if seconds > 0:
            with self._lock:
                self._t += float(seconds)


class FastClock:
    """The wall clock run ``factor`` times faster (``sleep`` waits the shorter wall time): a streaming emulator on it
    sends a minute of its frames in a few seconds, with its own timing unchanged. For tests."""

    virtual = False

    def __init__(self, factor: float):
        if not factor > 0:
            raise ValueError(f"FastClock factor must be > 0, got {factor!r}")
        self.factor = float(factor)
        self._t0 = time.monotonic()

    def __call__(self) -> float:
        return (time.monotonic() - self._t0) * self.factor

    def sleep(self, seconds: float) -> None:
        if seconds > 0:
            time.sleep(seconds / self.factor)


#: The clock every device uses unless told otherwise.
WALL_CLOCK = WallClock()


def as_clock(clock) -> Clock:
    """``clock`` as a :class:`Clock`: None is the wall clock; a plain callable (e.g. ``time.monotonic``) is taken as
    a free-running clock whose ``sleep`` waits on the wall."""
    if clock is None:
        return WALL_CLOCK
    if hasattr(clock, "sleep") and hasattr(clock, "virtual"):
        return clock
    if not callable(clock):
        raise TypeError(f"a clock must be callable (seconds), got {type(clock).__name__}")
    return _FreeRunning(clock)


class _FreeRunning:
    virtual = False

    def __init__(self, fn):
        self._fn = fn

    def __call__(self) -> float:
        return float(self._fn())

    def sleep(self, seconds: float) -> None:
        if seconds > 0:
            time.sleep(seconds)
