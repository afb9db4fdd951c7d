"""Device clocks: the wall clock a rig runs on, and a stepped clock a test (or a fast emulated run) controls.

A clock is a callable returning seconds with a ``sleep(seconds)`` method. Drivers pace their control loops with
``sleep`` and stamp readings with ``clock()``; emulators integrate their dynamics and emit their frames on the same
clock. On the :class:`WallClock` that is real time. On a :class:`StepClock` time stands still until the host sleeps
on it, so an emulated servo moves by exactly one control cycle per cycle whatever the operating system's scheduler
does: a test's outcome then depends on the messages exchanged, never on how loaded the machine is.
"""

from __future__ import annotations

import collections
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
        wall_ratio: each sleep also waits this fraction of it on the wall clock (0: none).

    Every emulator and driver sharing one StepClock sees the same instants: a driver that reads its servos once
    per control cycle and sleeps out the rest of the cycle advances the emulated physics by exactly that cycle.
    """

    virtual = True

    def __init__(self, start: float = 0.0, wall_ratio: float = 0.0):
        if not 0 <= wall_ratio <= 1:
            raise ValueError(f"StepClock wall_ratio must be in [0, 1], got {wall_ratio!r}")
        self._t = float(start)
        self._wall_ratio = float(wall_ratio)
        self._lock = threading.Lock()

    def __call__(self) -> float:
        return self._t

    def sleep(self, seconds: float) -> None:
        """Advance by ``seconds``; with ``wall_ratio`` also wait that fraction of it on the wall (time for other
        threads, such as a streaming emulator's, to run)."""
        if seconds > 0:
            with self._lock:
                self._t += float(seconds)
            if self._wall_ratio:
                time.sleep(seconds * self._wall_ratio)


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


class DeviceTimeMap:
    """A device's own times put on the host clock: ``host = device + offset``, the offset being the smallest
    ``arrival - device`` seen over the last ``window`` s of arrivals (the least delayed sample: USB and scheduling
    only ever add delay). The window lets the offset follow the two crystals' drift (50 ppm: 0.5 ms per 10 s)."""

    def __init__(self, window: float = 10.0):
        if not window > 0:
            raise ValueError(f"DeviceTimeMap window must be > 0 s, got {window!r}")
        self.window = float(window)
        self._queue: collections.deque[tuple[float, float]] = collections.deque()  # (arrival, arrival - device)

    def observe(self, device_t: float, arrival: float) -> None:
        """A sample stamped ``device_t`` by the device arrived at host time ``arrival``."""
        diff = arrival - device_t
        q = self._queue
        while q and q[-1][1] >= diff:  # a monotonic queue: the front is the window's minimum
            q.pop()
        q.append((arrival, diff))
        while q[0][0] < arrival - self.window:
            q.popleft()

    @property
    def offset(self) -> float | None:
        """Host time minus device time, s (None before the first sample)."""
        return self._queue[0][1] if self._queue else None

    def host_time(self, device_t: float) -> float:
        """``device_t`` on the host clock."""
        if not self._queue:
            raise ValueError("DeviceTimeMap: no sample seen yet")
        return device_t + self._queue[0][1]


def read_arrived(port, limit: int) -> bytes:
    """What has arrived on a pyserial ``port`` (at most ``limit`` bytes), waiting up to the port's timeout only for
    the first byte.

    A plain ``read(limit)`` waits out the whole timeout unless ``limit`` bytes come, so everything that arrived in
    it is stamped at its end: a frame every 20 ms read with a 20 ms timeout can be stamped up to 20 ms late for
    seconds on end (the two periods beat), and a :class:`DeviceTimeMap` only finds the true delay when a frame
    happens to land just before a read returns. Returning as soon as bytes are there stamps a record when its last
    byte arrives.
    """
    waiting = port.in_waiting
    return port.read(min(limit, max(1, waiting)))
