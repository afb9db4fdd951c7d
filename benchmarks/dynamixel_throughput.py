"""Sync-read round trips per second against the Protocol 2.0 servo emulator, through dynamixel-sdk.

One round trip = one GroupSyncRead of present current/velocity/position (10 bytes from address 126) of every
servo: the instruction out, one status packet per servo back. Measured with the emulator on a thread of this
process (as the tests run it; both sides then share the GIL) and in its own process (as a real bus would be,
the host alone in Python). Also the driver's read_state() (sync read + unit conversion + lost-servo checks)
and the codec's parse rate.

    .venv/bin/python benchmarks/dynamixel_throughput.py [--quick]
"""

from __future__ import annotations

import argparse
import contextlib
import subprocess
import sys
import time

import numpy as np

from palpate.hardware.dynamixel.protocol import PacketParser, encode, status_packet

BAUD = 1_000_000


@contextlib.contextmanager
def emulated_bus(ids: list[int], mode: str):
    if mode == "thread":
        from palpate.hardware.dynamixel.emulator import ServoBusEmulator

        with ServoBusEmulator(ids, baud=BAUD) as emu:
            yield emu.port
        return
    proc = subprocess.Popen([sys.executable, "-m", "palpate.hardware.dynamixel.emulator", "--ids",
                             ",".join(map(str, ids)), "--baud", str(BAUD)], stdout=subprocess.PIPE, text=True)
    try:
        yield proc.stdout.readline().strip()
    finally:
        proc.terminate()
        proc.wait(timeout=5)


def sdk_round_trips(port: str, ids: list[int], seconds: float) -> tuple[int, float, int]:
    from dynamixel_sdk import COMM_SUCCESS, GroupSyncRead, PacketHandler, PortHandler

    ph = PacketHandler(2.0)
    p = PortHandler(port)
    p.openPort()
    p.setBaudRate(BAUD)
    group = GroupSyncRead(p, ph, 126, 10)
    for i in ids:
        group.addParam(i)
    n = failures = 0
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        if group.txRxPacket() == COMM_SUCCESS:
            n += 1
        else:
            failures += 1
    elapsed = time.perf_counter() - t0
    p.closePort()
    return n, elapsed, failures


def driver_round_trips(port: str, ids: list[int], seconds: float) -> tuple[int, float, int]:
    from palpate.hardware.dynamixel.driver import DynamixelFinger
    from palpate.hardware.dynamixel.finger import finger_from_dict

    joints = [{"name": f"j{i}", "servo_id": i, "link_length": 0.05, "limits": [-1.0, 1.0]} for i in ids]
    finger = finger_from_dict({"name": "bench", "joints": joints, "servo": {"current_limit": 1000}}, "benchmark")
    n = 0
    with DynamixelFinger(port, BAUD, finger) as drv:
        t0 = time.perf_counter()
        while time.perf_counter() - t0 < seconds:
            drv.read_state()
            n += 1
        elapsed = time.perf_counter() - t0
        retries = drv.corrupt_retries + drv.timeout_retries
    return n, elapsed, retries


def parse_rate(seconds: float) -> float:
    rng = np.random.default_rng(0)
    packets = [encode(status_packet(int(i), 0, bytes(rng.integers(0, 256, 10).astype(np.uint8))))
               for i in rng.integers(0, 253, 2000)]
    blob = b"".join(packets)
    parser = PacketParser()
    n = 0
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        n += len(parser.feed(blob))
    return n / (time.perf_counter() - t0)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="0.5 s per row instead of 2 s")
    args = ap.parse_args()
    seconds = 0.5 if args.quick else 2.0
    print(f"sync read of 10 bytes from address 126 at {BAUD} baud over a pty, {seconds} s per row")
    print(f"{'emulator':>9} {'servos':>6} {'client':>12} {'round trips/s':>14} {'ms each':>8} {'failed/retried':>15}")
    for mode in ("thread", "process"):
        for n_servos in (1, 2, 3):
            ids = list(range(1, n_servos + 1))
            clients = [("sdk group", sdk_round_trips)]
            if n_servos >= 2:  # a finger has 2-3 joints
                clients.append(("read_state", driver_round_trips))
            for client, fn in clients:
                with emulated_bus(ids, mode) as port:
                    n, elapsed, bad = fn(port, ids, seconds)
                rate = n / elapsed
                print(f"{mode:>9} {n_servos:>6} {client:>12} {rate:>14.0f} {1e3 / rate:>8.2f} {bad:>15}")
    print(f"\nPacketParser: {parse_rate(seconds):,.0f} status packets/s parsed (13-byte data, pure Python)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
