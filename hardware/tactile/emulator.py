"""A tactile array on a pseudo-terminal: a microcontroller streaming its pad's counts at a steady rate.

The counts come from ``source(t) -> counts (rows, cols) uint8`` at each frame's time on the device clock: a model
of a fingertip pressing (:func:`press_counts`, sharing a press motion with the Liberty emulator so the two devices
see one press), or the simulation (:func:`palpate.hardware.dynamixel.physics_bus.physics_taxels`, the finger's
physics behind the servo emulator). Faults of a real line: dropped frames (the counter jumps), corrupted frames
(the checksum fails), random bytes, a device going silent.
"""

from __future__ import annotations

import argparse
import math
import sys
import threading
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from palpate.core.errors import ValidationError
from palpate.hardware.pty_device import PtyDevice
from palpate.hardware.tactile.protocol import COUNTER_MOD, FORMATS, check_shape, encode_binary, encode_csv

Source = Callable[[float], np.ndarray]


@dataclass(frozen=True)
class TactileFaults:
    """Faults, counted over frames (1-based: ``every=N`` hits frames N, 2N, ...).

    Attributes:
        drop_every: never send every Nth frame (its counter is skipped) (0 = never).
        corrupt_every: flip one byte of every Nth frame, so its checksum fails (0 = never).
        byte_error_rate: each byte sent is replaced by a random byte with this probability.
        silent_after: stop sending after this many frames (None = never).
    """

    drop_every: int = 0
    corrupt_every: int = 0
    byte_error_rate: float = 0.0
    silent_after: int | None = None

    def __post_init__(self) -> None:
        if self.drop_every < 0 or self.corrupt_every < 0:
            raise ValidationError("TactileFaults: drop_every and corrupt_every must be >= 0")
        if not 0.0 <= self.byte_error_rate < 1.0:
            raise ValidationError(f"TactileFaults.byte_error_rate must be in [0, 1), got {self.byte_error_rate}")


