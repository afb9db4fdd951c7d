"""The host side of the tactile array: a thread reads the serial port, parses frames, and keeps them with their
counters and arrival times.

Times: the array samples at its own steady ``rate``; its counter says which sample a frame is. A frame's time is
``counter * period`` put on the host clock by a :class:`~palpate.hardware.clock.DeviceTimeMap` (the least-delayed
arrival over the last seconds), so USB latency and a busy host shift no frame, and a frame read late keeps its time.
Counters wrap at 2^16 (21 min at 50 Hz) and are unwrapped with the arrival times.

Nothing is invented: a counter gap is counted as lost frames, a bad checksum as a corrupt frame, and a pad silent
for ``timeout`` s is reported (``stats.silent``), not filled in.
"""

from __future__ import annotations

import collections
import threading
from dataclasses import dataclass

import numpy as np

from palpate.core.errors import DeviceError, ValidationError
from palpate.core.perception.streams import TaxelFrame
from palpate.hardware.clock import Clock, DeviceTimeMap, as_clock, read_arrived
from palpate.hardware.tactile.protocol import COUNTER_MOD, FrameParser

READ_CHUNK = 4096


@dataclass
class TactileStats:
    """What the reader saw: frames kept; lost: counters that never arrived as a whole frame (dropped on the way, or
    arrived corrupted); corrupt: frames dropped for a bad checksum or size (or repeated); garbage bytes; and whether
    the array went silent (no frame for ``timeout`` s after the first)."""

    frames: int = 0
    lost: int = 0
    corrupt: int = 0
    garbage_bytes: int = 0
    silent: bool = False
    error: str = ""

    def to_dict(self) -> dict:
        return {"frames": self.frames, "lost": self.lost, "corrupt": self.corrupt, "garbage_bytes": self.garbage_bytes,
                "silent": self.silent, "error": self.error}


