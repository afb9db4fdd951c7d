"""Termination signals as exceptions while a device must be left safe or a recording finished.

By default SIGTERM and SIGHUP end a Python process at once: no ``finally``, no ``with`` exit, no ``atexit``, so a
Dynamixel finger keeps its torque on and a recording loses its last chunk and summary. While :func:`holding` is
active (a finger is open, a recording command runs), both signals raise :class:`Terminated` in the main thread
instead, so the paths that already handle Ctrl-C and errors (the driver's safety contexts, ``with`` blocks,
``atexit``) switch torque off and finish files on them too. SIGINT stays Python's KeyboardInterrupt. A signal that
lands while a recording's writer is in the middle of a record is delivered again a moment later, so the file's last
record is whole.

:class:`Terminated` is a :class:`SystemExit` carrying the shell's exit code for the signal (128 + signal number),
so code that catches ``Exception`` does not swallow it and an uncaught one ends the process with that code. Once
one termination is under way, further SIGTERM/SIGHUP are noted but do not interrupt the clean-up.

Handlers can only be installed from the main thread; elsewhere :func:`holding` does nothing (the ``atexit`` and
``with`` paths still apply). The previous handlers are put back when the last holder leaves.
"""

from __future__ import annotations

import contextlib
import os
import signal
import threading

#: A signal that arrives while a recording is being written is delivered again after this long, s.
REDELIVER = 0.01
#: The signals turned into :class:`Terminated`.
SIGNALS = tuple(s for s in (getattr(signal, "SIGTERM", None), getattr(signal, "SIGHUP", None)) if s is not None)


class Terminated(SystemExit):
    """The process was asked to end by a signal; ``code`` is 128 + ``signum``."""

    def __init__(self, signum: int):
        super().__init__(128 + int(signum))
        self.signum = int(signum)

    def __str__(self) -> str:
        return f"terminated by {signal.Signals(self.signum).name}"


class _State:
    def __init__(self):
        self.lock = threading.Lock()
        self.depth = 0
        self.previous: dict[int, object] = {}
        self.terminating = False
        self.ignored: list[int] = []
        self.critical = 0  # depth of deferring() blocks


_STATE = _State()


def _interrupt(signum, frame) -> None:
    """SIGINT: Python's KeyboardInterrupt, but never in the middle of a recording's record."""
    if _STATE.critical or _writing(frame):
        threading.Timer(REDELIVER, os.kill, (os.getpid(), signum)).start()
        return
    raise KeyboardInterrupt


def _handler(signum, frame) -> None:
    if _STATE.terminating:
        _STATE.ignored.append(signum)  # a clean-up in progress is not interrupted again
        return
    if _STATE.critical or _writing(frame):
        # an exception inside a recording's writer would leave a record half written (the file unreadable):
        # the signal is delivered again in a moment, when the write is done
        threading.Timer(REDELIVER, os.kill, (os.getpid(), signum)).start()
        return
    _STATE.terminating = True
    raise Terminated(signum)


def _writing(frame) -> bool:
    """Whether the interrupted code is inside a recording's writer (palpate's or the mcap library's)."""
    while frame is not None:
        name = frame.f_code.co_filename.replace("\\", "/")
        if name.endswith("io/mcap_writer.py") or "/mcap/" in name or "/zstandard/" in name:
            return True
        frame = frame.f_back
    return False


def hold() -> bool:
    """Turn SIGTERM/SIGHUP into :class:`Terminated` until the matching :func:`release`; False (nothing done) when
    not called from the main thread."""
    if threading.current_thread() is not threading.main_thread():
        return False
    with _STATE.lock:
        if _STATE.depth == 0:
            _STATE.terminating = False
            for s in SIGNALS:
                _STATE.previous[s] = signal.signal(s, _handler)
            if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
                _STATE.previous[signal.SIGINT] = signal.signal(signal.SIGINT, _interrupt)
        _STATE.depth += 1
    return True


def release() -> None:
    """Undo one :func:`hold`; the previous handlers return when the last holder releases."""
    if threading.current_thread() is not threading.main_thread():
        return
    with _STATE.lock:
        if _STATE.depth == 0:
            return
        _STATE.depth -= 1
        if _STATE.depth == 0:
            for s, previous in _STATE.previous.items():
                signal.signal(s, previous if previous is not None else signal.SIG_DFL)
            _STATE.previous.clear()


@contextlib.contextmanager
def deferring():
    """A block no signal interrupts (it is delivered again 10 ms after the block ends): what must happen together,
    such as writing a sample and counting it."""
    _STATE.critical += 1
    try:
        yield
    finally:
        _STATE.critical -= 1


@contextlib.contextmanager
def holding():
    """Context in which SIGTERM and SIGHUP raise :class:`Terminated` (see the module docstring)."""
    held = hold()
    try:
        yield
    finally:
        if held:
            release()
