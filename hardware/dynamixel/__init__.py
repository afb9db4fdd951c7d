"""Dynamixel (Protocol 2.0) robotic finger through dynamixel-sdk, and a pty servo emulator."""

from __future__ import annotations

import argparse

# How long a scan of an emulated bus waits for each answer, ms (its thread shares this process's interpreter).
EMULATED_TIMEOUT_MS = 500.0


def _subparsers(parser: argparse.ArgumentParser, dest: str) -> argparse._SubParsersAction:
    # another device may have created the same sub-command ("devices scan"): share it instead of clashing
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return action
    sub = parser.add_subparsers(dest=dest, metavar="KIND")
    parser.set_defaults(func=lambda a, p=parser: p.print_help() or 2)
    return sub


def _ids(text: str) -> list[int]:
    try:
        ids = [int(s) for s in text.split(",") if s.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated servo ids, got {text!r}") from None
    if not ids or not all(0 <= i <= 252 for i in ids):
        raise argparse.ArgumentTypeError(f"servo ids must be in 0..252, got {text!r}")
    return ids


def register_cli(groups: dict) -> None:
    """Add ``devices scan dynamixel`` and ``record dynamixel`` to the hardware command groups."""
    devices = groups["devices"]
    scan_parser = devices.choices.get("scan") or devices.add_parser("scan", help="list the devices on a port")
    scan_kinds = _subparsers(scan_parser, "scan_kind")
    p = scan_kinds.add_parser("dynamixel", help="ping Dynamixel ids 0..N (Protocol 2.0) and list what answers")
    p.add_argument("--port", help="serial port (e.g. /dev/ttyUSB0); not needed with --emulate")
    p.add_argument("--baud", type=int, default=1_000_000, help="bus bit rate (default 1000000)")
    p.add_argument("--max-id", type=int, default=20, help="highest id to ping (default 20; up to 252)")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    p.add_argument("--emulate", type=_ids, metavar="IDS", help="scan an emulated bus with these ids (e.g. 1,2,3)")
    p.set_defaults(func=_cmd_scan)

    r = groups["record"].add_parser("dynamixel", help="record a Dynamixel finger's joint states and fingertip poses")
    r.add_argument("--port", help="serial port; not needed with --emulate")
    r.add_argument("--baud", type=int, default=1_000_000, help="bus bit rate (default 1000000)")
    r.add_argument("--finger", required=True, help="finger description TOML (models/fingers/*.toml)")
    r.add_argument("--seconds", type=float, required=True, help="how long to record, s")
    r.add_argument("--out", required=True, help="output recording (.mcap)")
    r.add_argument("--force", action="store_true", help="overwrite an existing --out (never the finger file)")
    r.add_argument("--rate", type=float, default=100.0, help="sample rate while idle, Hz (default 100)")
    r.add_argument("--press", type=float, metavar="X", help="also press and release at x = X m (torque on)")
    r.add_argument("--surface-z", type=float, default=0.03, help="height of the surface pressed, m (default 0.03)")
    r.add_argument("--depth", type=float, default=0.003, help="press depth below the surface, m (default 0.003)")
    r.add_argument("--speed", type=float, default=0.02, help="press speed, m/s (default 0.02)")
    r.add_argument("--emulate", action="store_true",
                   help="start a servo emulator for the finger's ids, with an elastic surface at --surface-z")
    r.add_argument("--retries", type=int, default=3,
                   help="times a missing or corrupt answer is asked again before a servo counts as lost (default 3)")
    r.add_argument("--answer-timeout-ms", type=float, metavar="MS",
                   help="how long to wait for a servo's answer (default: dynamixel-sdk's, ~34 ms at 1 Mbaud); longer "
                        "for a slow USB adapter")
    r.set_defaults(func=_cmd_record)


def _need_port(args) -> None:
    from palpate.core.errors import ValidationError

    if not args.port and not args.emulate:
        raise ValidationError("--port is required (or --emulate to use the servo emulator)")


def _cmd_scan(args) -> int:
    import contextlib
    import json

    from palpate.core.errors import ValidationError
    from palpate.hardware.dynamixel.emulator import ServoBusEmulator
    from palpate.hardware.dynamixel.scan import scan

    _need_port(args)
    if not 0 <= args.max_id <= 252:
        raise ValidationError(f"--max-id must be in 0..252, got {args.max_id}")
    with contextlib.ExitStack() as stack:
        port = args.port
        if args.emulate:
            port = stack.enter_context(ServoBusEmulator(args.emulate, baud=args.baud)).port
        found = scan(port, args.baud, range(0, args.max_id + 1), timeout_ms=EMULATED_TIMEOUT_MS if args.emulate
                     else None)
    if args.json:
        print(json.dumps({"port": port, "baud": args.baud, "servos": found}, indent=2))
    else:
        print(f"{len(found)} servo(s) on {port} at {args.baud} baud")
        if found:
            print(f"{'id':>4}  {'model':>6}  name")
            for s in found:
                print(f"{s['id']:>4}  {s['model_number']:>6}  {s['model']}")
    return 0 if found else 1


def _cmd_record(args) -> int:
    import contextlib

    from palpate.core.errors import ValidationError
    from palpate.core.io.mcap_writer import RecordingWriter
    from palpate.core.session.output_guard import check_output_file
    from palpate.core.session.sources import PressTarget
    from palpate.hardware import exit_signals
    from palpate.hardware.clock import WALL_CLOCK, StepClock
    from palpate.hardware.dynamixel.driver import DynamixelFinger
    from palpate.hardware.dynamixel.emulator import ServoBusEmulator
    from palpate.hardware.dynamixel.finger import inverse_kinematics, joints_to_ticks, load_finger, surface_load_model
    from palpate.hardware.dynamixel.press import plan_press

    check_output_file(args.out, inputs=[args.finger], force=args.force)

    _need_port(args)
    if not args.seconds > 0:
        raise ValidationError(f"--seconds must be > 0, got {args.seconds}")
    if not args.rate > 0:
        raise ValidationError(f"--rate must be > 0 Hz, got {args.rate}")
    finger = load_finger(args.finger)
    target = None
    if args.press is not None:
        target = PressTarget(args.press, float(finger.base[1]), depth=args.depth, speed=args.speed, label="cli")
        plan_press(finger, target, args.surface_z)  # refuse an impossible press before touching the port
    # an emulated bus runs on a stepped clock that keeps pace with the wall: the recording's times are the servos'
    # own, however busy the machine (see palpate.hardware.clock)
    clock = StepClock(wall_ratio=1.0) if args.emulate else WALL_CLOCK
    with exit_signals.holding(), contextlib.ExitStack() as stack:
        port = args.port
        if args.emulate:
            x0 = args.press if args.press is not None else float(finger.base[0] + 0.5 * finger.lengths.sum())
            q0 = inverse_kinematics(finger, x0, args.surface_z + finger.approach_height)
            # an elastic surface (about 2 N at 3 mm, Hertz-like) so that a press loads the joints
            load = surface_load_model(finger, args.surface_z, 2.0 / 0.003**1.5)
            emu = stack.enter_context(ServoBusEmulator(finger.ids, finger.model.number, args.baud, load,
                                                       joints_to_ticks(finger, q0), clock=clock))
            port = emu.port
        metadata = {"scenario": None,
                    "sources": {"dynamixel": {"port": port, "baud": args.baud, "finger": finger.name,
                                              "finger_file": args.finger, "emulated": bool(args.emulate)}}}
        writer = stack.enter_context(RecordingWriter(args.out, metadata))
        driver = stack.enter_context(DynamixelFinger(
            port, args.baud, finger, clock=clock, retries=args.retries,
            answer_timeout=None if args.answer_timeout_ms is None else args.answer_timeout_ms / 1000.0))
        t_start = clock()
        count = 0
        stop_reason = "duration"

        def write(state, pose) -> None:
            nonlocal count
            with exit_signals.deferring():  # a sample and its count go together
                writer.write_joint_state(state.t - t_start, finger.names, state.position, state.velocity,
                                         state.current)
                writer.write_pose(type(pose)(pose.t - t_start, pose.position, pose.quaternion, pose.sensor_id))
                count += 1

        try:
            if target is not None:
                writer.write_annotation(clock() - t_start, "press_start",
                                        {"x": target.x, "depth": target.depth, "surface_z": args.surface_z})
                result = driver.press(target, args.surface_z, on_state=write)
                writer.write_annotation(clock() - t_start, "press_end", {
                    "stopped_by": result.stopped_by, "depth": result.depth, "force": result.force})
            period = 1.0 / args.rate
            with driver.safety():
                while clock() - t_start < args.seconds:
                    state = driver.read_state()
                    write(state, driver.pose(state))
                    clock.sleep(max(0.0, period - (clock() - state.t)))
        except BaseException as exc:
            # torque is already off (the driver's safety context); the recording says why it ended, then closes
            stop_reason = "interrupted" if isinstance(exc, KeyboardInterrupt) else str(exc) or type(exc).__name__
            raise
        finally:
            writer.write_annotation(clock() - t_start, "recording_end",
                                    {"stop_reason": stop_reason, "samples": count})
    print(f"recorded {count} joint states and fingertip poses to {args.out}")
    return 0