class TactileArrayReader:
    """Read a tactile array on a serial port (or an emulator's pty) in a background thread.

    Args:
        port: serial device path.
        rows, cols: the pad's size.
        sensel_area: area of one sensel, m^2.
        fmt: "binary" or "csv" (see :mod:`palpate.hardware.tactile.protocol`).
        baud: serial bit rate.
        rate: the array's frame rate, Hz (its frame period sets the times).
        clock: the host clock frames are put on (the driver's, when a finger presses).
        sensor_id: the TaxelFrame sensor id.
        timeout: a pad silent this long after its first frame is reported silent, s.
        keep: most frames kept for :meth:`between` (the oldest go first).
    """

    def __init__(self, port: str, *, rows: int = 4, cols: int = 4, sensel_area: float, fmt: str = "binary",
                 baud: int = 115200, rate: float = 50.0, clock: Clock | None = None, sensor_id: str = "taxels",
                 timeout: float = 1.0, keep: int = 200_000):
        if not (np.isfinite(sensel_area) and sensel_area > 0):
            raise ValidationError(f"tactile array sensel area must be > 0 m^2, got {sensel_area!r}")
        if not (np.isfinite(rate) and 0 < rate <= 10000):
            raise ValidationError(f"tactile array rate must be in (0, 10000] Hz, got {rate!r}")
        self.port = str(port)
        self.baud = int(baud)
        self.parser = FrameParser(rows, cols, fmt)
        self.sensel_area = float(sensel_area)
        self.period = 1.0 / float(rate)
        self.clock = as_clock(clock)
        self.sensor_id = sensor_id
        self.timeout = float(timeout)
        self.stats = TactileStats()
        self._map = DeviceTimeMap()
        self._frames: collections.deque[tuple[int, float, np.ndarray]] = collections.deque(maxlen=int(keep))
        self._drained = 0  # frames handed out by drain() (index into the sequence of all frames)
        self._total = 0
        self._last: tuple[int, int, float] | None = None  # (raw counter, unwrapped counter, arrival)
        self._last_t: float | None = None
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._serial = None

    # ---- lifetime --------------------------------------------------------------------------------------------
    def start(self) -> TactileArrayReader:
        """Open the port and start reading; DeviceError naming the port if it cannot be opened."""
        if self._thread is not None:
            return self
        try:
            import serial
        except ImportError as exc:
            raise DeviceError("pyserial is needed for the tactile array: pip install 'palpate[hardware]'") from exc
        try:
            self._serial = serial.Serial(self.port, self.baud, timeout=0.02)
        except (serial.SerialException, OSError, ValueError) as exc:
            raise DeviceError(f"cannot open the tactile array's port {self.port!r}: {exc}") from None
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name=f"tactile-reader {self.port}", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        """Stop reading and close the port."""
        if self._thread is None:
            return
        self._stop.set()
        self._thread.join(timeout=2.0)
        self._thread = None
        try:
            self._serial.close()
        except Exception:
            pass

    def __enter__(self) -> TactileArrayReader:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()

    # ---- reading ---------------------------------------------------------------------------------------------
    def _run(self) -> None:
        try:
            while not self._stop.is_set():
                data = read_arrived(self._serial, READ_CHUNK)
                arrival = self.clock()
                if data:
                    self.feed(data, arrival)
                elif self._last is not None and arrival - self._last[2] > self.timeout:
                    self.stats.silent = True
        except Exception as exc:  # the port went away: say so, keep what was read
            self.stats.error = f"reading {self.port} failed: {exc}"
            self.stats.silent = True

    def feed(self, data: bytes, arrival: float) -> None:
        """Parse bytes that arrived at host time ``arrival`` (the reading thread calls this; tests may too)."""
        frames = self.parser.feed(data)
        with self._lock:
            self.stats.corrupt = self.parser.corrupt
            self.stats.garbage_bytes = self.parser.garbage
            for f in frames:
                n = self._unwrap(f.counter, arrival)
                if n is None:
                    continue
                self._map.observe(n * self.period, arrival)
                self._frames.append((n, arrival, f.counts))
                self._total += 1
                self.stats.frames += 1
                self.stats.silent = False

    def _unwrap(self, counter: int, arrival: float) -> int | None:
        if self._last is None:
            self._last = (counter, counter, arrival)
            return counter
        raw, n_last, t_last = self._last
        step = (counter - raw) % COUNTER_MOD
        if step == 0:
            self.stats.corrupt += 1  # the same frame twice: a repeat, not a new sample
            return None
        # after a long silence the counter may have wrapped more than once: the arrival times tell how often
        expected = (arrival - t_last) / self.period
        step += COUNTER_MOD * max(0, int(round((expected - step) / COUNTER_MOD)))
        self.stats.lost += step - 1
        n = n_last + step
        self._last = (counter, n, arrival)
        return n

    def _frame(self, n: int, counts: np.ndarray, offset: float) -> TaxelFrame:
        return TaxelFrame(n * self.period + offset, counts, self.sensel_area, self.sensor_id)

    def drain(self) -> list[TaxelFrame]:
        """Frames received since the last drain, in order, on the host clock (strictly increasing times)."""
        with self._lock:
            new = self._total - self._drained
            items = list(self._frames)[-new:] if new > 0 else []
            self._drained = self._total
            offset = self._map.offset
        out = []
        for n, _, counts in items:
            frame = self._frame(n, counts, offset)
            if self._last_t is not None and frame.t <= self._last_t:
                # the offset dropped (a less delayed frame came in): keep times increasing, by the smallest step
                frame = TaxelFrame(self._last_t + 1e-6, counts, self.sensel_area, self.sensor_id)
            self._last_t = frame.t
            out.append(frame)
        return out

    def latest(self) -> float:
        """Host time of the newest frame kept (-inf before the first)."""
        with self._lock:
            if not self._frames or self._map.offset is None:
                return float("-inf")
            return self._frames[-1][0] * self.period + self._map.offset

    def between(self, t0: float, t1: float) -> list[TaxelFrame]:
        """Kept frames with t0 <= t <= t1 (host clock), all timed with the current offset."""
        with self._lock:
            offset = self._map.offset
            items = list(self._frames)
        if offset is None:
            return []
        out = [self._frame(n, counts, offset) for n, _, counts in items if t0 <= n * self.period + offset <= t1]
        return out