class TactileArrayEmulator(PtyDevice):
    """The array on a pty, streaming from the moment it is started.

    Args:
        source: counts at a device time, s.
        rows, cols: the pad's size.
        rate: frames per second.
        fmt: "binary" or "csv".
        baud: the port's bit rate.
        clock: the device clock (:mod:`palpate.hardware.clock`); frame k is the pad at ``t0 + k / rate``.
        faults: line faults.
        seed: seed of the faults.
        start_counter: the counter of the first frame.
        epoch: the clock reading ``source`` counts its time from (default: when serving starts); give another
            emulator's (``LibertyEmulator.epoch``) and both devices see one motion.
        ready: ``ready(t)`` (clock time) says whether the frame at t can be made yet (a physics behind the array
            that has not reached t); the frame is sent when it can, late but with its own counter.
    """

    def __init__(self, source: Source, *, rows: int = 4, cols: int = 4, rate: float = 50.0, fmt: str = "binary",
                 baud: int = 115200, clock=None, faults: TactileFaults | None = None, seed: int = 0,
                 start_counter: int = 0, epoch: float | None = None,
                 ready: Callable[[float], bool] | None = None):
        self.rows, self.cols = check_shape(rows, cols)
        if fmt not in FORMATS:
            raise ValidationError(f"tactile array format must be one of {FORMATS}, got {fmt!r}")
        if not (np.isfinite(rate) and 0 < rate <= 10000):
            raise ValidationError(f"tactile array rate must be in (0, 10000] Hz, got {rate!r}")
        super().__init__(baud, "tactile-emulator", clock=clock, garble_wrong_baud=True, seed=seed + 7)
        self.source = source
        self.rate = float(rate)
        self.fmt = fmt
        self.faults = faults or TactileFaults()
        self._rng = np.random.default_rng(seed)
        self._encode = encode_binary if fmt == "binary" else encode_csv
        self._lock = threading.Lock()
        self._k = 0
        self._counter0 = int(start_counter)
        self._t0 = 0.0
        self._epoch = epoch
        self._ready = ready
        self.sent: list[tuple[int, float]] = []  # (counter, device time) of every frame sent, for tests
        self.dropped = self.corrupted = 0

    def on_start(self) -> None:
        self._t0 = self.clock()

    def next_emit(self) -> float | None:
        if self.faults.silent_after is not None and self._k >= self.faults.silent_after:
            return None
        return self._t0 + self._k / self.rate

    def emit(self, now: float) -> bytes:
        out = bytearray()
        with self._lock:
            while True:
                due = self.next_emit()
                if due is None or due > now or (self._ready is not None and not self._ready(due)):
                    break
                self._k += 1
                out += self._frame(self._k, due)
        return bytes(out)

    def _frame(self, k: int, t: float) -> bytes:
        f = self.faults
        counter = (self._counter0 + k - 1) % COUNTER_MOD
        if f.drop_every and k % f.drop_every == 0:
            self.dropped += 1
            return b""
        since = t - (self._t0 if self._epoch is None else self._epoch)
        counts = np.asarray(self.source(since), dtype=np.uint8).reshape(self.rows, self.cols)
        data = bytearray(self._encode(counter, counts))
        if f.corrupt_every and k % f.corrupt_every == 0:
            data[len(data) // 2] ^= 0x10
            self.corrupted += 1
        if f.byte_error_rate > 0:
            hit = self._rng.random(len(data)) < f.byte_error_rate
            for i in np.flatnonzero(hit):
                data[i] = int(self._rng.integers(0, 256))
        self.sent.append((counter, t - self._t0))
        return bytes(data)


def press_counts(motion, *, station: int = 1, surface_z: float = 0.048, radius: float = 0.008,
                 young: float = 1e5, gain: float = 1.2e-3, rows: int = 4, cols: int = 4, pitch: float = 0.0025,
                 noise: float = 0.5, seed: int = 0) -> Source:
    """Counts of a pad on a fingertip following ``motion`` (a Liberty emulator's ``motion(t, station)``, m) against a
    flat surface at ``surface_z`` m: Hertz's pressure p(r) = p0 sqrt(1 - r^2/a^2), a = sqrt(R d), under the pad's
    sensel centres, times ``gain`` counts/Pa, plus noise (counts). ``young`` is the surface's modulus, Pa."""
    e_star = young / (1 - 0.5**2)
    rng = np.random.default_rng(seed)
    ys, xs = np.meshgrid((np.arange(rows) - (rows - 1) / 2) * pitch, (np.arange(cols) - (cols - 1) / 2) * pitch,
                         indexing="ij")
    r2 = xs**2 + ys**2

    def source(t: float) -> np.ndarray:
        pos, _ = motion(t, station)
        depth = max(0.0, surface_z - float(pos[2]))
        counts = np.zeros((rows, cols))
        if depth > 0:
            a = math.sqrt(radius * depth)
            p0 = 2 * e_star / math.pi * a / radius
            counts = gain * p0 * np.sqrt(np.clip(1 - r2 / a**2, 0.0, None))
        counts = counts + noise * rng.standard_normal(counts.shape)
        return np.clip(np.rint(counts), 0, 255).astype(np.uint8)

    return source


def main(argv: list[str] | None = None) -> int:
    """Serve an array pressing a block every 2 s from this process until Ctrl-C; prints its port."""
    from palpate.hardware.polhemus.emulator import press_motion

    ap = argparse.ArgumentParser(description="A tactile array emulator on a pseudo-terminal.")
    ap.add_argument("--rate", type=float, default=50.0, help="frames per second (default 50)")
    ap.add_argument("--format", choices=FORMATS, default="binary")
    ap.add_argument("--baud", type=int, default=115200)
    args = ap.parse_args(argv)
    source = press_counts(press_motion())
    TactileArrayEmulator(source, rate=args.rate, fmt=args.format, baud=args.baud).serve_until_interrupted()
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
