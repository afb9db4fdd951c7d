"""Sync-read round trips per second against the Protocol 2.0 servo emulator, through dynamixel-sdk.

One round trip = one GroupSyncRead of present current/velocity/position (10 bytes from address 126) of every
servo: the instruction out, one status packet per servo back. Measured with the emulator on a thread of this
process (as the tests run it; both sides then share the GIL) and in its own process (as a real bus would be,
the host alone in Python). Also the driver's read_state() (sync read + unit conversion + lost-servo checks),
the codec's parse rate, and whole press-and-release cycles through the physics-backed chain (dynamixel-sdk ->
pty -> emulator -> MuJoCo finger with the local-Hertz contact -> currents and taxel frames), which run in real
time: the table gives wall time against the commanded motion time, control cycles/s during the press, the
cost of one load-model evaluation and of turning a press into taxel frames.

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


def physics_presses(n_presses: int) -> list[tuple]:
    """Rows (material, wall s, motion s, cycles/s, taxel frames, streams ms) for presses on the MuJoCo finger."""
    import dataclasses
    from pathlib import Path

    from palpate.core.session.sources import PressTarget
    from palpate.core.world.scene import Material, ObjectSpec, Scene
    from palpate.hardware.dynamixel.driver import DynamixelFinger
    from palpate.hardware.dynamixel.finger import inverse_kinematics, load_finger
    from palpate.hardware.dynamixel.physics_bus import physics_bus
    from palpate.hardware.dynamixel.press import FingerActuator

    finger = load_finger(Path(__file__).resolve().parent.parent / "models" / "fingers" / "planar2.toml")
    finger = dataclasses.replace(finger, approach_height=0.003)
    x, top = 0.07, 0.03
    rows = []
    for name, young in (("20 kPa", 2e4), ("500 kPa", 5e5)):
        scene = Scene((ObjectSpec("block", "box", (0.06, 0.04, top), (x, 0.0), Material(name, young)),))
        emu, physics = physics_bus(finger, scene, start=inverse_kinematics(finger, x, top + 0.003))
        target = PressTarget(x, 0.0, depth=0.004, force=8.0, speed=0.01)
        streams = physics.actuator_streams()
        spent = []

        def timed(t0, t1, spent=spent, streams=streams):
            s0 = time.perf_counter()
            out = streams(t0, t1)
            spent.append(time.perf_counter() - s0)
            return out

        with emu, DynamixelFinger(emu.port, BAUD, finger) as drv:
            act = FingerActuator(drv, top, streams=timed)
            for _ in range(n_presses):
                t0 = time.perf_counter()
                rec = act.press(target)
                wall = time.perf_counter() - t0
                depth = act.last.depth
                motion = 2 * (finger.approach_height + depth) / target.speed
                rows.append((name, act.last.stopped_by, wall, motion, len(act.last.joints) / wall, len(rec.frames),
                             1e3 * spent[-1]))
    return rows


def load_eval_time(n: int = 2000) -> float:
    """Mean time of one FingerPhysics.load (force + Jacobian, MuJoCo kinematics) in contact, s."""
    from pathlib import Path

    from palpate.core.world.scene import Material, ObjectSpec, Scene
    from palpate.hardware.dynamixel.finger import inverse_kinematics, load_finger
    from palpate.sim.finger_physics import FingerPhysics

    finger = load_finger(Path(__file__).resolve().parent.parent / "models" / "fingers" / "planar2.toml")
    physics = FingerPhysics(finger, Scene((ObjectSpec("b", "box", (0.06, 0.04, 0.03), (0.07, 0.0),
                                                      Material("m", 2e5)),)))
    q = inverse_kinematics(finger, 0.07, 0.028)
    servo = finger.directions * (q - finger.offsets)
    # distinct angles every call (a cache serves repeated ones)
    angles = servo[None, :] + 1e-6 * np.arange(n)[:, None]
    t0 = time.perf_counter()
    for a in angles:
        physics.load(a)
    return (time.perf_counter() - t0) / n


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
    print("\npress-and-release through the physics-backed chain (planar2, 3 mm approach, 4 mm or 8 N at 10 mm/s;"
          " real time by design)")
    print(f"{'material':>9} {'stop':>6} {'wall s':>7} {'motion s':>9} {'cycles/s':>9} {'frames':>7} "
          f"{'streams ms':>11}")
    for name, stop, wall, motion, rate, frames, ms in physics_presses(1 if args.quick else 3):
        print(f"{name:>9} {stop:>6} {wall:>7.2f} {motion:>9.2f} {rate:>9.0f} {frames:>7} {ms:>11.1f}")
    print(f"FingerPhysics.load (force + MuJoCo Jacobian) in contact: {1e6 * load_eval_time():.1f} us per call")
    return 0


if __name__ == "__main__":
    sys.exit(main())
