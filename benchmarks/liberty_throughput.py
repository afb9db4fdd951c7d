"""Polhemus Liberty throughput: records/s parsed (binary and ASCII, clean and damaged) and end to end over a pty.

Run: .venv/bin/python benchmarks/liberty_throughput.py [--quick]

A real Liberty sends 240 frames/s per station (up to 16 stations: 3840 records/s), so parsing needs to stay far
above that to leave the CPU for the perception stack. Rows:
- parser rows: bytes already in memory, fed in chunks of the given size; "arrays" is RecordParser.feed_arrays
  (numpy batch), "objects" is RecordParser.feed (one Record per record).
- damaged: 1 record in 50 prefixed with 7 garbage bytes and 1 in 70 cut in half (the resynchronising path).
- pty end to end: LibertyEmulator at a high rate -> pty -> pyserial -> LibertyDriver -> PoseSample (SI), both
  ends in this process on this machine's CPUs; the emulator thread shares the interpreter, so this is a floor.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from palpate.hardware.polhemus.driver import LibertyDriver
from palpate.hardware.polhemus.emulator import LibertyEmulator
from palpate.hardware.polhemus.parser import RecordParser
from palpate.hardware.polhemus.protocol import DEFAULT_ITEMS, encode_ascii, encode_binary
from palpate.hardware.polhemus.transport import SerialTransport


def make_binary(n: int, seed: int = 0, damaged: bool = False) -> bytes:
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    data = encode_binary(DEFAULT_ITEMS, (np.arange(n) % 4) + 1, "C", rng.normal(0, 30, (n, 3)), q,
                         np.arange(n), np.arange(n))
    if not damaged:
        return data
    size = len(data) // n
    parts = []
    for i in range(n):
        rec = data[i * size : (i + 1) * size]
        if i % 50 == 49:
            rec = b"\x01\x02\x03\x04\x05\x06\x07" + rec
        if i % 70 == 69:
            rec = rec[: size // 2]
        parts.append(rec)
    return b"".join(parts)


def make_ascii(n: int, seed: int = 0) -> bytes:
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    p = rng.normal(0, 30, (n, 3))
    return b"".join(encode_ascii(DEFAULT_ITEMS, 1 + i % 4, "C", p[i], q[i], i, i) for i in range(n))


def time_parser(data: bytes, chunk: int, mode: str, binary: bool = True, repeats: int = 3) -> tuple[float, int]:
    """Best records/s over ``repeats`` runs, and the record count."""
    best = 0.0
    count = 0
    for _ in range(repeats):
        parser = RecordParser(binary=binary)
        count = 0
        t0 = time.perf_counter()
        for i in range(0, len(data), chunk):
            piece = data[i : i + chunk]
            if mode == "arrays":
                count += len(parser.feed_arrays(piece))
            else:
                count += sum(1 for r in parser.feed(piece) if not hasattr(r, "kind"))
        dt = time.perf_counter() - t0
        best = max(best, count / dt)
    return best, count


def time_pty(rate: float, stations: tuple[int, ...], seconds: float) -> tuple[float, int, int, int]:
    """(received records/s on the device clock, received, sent during the stream, errors)."""
    with LibertyEmulator(rate=rate, stations=stations) as emu:
        with SerialTransport(emu.port, 115200, timeout=0.02) as tr:
            drv = LibertyDriver(tr, stations=stations, timeout=0.5)
            drv.configure()
            before = emu.records_sent
            poses = list(drv.stream(seconds=seconds))
            poses += drv.stop()
            sent = emu.records_sent - before
    t = np.array([p.t for p in poses if p.sensor_id.endswith(f"station{stations[0]}")])
    span = t[-1] - t[0] if t.size > 1 else float("nan")
    return len(poses) / max(span, 1e-9), len(poses), sent, len(drv.stats.errors)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="smaller data and shorter pty runs")
    args = ap.parse_args()
    n = 20_000 if args.quick else 200_000
    seconds = 0.5 if args.quick else 2.0

    clean = make_binary(n)
    damaged = make_binary(n, damaged=True)
    text = make_ascii(n // 10)
    print(f"Liberty parser throughput (output list 2,7,8,9,1: {len(clean) // n} bytes/record, {n} records)")
    print(f"{'stream':<10} {'format':<7} {'api':<8} {'chunk B':>9} {'records':>9} {'records/s':>12}")
    rows = []
    for chunk in (512, 4096, 65536, 1 << 20):
        rows.append(("clean", "binary", "arrays", chunk, *time_parser(clean, chunk, "arrays")))
    rows.append(("clean", "binary", "objects", 65536, *time_parser(clean, 65536, "objects")))
    rows.append(("damaged", "binary", "arrays", 4096, *time_parser(damaged, 4096, "arrays")))
    rows.append(("damaged", "binary", "arrays", 65536, *time_parser(damaged, 65536, "arrays")))
    rows.append(("clean", "ascii", "objects", 4096, *time_parser(text, 4096, "objects", binary=False)))
    for stream, fmt, api, chunk, rate, count in rows:
        print(f"{stream:<10} {fmt:<7} {api:<8} {chunk:>9} {count:>9} {rate:>12,.0f}")

    print()
    print(f"End to end over a pty (emulator -> pyserial -> driver -> PoseSample), {seconds:g} s per row")
    print(f"{'frames/s':>9} {'stations':>8} {'sent':>7} {'received':>9} {'errors':>7} {'records/s':>10}")
    for rate, stations in ((240.0, (1,)), (240.0, tuple(range(1, 17))), (2000.0, (1, 2, 3, 4))):
        got_rate, got, sent, errors = time_pty(rate, stations, seconds)
        print(f"{rate:>9.0f} {len(stations):>8} {sent:>7} {got:>9} {errors:>7} {got_rate:>10,.0f}")


if __name__ == "__main__":
    main()
