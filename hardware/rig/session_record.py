"""``palpate record session``: a tactile array and a Liberty recorded live into one file, on one host clock.

Both devices keep their own clocks (the array its frame counter, the Liberty its ms timer); each sample is put on
the host's monotonic clock through its device time and the least-delayed arrival seen
(:class:`~palpate.hardware.clock.DeviceTimeMap`), so USB latency and a busy host do not shift it, and the two
streams need no clock estimate afterwards. Times in the file count from the start of the recording (metadata
``session.t0_unix`` gives that instant as Unix time). The file asks to be perceived with the press axis taken from
each press's motion, and replays with ``palpate replay``; an ``operator`` run takes its presses from it.

Ctrl-C, SIGTERM and SIGHUP end the recording early with a finished file; a device that goes silent ends it with
exit code 1 and a finished file.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
import time
from pathlib import Path

from palpate.core.alignment.merge import SESSION_PIPELINE
from palpate.core.errors import ValidationError
from palpate.core.io.mcap_writer import RecordingWriter
from palpate.core.perception.streams import PoseSample, TaxelFrame
from palpate.core.session.output_guard import check_output_file
from palpate.hardware import exit_signals
from palpate.hardware.clock import DeviceTimeMap
from palpate.hardware.polhemus.cli import parse_stations
from palpate.hardware.polhemus.driver import LibertyDriver
from palpate.hardware.polhemus.emulator import LibertyEmulator, press_motion
from palpate.hardware.polhemus.transport import SerialTransport
from palpate.hardware.tactile.emulator import TactileArrayEmulator, press_counts
from palpate.hardware.tactile.protocol import FORMATS
from palpate.hardware.tactile.reader import TactileArrayReader


def add_record_command(record: argparse._SubParsersAction) -> None:
    """Add ``palpate record session`` to the ``record`` group."""
    p = record.add_parser(
        "session", help="record a live tactile array and a Liberty into one file on one host clock",
        description="Record a tactile array (serial, binary frames or CSV lines, docs/tactile_array.md) and a "
                    "Polhemus Liberty live into one MCAP recording on one host clock. Ctrl-C, SIGTERM or SIGHUP "
                    "stop early and keep everything recorded; a device going silent stops it with exit code 1.")
    p.add_argument("--taxels", help="serial port of the tactile array")
    p.add_argument("--liberty", help="serial port of the Liberty")
    p.add_argument("--seconds", type=float, required=True, help="how long to record, s")
    p.add_argument("--out", type=Path, required=True, help="the recording to write (.mcap)")
    p.add_argument("--force", action="store_true", help="overwrite an existing --out")
    p.add_argument("--taxel-format", choices=FORMATS, default="binary", help="the array's wire format")
    p.add_argument("--taxel-rate", type=float, default=50.0, help="the array's frame rate, Hz (default 50)")
    p.add_argument("--taxel-baud", type=int, default=115200, help="the array's bit rate (default 115200)")
    p.add_argument("--rows", type=int, default=4, help="the array's rows (default 4)")
    p.add_argument("--cols", type=int, default=4, help="the array's columns (default 4)")
    p.add_argument("--sensel-area-mm2", type=float, default=4.84, help="area of one sensel, mm^2 (default 4.84)")
    p.add_argument("--liberty-baud", type=int, default=115200, help="the Liberty's bit rate (default 115200)")
    p.add_argument("--station", default="1", help="the Liberty station on the fingertip (default 1)")
    p.add_argument("--timeout", type=float, default=1.0, help="how long a silent device is tolerated, s")
    p.add_argument("--emulate", action="store_true",
                   help="record from emulators of both devices (a fingertip pressing a block every 2 s)")
    p.set_defaults(func=run_record)


def run_record(args: argparse.Namespace) -> int:
    """Handler of ``palpate record session``; returns the exit code."""
    if not args.seconds > 0:
        raise ValidationError(f"--seconds must be > 0, got {args.seconds}")
    if not args.emulate and not (args.taxels and args.liberty):
        raise ValidationError("palpate record session needs --taxels PORT and --liberty PORT (or --emulate)")
    if not args.sensel_area_mm2 > 0:
        raise ValidationError(f"--sensel-area-mm2 must be > 0, got {args.sensel_area_mm2}")
    (station,) = parse_stations(args.station)
    check_output_file(args.out, force=args.force)
    with exit_signals.holding(), contextlib.ExitStack() as stack:
        taxel_port, liberty_port = args.taxels, args.liberty
        if args.emulate:
            motion = press_motion()
            lib = stack.enter_context(LibertyEmulator(stations=(station,), noise=1e-4, motion=motion,
                                                      baud=args.liberty_baud))
            arr = stack.enter_context(TactileArrayEmulator(
                press_counts(motion, station=station, rows=args.rows, cols=args.cols), rows=args.rows,
                cols=args.cols, rate=args.taxel_rate, fmt=args.taxel_format, baud=args.taxel_baud, epoch=lib.epoch))
            taxel_port, liberty_port = arr.port, lib.port
        reader = stack.enter_context(TactileArrayReader(
            taxel_port, rows=args.rows, cols=args.cols, sensel_area=args.sensel_area_mm2 * 1e-6, fmt=args.taxel_format,
            baud=args.taxel_baud, rate=args.taxel_rate, timeout=args.timeout, sensor_id="taxels"))
        transport = stack.enter_context(SerialTransport(liberty_port, args.liberty_baud, timeout=0.02))
        driver = LibertyDriver(transport, stations=(station,), timeout=args.timeout)
        driver.configure()
        driver.host_time_map = DeviceTimeMap()
        t0, t0_unix = time.monotonic(), time.time()
        metadata = {
            "scenario": None,
            "sources": {
                "taxels": {"device": "tactile-array", "port": "emulator" if args.emulate else taxel_port,
                           "format": args.taxel_format, "rate_hz": args.taxel_rate, "rows": args.rows,
                           "cols": args.cols, "sensel_area_m2": args.sensel_area_mm2 * 1e-6},
                "pose": {"device": "polhemus-liberty", "port": "emulator" if args.emulate else liberty_port,
                         "station": station, "baud": args.liberty_baud},
                "emulated": bool(args.emulate),
            },
            "session": {"clock": "host monotonic clock, s from the start of the recording", "t0_unix": t0_unix,
                        "perception": dict(SESSION_PIPELINE)},
        }
        code, reason, counts = _record(args, reader, driver, metadata, t0)
    _report(args, code, reason, counts, reader, driver)
    return code


def _record(args, reader: TactileArrayReader, driver: LibertyDriver, metadata: dict, t0: float):
    counts = {"frames": 0, "poses": 0}
    code, reason = 0, "duration"
    with RecordingWriter(args.out, metadata) as writer:
        def frames() -> None:
            for f in reader.drain():
                if f.t >= t0:
                    writer.write_taxel(TaxelFrame(f.t - t0, f.counts, f.sensel_area, f.sensor_id))
                    counts["frames"] += 1

        def pose(p: PoseSample) -> None:
            if p.t >= t0:
                writer.write_pose(PoseSample(p.t - t0, p.position, p.quaternion, "fingertip"))
                counts["poses"] += 1

        try:
            for p in driver.stream(seconds=args.seconds):
                pose(p)
                if counts["poses"] % 20 == 0:
                    frames()
                if reader.stats.silent:
                    code, reason = 1, f"the tactile array went silent ({reader.stats.error or 'no frame'})"
                    break
        except (KeyboardInterrupt, exit_signals.Terminated) as exc:
            code = 130 if isinstance(exc, KeyboardInterrupt) else exc.code
            reason = "interrupted" if isinstance(exc, KeyboardInterrupt) else str(exc)
        finally:
            for p in driver.stop():
                pose(p)
            time.sleep(min(0.1, args.timeout))  # the array's last frames
            frames()
            stop = driver.stats.stop_reason
            if code == 0 and (stop == "silent" or stop.startswith("link lost")):
                code, reason = 1, f"the Liberty went silent ({stop})"
            writer.write_annotation(max(time.monotonic() - t0, 0.0), "session_end", {
                "stop_reason": reason, "frames": counts["frames"], "poses": counts["poses"],
                "taxels": reader.stats.to_dict(),
                "liberty": {"errors": driver.stats.error_counts(), "rejected": dict(driver.stats.rejected),
                            "stop_reason": stop}})
    return code, reason, counts


def _report(args, code: int, reason: str, counts: dict, reader, driver) -> None:
    s = reader.stats
    print(f"wrote {args.out}: {counts['frames']} taxel frames ({s.lost} lost, {s.corrupt} corrupt), "
          f"{counts['poses']} poses ({sum(driver.stats.rejected.values())} implausible records dropped); "
          f"stopped: {reason}")
    if code == 1:
        print(f"palpate: error: {reason}; {args.out} is finished and keeps everything received", file=sys.stderr)
    elif code:
        print(f"palpate: {reason}; the recording keeps everything received", file=sys.stderr)
