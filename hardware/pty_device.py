"""A device emulator's wire: a pseudo-terminal in raw mode served from a thread, so real client libraries
(dynamixel-sdk, pyserial) open its slave path like a USB serial adapter.

A subclass answers bytes with :meth:`PtyDevice.respond` (a servo bus answers packets) and may also send on its own
with :meth:`PtyDevice.emit` / :meth:`PtyDevice.next_emit` (a tracker or a tactile array streaming frames at its
rate). Output is queued and written without blocking, so a host that stops reading never stalls the device; past
``max_queued`` bytes the device drops what it cannot send (and counts it), as a UART's buffer overflows.

Time is the device's ``clock`` (:mod:`palpate.hardware.clock`): on a virtual clock a streaming device emits what is
due whenever the clock has moved, however late its thread runs.

A host whose port is set to another standard bit rate than the device's is a UART at the wrong speed: with
``garble_wrong_baud`` (a device that keeps talking, like a streaming tracker) what it receives is counted as
garbage and what it sends arrives as random bytes; without it (a servo bus) it neither hears nor answers.
"""

from __future__ import annotations

import os
import select
import termios
import threading
import time
import tty

import numpy as np

from palpate.core.errors import DeviceError
from palpate.hardware.clock import Clock, as_clock

#: Poll interval of the serving thread when nothing is due, s (also how fast stop() is noticed).
POLL = 0.05
#: Poll interval on a virtual clock, s (its time moves when the host sleeps, not with the wall).
VIRTUAL_POLL = 0.002


class PtyDevice:
    """The pty side of an emulated serial device; use as a context manager or call start()/stop().

    Args:
        baud: bit rate the device listens at.
        name: thread name (for debugging).
        clock: the device's clock (default the wall clock).
        garble_wrong_baud: a host at another bit rate gets random bytes (True) or nothing (False).
        max_queued: most bytes waiting for a host that does not read; more are dropped.
        seed: seed of the garbling.

    After :meth:`start`, ``port`` is the slave path to open.
    """

    def __init__(self, baud: int, name: str = "pty-device", *, clock: Clock | None = None,
                 garble_wrong_baud: bool = False, max_queued: int = 1 << 20, seed: int = 0):
        self.baud = int(baud)
        self._name = name
        self.clock = as_clock(clock)
        self.garble_wrong_baud = bool(garble_wrong_baud)
        self.max_queued = int(max_queued)
        self._garble_rng = np.random.default_rng(seed)
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._master = self._slave = -1
        self._out = bytearray()
        self.port = ""
        self.thread_error: BaseException | None = None
        self.garbled_bytes_in = 0
        self.dropped_bytes = 0

    # ---- what a device does (overridden) -----------------------------------------------------------------------
    def respond(self, data: bytes) -> bytes:
        """The device's answer to bytes the host wrote (may be empty)."""
        return b""

    def emit(self, now: float) -> bytes:
        """Bytes the device sends on its own by time ``now`` (its clock, s); called on every turn of the loop."""
        return b""

    def next_emit(self) -> float | None:
        """When (clock time, s) the device next has something to send on its own; None if nothing is scheduled."""
        return None

    def on_start(self) -> None:
        """Called when serving starts (a device resets its clock here)."""

    # ---- the wire ----------------------------------------------------------------------------------------------
    def _host_baud_matches(self) -> bool:
        expected = getattr(termios, f"B{self.baud}", None)
        if expected is None:
            return True
        try:
            attrs = termios.tcgetattr(self._slave)
        except termios.error:
            return True
        return attrs[4] == expected and attrs[5] == expected

    def queue(self, data: bytes) -> None:
        """Send ``data`` (garbled for a host at the wrong rate, dropped past ``max_queued``)."""
        if not data:
            return
        if not self._host_baud_matches():
            if not self.garble_wrong_baud:
                return
            data = self._garble_rng.integers(0, 256, len(data), dtype=np.uint8).tobytes()
        if len(self._out) + len(data) > self.max_queued:
            self.dropped_bytes += len(data)
            return
        self._out += data

    def _wait(self) -> float:
        due = self.next_emit()
        if due is None:
            return POLL  # nothing to send unasked: sleep until the host writes
        if self.clock.virtual:
            return VIRTUAL_POLL  # virtual time moves when the host sleeps on it: look again soon
        return min(POLL, max(0.0, due - self.clock()))

    def _serve(self) -> None:
        try:
            while not self._stop.is_set():
                ready, writable, _ = select.select([self._master], [self._master] if self._out else [], [],
                                                   self._wait())
                if ready:
                    try:
                        data = os.read(self._master, 4096)
                    except BlockingIOError:
                        data = b""
                    except OSError:
                        time.sleep(0.005)
                        data = b""
                    if data and not self._host_baud_matches():
                        # a UART at another rate sees framing errors, never a packet
                        self.garbled_bytes_in += len(data)
                    elif data:
                        self.queue(self.respond(data))
                self.queue(self.emit(self.clock()))
                if self._out:
                    try:
                        n = os.write(self._master, bytes(self._out[:65536]))
                        del self._out[:n]
                    except (BlockingIOError, InterruptedError):
                        pass
        except BaseException as exc:  # surfaced by stop(); the line goes silent like a crashed device
            self.thread_error = exc

    # ---- lifetime ----------------------------------------------------------------------------------------------
    def start(self):
        """Open the pty and start serving; returns self. ``.port`` is then the path to open."""
        if self._thread is not None:
            return self
        self._master, self._slave = os.openpty()
        # raw mode: no echo, no line discipline, no CR/LF translation of binary packets
        tty.setraw(self._slave)
        attrs = termios.tcgetattr(self._slave)
        speed = getattr(termios, f"B{self.baud}", termios.B38400)
        attrs[4] = attrs[5] = speed
        termios.tcsetattr(self._slave, termios.TCSANOW, attrs)
        os.set_blocking(self._master, False)
        self.port = os.ttyname(self._slave)
        self.on_start()
        self._stop.clear()
        self._thread = threading.Thread(target=self._serve, name=f"{self._name} {self.port}", daemon=True)
        self._thread.start()
        return self

    @property
    def serving(self) -> bool:
        """True while the serving thread runs."""
        return self._thread is not None and self._thread.is_alive()

    def stop(self) -> None:
        """Stop serving and close the pty. Raises DeviceError if the serving thread failed."""
        if self._thread is None:
            return
        self._stop.set()
        self._thread.join(timeout=2.0)
        self._thread = None
        for fd in (self._master, self._slave):
            try:
                os.close(fd)
            except OSError:
                pass
        self._master = self._slave = -1
        if self.thread_error is not None:
            err, self.thread_error = self.thread_error, None
            raise DeviceError(f"{self._name} on {self.port} failed: {err}") from err

    def serve_until_interrupted(self, banner: str | None = None) -> None:
        """Serve (starting if needed), print ``banner`` (default: the port) on stdout, and return on Ctrl-C or when
        the serving thread ends: the body of an emulator's ``main``."""
        self.start()
        print(banner or self.port, flush=True)
        try:
            while self.serving:
                time.sleep(0.2)
        except KeyboardInterrupt:
            pass
        finally:
            self.stop()

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()
