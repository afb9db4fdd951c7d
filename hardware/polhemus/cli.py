"""``palpate record liberty``: record a Polhemus Liberty (or its emulator) into an MCAP recording."""

from __future__ import annotations

import argparse
import sys
import time

from palpate.core.errors import DeviceError, ValidationError
from palpate.core.session.output_guard import check_output_file
from palpate.hardware.polhemus.driver import station_sensor_id
from palpate.hardware.polhemus.protocol import DEFAULT_ITEMS, MAX_STATIONS


def add_record_command(record: argparse._SubParsersAction) -> None:
    """Add ``liberty`` to the ``palpate record`` group."""
    p = record.add_parser(
        "liberty",
        help="record poses from a Polhemus Liberty (one MCAP topic per station)",
        description="Configure a Polhemus Liberty (binary or ASCII, cm, output list position, quaternion, "
        "timestamp, frame count), stream its stations for S seconds and write them to an MCAP recording on "
        "/palpate/pose/liberty_station<N> (the frame for Foxglove on /pose/liberty_station<N>). Ctrl-C, SIGTERM or "
        "SIGHUP stop early and keep what was recorded. Pose times are "
        "the device clock (1 ms resolution). Records that cannot be true (broken frame or clock sequence, a jump no "
        "hand makes) are dropped and counted. A device that goes silent ends the command with exit code 1 and a "
        "finished file.",
    )
    p.add_argument("--port", help="serial port of the Liberty, e.g. /dev/ttyUSB0 (not needed with --emulate)")
    p.add_argument("--baud", type=int, default=115200, help="baud rate set on the device (default 115200)")
    p.add_argument("--stations", default="1", help="comma-separated 1-based stations to record (default 1)")
    p.add_argument("--seconds", type=float, required=True, help="how long to record, s")
    p.add_argument("--out", required=True, help="output recording (.mcap)")
    p.add_argument("--force", action="store_true", help="overwrite an existing --out")
    p.add_argument("--units", choices=("cm", "in"), default="cm", help="units on the wire (poses are stored in m)")
    p.add_argument("--ascii", action="store_true", help="use ASCII output (F0) instead of binary (F1)")
    p.add_argument("--timeout", type=float, default=0.5,
                   help="how long to wait for an answer and how long a silent device is tolerated, s")
    p.add_argument("--emulate", action="store_true",
                   help="start a Liberty emulator on a pseudo-terminal (a station pressing 5 mm every 2 s) and "
                        "record from it")
    p.add_argument("--emulate-rate", type=float, default=240.0, help="emulator frame rate, Hz (default 240)")
    p.add_argument("--emulate-silent-after", type=int, metavar="N",
                   help="the emulator stops answering after N records (to see how a silent device ends a recording)")
    p.set_defaults(func=run_record)


def parse_stations(text: str) -> tuple[int, ...]:
    """Parse ``"1,2"`` into (1, 2); raises ValidationError naming the bad entry."""
    out = []
    for part in str(text).split(","):
        part = part.strip()
        if not part.isdigit() or not 1 <= int(part) <= MAX_STATIONS:
            raise ValidationError(
                f"--stations: {part!r} is not a station number 1..{MAX_STATIONS} (e.g. --stations 1,2)"
            )
        out.append(int(part))
    if len(set(out)) != len(out):
        raise ValidationError(f"--stations {text!r} repeats a station")
    return tuple(out)


