"""A device emulator's wire: a pseudo-terminal in raw mode served from a thread, so real client libraries
(dynamixel-sdk, pyserial) open its slave path like a USB serial adapter.

A subclass answers bytes with :meth:`PtyDevice.respond`; a host whose port is set to another standard bit rate
than the device's gets nothing, as on a real line.
"""

from __future__ import annotations

import os
import select
import termios
import threading
import time
import tty

from palpate.core.errors import DeviceError


class PtyDevice:
    """The pty side of an emulated serial device; use as a context manager or call start()/stop().

    Args:
        baud: bit rate the device listens at.
        name: thread name (for debugging).

    After :meth:`start`, ``port`` is the slave path to open.
    """

    def __init__(self, baud: int, name: str = "pty-device"):
        self.baud = int(baud)
        self._name = name
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._master = self._slave = -1
        self.port = ""
        self.thread_error: BaseException | None = None

    def respond(self, data: bytes) -> bytes:  # pragma: no cover - every device overrides it
        """The device's answer to bytes the host wrote (may be empty)."""
        raise NotImplementedError

    def on_start(self) -> None:
        """Called when serving starts (a device resets its clock here)."""

    def _host_baud_matches(self) -> bool:
        expected = getattr(termios, f"B{self.baud}", None)
        if expected is None:
            return True
        try:
            attrs = termios.tcgetattr(self._slave)
        except termios.error:
            return True
        return attrs[4] == expected and attrs[5] == expected

    def _serve(self) -> None:
        try:
            while not self._stop.is_set():
                ready, _, _ = select.select([self._master], [], [], 0.05)
                if not ready:
                    continue
                try:
                    data = os.read(self._master, 4096)
                except OSError:
                    time.sleep(0.005)
                    continue
                if not data or not self._host_baud_matches():
                    # a UART at another rate sees framing errors, never a packet
                    continue
                reply = self.respond(data)
                if reply:
                    os.write(self._master, reply)
        except BaseException as exc:  # surfaced by stop(); the line goes silent like a crashed device
            self.thread_error = exc

    def start(self):
        """Open the pty and start answering; returns self. ``.port`` is then the path to open."""
        if self._thread is not None:
            return self
        self._master, self._slave = os.openpty()
        # raw mode: no echo, no line discipline, no CR/LF translation of binary packets
        tty.setraw(self._slave)
        attrs = termios.tcgetattr(self._slave)
        speed = getattr(termios, f"B{self.baud}", termios.B38400)
        attrs[4] = attrs[5] = speed
        termios.tcsetattr(self._slave, termios.TCSANOW, attrs)
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

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()
