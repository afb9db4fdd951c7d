"""A Polhemus Liberty on a pseudo-terminal, for tests and demos without the device.

The emulator owns the master side of a pty and answers, in a background thread, the byte protocol of
:mod:`palpate.hardware.polhemus.protocol`: ``F0``/``F1`` (ASCII/binary), ``U0``/``U1`` (inch/cm), ``O`` (output
list, per station or ``*``), ``P`` (one record per station; stops continuous output when it is on) and ``C``
(continuous output at ``rate`` Hz). Any client opens :attr:`LibertyEmulator.port` with pyserial exactly as it
would open the device.

Like the device after power-up it starts in ASCII, inches, output list 2,7,1 (the real default list also
carries Euler angles, item 4, which palpate does not decode), so a client must configure it.

Wrong baud: pyserial on a pty accepts any baud, so the emulator reads the speed the client set (the pty's
termios) and, when it differs from its own ``baud``, behaves as a UART at the wrong speed does: what it receives is
garbage (no command is understood) and what it sends is garbled (see :class:`~palpate.hardware.pty_device.PtyDevice`,
which serves the pty).

Faults (:class:`Faults`) are those of a real line: garbage bursts, records cut short, device error codes, a device
going silent, and, byte by byte, truly random bytes (any value, 'L' and 'Y' included) and false record headers
followed by random payload. Every record sent is kept in :attr:`LibertyEmulator.sent` with the pose it carried, so
a test can count wrong poses a driver accepted.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from palpate.core.errors import ValidationError
from palpate.hardware.polhemus.protocol import (
    CM_PER_INCH,
    ITEM_CRLF,
    ITEM_POSITION,
    ITEM_QUATERNION,
    MAX_STATIONS,
    encode_ascii,
    encode_binary,
    parse_command_line,
    validate_items,
    validate_station,
)
from palpate.hardware.pty_device import PtyDevice

Motion = Callable[[float, int], tuple[np.ndarray, np.ndarray]]
# The device queues at most this much output for a host that does not read; more is dropped (and counted).
MAX_QUEUED_BYTES = 1 << 20
# Records kept in LibertyEmulator.sent (the truth a test compares with); later ones are not logged.
MAX_SENT_LOG = 1_000_000


@dataclass(frozen=True)
class Faults:
    """Error injection, counted over records sent (all stations), 1-based: ``every=N`` hits records N, 2N, ...

    Attributes:
        corrupt_every: send ``corrupt_bytes`` random bytes (never 'L') before every Nth record (0 = never).
        corrupt_bytes: how many garbage bytes to insert.
        partial_every: send only the first half of every Nth record (0 = never).
        error_every: set the error byte of every Nth record to ``error_code`` (0 = never).
        error_code: the nonzero error code sent.
        silent_after: after this many records, stop answering altogether (None = never).
        byte_error_rate: each byte sent is replaced by a uniformly random byte (any value) with this probability.
        false_header_every: before every Nth record, a well-formed header ('LY', a configured station, 'C', the
            right size) followed by random payload bytes (0 = never).
    """

    corrupt_every: int = 0
    corrupt_bytes: int = 7
    partial_every: int = 0
    error_every: int = 0
    error_code: int = 0x45
    silent_after: int | None = None
    byte_error_rate: float = 0.0
    false_header_every: int = 0

    def __post_init__(self) -> None:
        for name in ("corrupt_every", "partial_every", "error_every", "corrupt_bytes", "false_header_every"):
            if int(getattr(self, name)) < 0:
                raise ValidationError(f"Faults.{name} must be >= 0, got {getattr(self, name)}")
        if self.error_code in (0, 0x20) or not 0 < self.error_code < 256:
            raise ValidationError(f"Faults.error_code must be a nonzero byte other than space, got {self.error_code}")
        if self.silent_after is not None and self.silent_after < 0:
            raise ValidationError(f"Faults.silent_after must be >= 0 records, got {self.silent_after}")
        if not 0.0 <= self.byte_error_rate < 1.0:
            raise ValidationError(f"Faults.byte_error_rate must be in [0, 1), got {self.byte_error_rate}")


@dataclass(frozen=True)
class SentRecord:
    """What the emulator meant to send in one record (before any fault touched it).

    Attributes:
        station: station number.
        frame: frame count sent.
        timestamp_ms: device clock sent, ms (mod 2^32).
        position: m, world.
        quaternion: (w, x, y, z).
        faults: the faults applied to it ("corrupt", "partial", "device_error", "false_header" before it;
            "bytes" when a random byte error hit it).
    """

    station: int
    frame: int
    timestamp_ms: int
    position: np.ndarray
    quaternion: np.ndarray
    faults: str


def static_motion(t: float, station: int) -> tuple[np.ndarray, np.ndarray]:
    """Default motion: station n sits still at (0.1 n, 0, 0.2) m with identity orientation."""
    return np.array([0.1 * station, 0.0, 0.2]), np.array([1.0, 0.0, 0.0, 0.0])


def press_motion(
    depth: float = 0.005, period: float = 2.0, origin=(0.0, 0.0, 0.05), tilt: float = 0.0
) -> Motion:
    """A fingertip pressing straight down ``depth`` m and back every ``period`` s (raised-cosine profile).

    Station n is offset by 0.05 (n - 1) m along x. ``tilt`` rad rotates about y, scaled by the press depth so the
    orientation changes too. Returns ``motion(t, station) -> (position m, quaternion w,x,y,z)``.
    """
    if not (depth >= 0 and period > 0):
        raise ValidationError(f"press_motion needs depth >= 0 m and period > 0 s, got {depth}, {period}")
    origin = np.asarray(origin, dtype=float)

    def motion(t: float, station: int) -> tuple[np.ndarray, np.ndarray]:
        s = 0.5 * (1.0 - np.cos(2.0 * np.pi * t / period))  # 0 -> 1 -> 0 over one period
        pos = origin + np.array([0.05 * (station - 1), 0.0, -depth * s])
        half = 0.5 * tilt * s
        return pos, np.array([np.cos(half), 0.0, np.sin(half), 0.0])

    return motion


class LibertyEmulator(PtyDevice):
    """A Liberty speaking the real byte protocol on a pty (serving starts at construction).

    Args:
        rate: continuous output rate, frames per second (each frame has one record per station).
        stations: the stations with a sensor plugged in (1-based).
        noise: standard deviation of the position noise added to every axis, m.
        seed: seed of the noise, the garbage and the byte errors. Each record draws them from its own generator,
            keyed by the seed and the record's index since :attr:`faults` was last set, so one seed gives one
            pattern of noise and faults whatever the host's timing.
        motion: ``motion(t, station) -> (position m (3,), quaternion w,x,y,z (4,))``, t in s on the device clock.
        baud: the device's baud rate; a client at another speed gets garbage (see the module docstring).
        faults: error injection.
        clock: the device's clock (:mod:`palpate.hardware.clock`); the device time starts at 0 at construction.
        stream_time: when set, the device clock reads this (s, whole ms) at the first frame of continuous output,
            so the stamps and the motion's phase do not depend on when the host's ``C`` arrived (a reproducible
            trial; the real device's clock just runs on). None: frames start when ``C`` arrives.

    Timestamps (item 8) are the device clock's ms; continuous frames are exactly 1/rate apart on it. Use as a
    context manager or call :meth:`close`.
    """

    def __init__(
        self,
        rate: float = 240.0,
        stations=(1,),
        noise: float = 0.0,
        seed: int = 0,
        motion: Motion | None = None,
        baud: int = 115200,
        faults: Faults | None = None,
        clock=None,
        stream_time: float | None = None,
    ):
        if not (np.isfinite(rate) and 0 < rate <= 10000):
            raise ValidationError(f"emulator rate must be in (0, 10000] Hz, got {rate}")
        if not (np.isfinite(noise) and noise >= 0):
            raise ValidationError(f"emulator position noise must be >= 0 m, got {noise}")
        super().__init__(baud, "liberty-emulator", clock=clock, garble_wrong_baud=True, max_queued=MAX_QUEUED_BYTES,
                         seed=seed + 1)
        self.rate = float(rate)
        self.stations = tuple(validate_station(s) for s in stations)
        if not self.stations:
            raise ValidationError("emulator needs at least one station")
        self.noise = float(noise)
        self.motion = motion or static_motion
        if stream_time is not None and not (np.isfinite(stream_time) and stream_time >= 0):
            raise ValidationError(f"emulator stream_time must be >= 0 s, got {stream_time}")
        self.stream_time = None if stream_time is None else round(float(stream_time) * 1000.0) / 1000.0
        self._seed = int(seed)
        self._lock = threading.Lock()
        self.faults = faults or Faults()
        # Device state (power-up defaults).
        self.binary = False
        self.units = "in"
        self.items = {s: (ITEM_POSITION, ITEM_QUATERNION, ITEM_CRLF) for s in range(1, MAX_STATIONS + 1)}
        self.continuous = False
        # What happened, for tests and summaries.
        self.commands: list[str] = []
        self.unknown_commands: list[str] = []
        self.records_sent = 0
        # One entry per record sent: (station, timestamp ms, faults applied such as "corrupt,partial", bytes sent
        # that belong to no good record: the garbage, or the whole of a cut record).
        self.log: list[tuple[int, int, str, int]] = []
        self.sent: list[SentRecord] = []
        self.frames_sent = 0
        self.faults_injected = {"corrupt": 0, "partial": 0, "device_error": 0, "false_header": 0, "bytes": 0}
        self._frame_count = 0
        self._line = b""
        self._next_frame_time = 0.0
        self._t0 = self.clock()
        self.start()

    @property
    def faults(self) -> Faults:
        """The faults injected; setting them restarts the records' index that keys their random draws."""
        return self._faults

    @faults.setter
    def faults(self, value: Faults) -> None:
        with self._lock:
            self._faults = value
            self._draw_index = 0

    # -- lifecycle ----------------------------------------------------------------------------------------

    def close(self) -> None:
        """Stop serving and release the pty."""
        self.stop()

    @property
    def silent(self) -> bool:
        """True once the injected 'go silent' fault has fired."""
        s = self.faults.silent_after
        return s is not None and self.records_sent >= s

    @property
    def epoch(self) -> float:
        """The clock's reading at the device's time zero (another emulator can share it: one motion, two devices;
        with ``stream_time`` set it moves when continuous output starts)."""
        return self._t0

    def device_time(self) -> float:
        """Seconds on the device clock."""
        return self.clock() - self._t0

    def start_continuous(self) -> None:
        """Put the device in continuous mode as if a previous session had left it streaming."""
        with self._lock:
            self._start_continuous()

    # -- the pty (called by PtyDevice's thread) -----------------------------------------------------------

    def respond(self, data: bytes) -> bytes:
        if self.silent:
            return b""
        with self._lock:
            self._receive(data)
        return b""  # records are queued as they are made

    def emit(self, now: float) -> bytes:
        with self._lock:
            if self.continuous and not self.silent:
                self._emit_due_frames()
        return b""

    def next_emit(self) -> float | None:
        if not self.continuous or self.silent:
            return None
        return self._t0 + self._next_frame_time

    # -- commands -----------------------------------------------------------------------------------------

    def _receive(self, data: bytes) -> None:
        for byte in data:
            ch = bytes([byte])
            if not self._line and ch in (b"P", b"C"):
                self.commands.append(ch.decode())
                self._single() if ch == b"P" else self._start_continuous()
            elif ch in (b"\r", b"\n"):
                if self._line:
                    self._command(self._line)
                self._line = b""
            else:
                self._line += ch
                if len(self._line) > 256:  # runaway input with no CR is not a command
                    self._line = b""

    def _command(self, line: bytes) -> None:
        text = line.decode("ascii", errors="replace")
        self.commands.append(text)
        try:
            letter, args = parse_command_line(line)
        except ValidationError:
            self.unknown_commands.append(text)
            return
        if letter == "F" and args in (["0"], ["1"]):
            self.binary = args == ["1"]
        elif letter == "U" and args in (["0"], ["1"]):
            self.units = "cm" if args == ["1"] else "in"
        elif letter == "O" and len(args) >= 2:
            try:
                items = validate_items(int(a) for a in args[1:])
                targets = range(1, MAX_STATIONS + 1) if args[0] == "*" else [validate_station(int(args[0]))]
            except (ValueError, ValidationError):
                self.unknown_commands.append(text)
                return
            for s in targets:
                self.items[s] = items
        else:
            self.unknown_commands.append(text)

    def _single(self) -> None:
        if self.continuous:
            # On the Liberty, P while streaming ends continuous mode and sends nothing.
            self.continuous = False
            return
        self._send_frame("P", self.device_time())

    def _start_continuous(self) -> None:
        if not self.continuous:
            self.continuous = True
            if self.stream_time is not None:
                self._t0 = self.clock() - self.stream_time
            self._next_frame_time = self.device_time()

    def _emit_due_frames(self) -> None:
        now = self.device_time()
        period = 1.0 / self.rate
        while self._next_frame_time <= now and self.continuous and not self.silent:
            self._send_frame("C", self._next_frame_time)
            self._next_frame_time += period

    # -- records ------------------------------------------------------------------------------------------

    def _send_frame(self, command: str, t: float) -> None:
        # The device samples at the instant it stamps: the motion is evaluated at the 1-ms timestamp it reports.
        t = round(t * 1000.0) / 1000.0
        self._frame_count += 1
        self.frames_sent += 1
        scale = 100.0 if self.units == "cm" else 100.0 / CM_PER_INCH
        for station in self.stations:
            if self.silent:
                return
            pos, quat = self.motion(t, station)
            rng = np.random.default_rng((self._seed, self._draw_index))
            self._draw_index += 1
            pos = np.asarray(pos, dtype=float) + (rng.normal(0.0, self.noise, 3) if self.noise else 0.0)
            self._send_record(command, station, pos, scale, np.asarray(quat, dtype=float), t, rng)

    def _send_record(self, command: str, station: int, pos_m, scale: float, quat, t: float,
                     rng: np.random.Generator) -> None:
        f = self.faults
        k = self.records_sent + 1
        error = f.error_code if f.error_every and k % f.error_every == 0 else 0
        items = self.items[station]
        ts, frame = int(round(t * 1000.0)) & 0xFFFFFFFF, self._frame_count
        pos = pos_m * scale
        if self.binary:
            data = encode_binary(items, station, command, pos, quat, ts, frame, error)
        else:
            data = encode_ascii(items, station, command, pos, quat, ts, frame, error)
        applied = []
        if error:
            self.faults_injected["device_error"] += 1
            applied.append("device_error")
        wasted = 0
        if f.corrupt_every and k % f.corrupt_every == 0:
            # Garbage without 'L', so it cannot be taken for a header: the test knows exactly what was sent.
            junk = rng.integers(0, 255, f.corrupt_bytes, dtype=np.uint8)
            junk[junk == ord("L")] = 0x4D
            data = junk.tobytes() + data
            self.faults_injected["corrupt"] += 1
            applied.append("corrupt")
            wasted = f.corrupt_bytes
        if f.false_header_every and k % f.false_header_every == 0:
            fake = bytearray(encode_binary(items, station, "C"))
            fake[8:] = rng.integers(0, 256, len(fake) - 8, dtype=np.uint8).tobytes()
            data = bytes(fake) + data
            self.faults_injected["false_header"] += 1
            applied.append("false_header")
        if f.partial_every and k % f.partial_every == 0:
            data = data[: len(data) // 2]
            self.faults_injected["partial"] += 1
            applied.append("partial")
            wasted = len(data)
        if f.byte_error_rate > 0:
            raw = np.frombuffer(data, dtype=np.uint8).copy()
            hit = rng.random(len(raw)) < f.byte_error_rate
            if hit.any():
                raw[hit] = rng.integers(0, 256, int(hit.sum()), dtype=np.uint8)
                data = raw.tobytes()
                self.faults_injected["bytes"] += int(hit.sum())
                applied.append("bytes")
        self.records_sent += 1
        self.log.append((station, ts, ",".join(applied), wasted))
        if len(self.sent) < MAX_SENT_LOG:
            self.sent.append(SentRecord(station, frame, ts, np.asarray(pos_m, dtype=float).copy(),
                                        np.asarray(quat, dtype=float).copy(), ",".join(applied)))
        self.queue(data)


def main(argv: list[str] | None = None) -> int:
    """Run an emulator until Ctrl-C, printing its port: ``python -m palpate.hardware.polhemus.emulator``."""
    import argparse

    ap = argparse.ArgumentParser(description="A Polhemus Liberty emulator on a pseudo-terminal.")
    ap.add_argument("--rate", type=float, default=240.0, help="frames per second (default 240)")
    ap.add_argument("--stations", default="1", help="comma-separated stations with a sensor (default 1)")
    ap.add_argument("--baud", type=int, default=115200, help="the emulated device's baud rate")
    ap.add_argument("--noise", type=float, default=1e-4, help="position noise, m (default 1e-4)")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    stations = tuple(int(s) for s in args.stations.split(","))
    emu = LibertyEmulator(rate=args.rate, stations=stations, noise=args.noise, seed=args.seed, motion=press_motion(),
                          baud=args.baud)
    emu.serve_until_interrupted(f"Liberty emulator on {emu.port} ({args.baud} baud, stations {list(stations)}); "
                                "Ctrl-C to stop")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