def run_record(args: argparse.Namespace) -> int:
    """Handler of ``palpate record liberty``; returns the exit code (130 after Ctrl-C, recording kept)."""
    from palpate.core.io.mcap_writer import RecordingWriter
    from palpate.hardware import exit_signals
    from palpate.hardware.polhemus.driver import LibertyDriver
    from palpate.hardware.polhemus.emulator import Faults, LibertyEmulator, press_motion
    from palpate.hardware.polhemus.transport import SerialTransport

    check_output_file(args.out, force=args.force)

    stations = parse_stations(args.stations)
    if not args.seconds > 0:
        raise ValidationError(f"--seconds must be > 0, got {args.seconds}")
    if not args.emulate and not args.port:
        raise ValidationError("palpate record liberty needs --port PORT (or --emulate to record from an emulator)")
    emulator = None
    if args.emulate:
        emulator = LibertyEmulator(rate=args.emulate_rate, stations=stations, noise=1e-4, seed=0,
                                   motion=press_motion(), baud=args.baud,
                                   faults=Faults(silent_after=args.emulate_silent_after))
    port = emulator.port if emulator else args.port
    interrupted: BaseException | None = None
    written = 0
    span: dict[str, list[float]] = {}  # sensor id -> [first t, last t] on the pose clock
    try:
        with exit_signals.holding(), SerialTransport(port, args.baud, timeout=0.02) as transport:
            driver = LibertyDriver(transport, stations=stations, units=args.units, binary=not args.ascii,
                                   timeout=args.timeout)
            driver.configure()
            metadata = {
                "sources": {
                    "pose": {
                        "device": "polhemus-liberty",
                        "port": "emulator" if emulator else port,
                        "baud": args.baud,
                        "stations": list(stations),
                        "units_on_wire": args.units,
                        "format": "ascii" if args.ascii else "binary",
                        "output_list": list(DEFAULT_ITEMS),
                        "time_base": driver.time_base,
                        "emulated": bool(emulator),
                    }
                },
                "scenario": None,
            }
            with RecordingWriter(args.out, metadata) as writer:
                t_last = 0.0

                def keep(pose) -> None:
                    nonlocal t_last, written
                    writer.write_pose(pose)
                    span.setdefault(pose.sensor_id, [pose.t, pose.t])[1] = pose.t
                    t_last = pose.t
                    written += 1

                try:
                    for pose in driver.stream(seconds=args.seconds):
                        keep(pose)
                except (KeyboardInterrupt, exit_signals.Terminated) as exc:
                    interrupted = exc
                    driver.stats.stop_reason = "interrupted" if isinstance(exc, KeyboardInterrupt) else str(exc)
                for pose in driver.stop():
                    keep(pose)
                stats = driver.stats
                writer.write_annotation(t_last, "liberty_stream_end", {
                    "records": {str(k): v for k, v in stats.records.items()},
                    "errors": stats.error_counts(),
                    "rejected": dict(stats.rejected),
                    "stop_reason": stats.stop_reason,
                })
    finally:
        if emulator is not None:
            emulator.close()
    _print_summary(driver.stats, args.out, written, span)
    if interrupted is not None:
        print(f"palpate: {driver.stats.stop_reason}; the recording keeps everything received", file=sys.stderr)
        return 130 if isinstance(interrupted, KeyboardInterrupt) else interrupted.code
    if written == 0:
        raise DeviceError(f"the Liberty on {port} sent no pose records ({driver.stats.stop_reason}); "
                          f"{args.out} holds metadata only")
    reason = driver.stats.stop_reason
    if reason == "silent" or reason.startswith("link lost"):
        what = (f"went silent (nothing for {args.timeout:g} s)" if reason == "silent" else f"was lost ({reason})")
        print(f"palpate: error: the Liberty on {port} {what} after {written} poses, before the {args.seconds:g} s "
              f"asked; {args.out} is finished and keeps everything received", file=sys.stderr)
        return 1
    return 0


def _print_summary(stats, out: str, written: int, span: dict[str, list[float]]) -> None:
    elapsed = max((stats.ended or time.monotonic()) - stats.started, 1e-9)
    parts = []
    for station, n in sorted(stats.records.items()):
        t0, t1 = span.get(station_sensor_id(station), (0.0, 0.0))
        # The rate on the pose clock: the host's elapsed time also counts configuring and stopping.
        rate = f"{(n - 1) / (t1 - t0):.1f} Hz" if n > 1 and t1 > t0 else "rate n/a"
        parts.append(f"station {station}: {n} at {rate}")
    errors = stats.error_counts()
    error_text = ", ".join(f"{k} {v}" for k, v in sorted(errors.items())) if errors else "none"
    rejected = ", ".join(f"{k} {v}" for k, v in sorted(stats.rejected.items())) if stats.rejected else "none"
    print(f"liberty: {written} records in {elapsed:.2f} s of host time ({'; '.join(parts)})")
    print(f"errors: {error_text}; rejected as implausible: {rejected}; stopped: {stats.stop_reason}; wrote {out}")
