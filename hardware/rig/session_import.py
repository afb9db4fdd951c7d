"""``palpate import session``: a tactile pad's recording and a tracker's recording of the same presses, made apart
(two programs, two computers, two clocks), merged into one recording that ``palpate replay`` maps.

Steps (each printed):

1. the pad's frames: a Tekscan ASCII/CSV export (times ``--start-time`` + frame number x period) or an MCAP
   recording with one taxel topic (``palpate import tekscan`` output, or a bridge's);
2. the poses: an MCAP recording with a pose topic (``palpate record liberty``; ``--station`` picks one);
3. the clock map pose -> pad: given (``--clock-offset`` s, ``--clock-drift-ppm``; checked against the presses),
   or estimated from the presses themselves with its uncertainty (:mod:`palpate.core.alignment.clock`); refused,
   with the reason, when the streams do not overlap, the estimate is ambiguous or a given map does not pair the
   presses;
4. the workspace: the tracker frame placed on the grid from three touches (``--calibration TOUCHES.mcap``, see
   :mod:`palpate.core.alignment.calibration`) or a transform file (``--workspace T.json``); without either, positions
   stay in the tracker's frame;
5. one MCAP: the frames as they were, the poses on the pad's clock and in the grid frame, and the metadata
   ``session`` (clock map, transform, how to perceive: press axis from each press's motion) beside both sources.
"""

from __future__ import annotations

import argparse
import heapq
import json
import math
import os
from dataclasses import dataclass
from pathlib import Path

from palpate.core.alignment.calibration import (
    IDENTITY,
    WorkspaceTransform,
    read_transform,
    touches_from_poses,
    transform_from_touches,
)
from palpate.core.alignment.clock import ClockMap, check_clock_map, estimate_clock_map
from palpate.core.alignment.merge import merge_session
from palpate.core.errors import ValidationError
from palpate.core.files import write_text
from palpate.core.io.mcap_reader import read_recording
from palpate.core.io.mcap_writer import RecordingWriter
from palpate.core.perception.streams import PoseSample, TaxelFrame
from palpate.core.session.output_guard import check_output_file
from palpate.hardware.tekscan.importer import file_sha256, parse_start_time
from palpate.hardware.tekscan.reader import movie_frames, read_tekscan, select_region

MCAP_MAGIC = b"\x89MCAP"


@dataclass(frozen=True)
class SessionSummary:
    """What an import wrote: the file, stream sizes, the clock map and the transform used."""

    out: Path
    frames: int
    poses: int
    dropped_poses: int
    clock: ClockMap
    transform: WorkspaceTransform

    def text(self) -> str:
        """Lines for people."""
        where = ("tracker frame (no calibration)" if self.transform.source == "identity"
                 else f"grid frame from {self.transform.source}")
        return (f"{self.clock.text()}\n"
                f"poses in the {where}\n"
                f"wrote {self.out}: {self.frames} taxel frames, {self.poses} poses on the taxel clock "
                f"({self.dropped_poses} outside the taxel span dropped)")


def read_taxels(path, *, region: str | None = None, start_time: float = 0.0, sensor_id: str | None = None,
                full_scale_pa: float | None = None) -> tuple[list[TaxelFrame], dict]:
    """The pad's frames from a Tekscan export or an MCAP recording, and a source description for the metadata."""
    path = Path(path)
    if _is_mcap(path):
        rec = read_recording(path)
        ids = sorted({f.sensor_id for f in rec.frames})
        if sensor_id is None and len(ids) > 1:
            raise ValidationError(f"{path}: several taxel pads {ids}; choose one with --taxel-sensor")
        wanted = sensor_id or (ids[0] if ids else None)
        frames = [f for f in rec.frames if f.sensor_id == wanted]
        if not frames:
            raise ValidationError(f"{path}: no taxel frames{f' of {wanted!r}' if wanted else ''} (topics /taxels/...)")
        return frames, {"kind": "mcap", "file": path.name, "sensor_id": wanted, "sources": rec.metadata.get("sources")}
    movie = read_tekscan(path, full_scale_pa=full_scale_pa)
    if region is not None:
        movie = select_region(movie, region)
    sid = sensor_id or "tekscan"
    return movie_frames(movie, start_time=start_time, sensor_id=sid), {
        "kind": "tekscan_ascii", "file": path.name, "sha256": file_sha256(path), "sensor_id": sid,
        "region": list(movie.region), "start_time": start_time, "seconds_per_frame": movie.seconds_per_frame,
        "noise_threshold_counts": movie.noise_threshold}


def read_poses(path, *, station: str | None = None) -> tuple[list[PoseSample], dict]:
    """One pose sensor's samples from an MCAP recording (``station``: a sensor id or a Liberty station number)."""
    path = Path(path)
    rec = read_recording(path)
    ids = sorted({p.sensor_id for p in rec.poses})
    if station is not None and station.isdigit():
        station = f"liberty_station{int(station)}"
    if station is None and len(ids) > 1:
        raise ValidationError(f"{path}: several pose sensors {ids}; choose one with --station")
    wanted = station or (ids[0] if ids else None)
    poses = [p for p in rec.poses if p.sensor_id == wanted]
    if len(poses) < 2:
        raise ValidationError(f"{path}: {len(poses)} pose sample(s){f' of {wanted!r}' if wanted else ''}; a session "
                              f"needs the fingertip's poses (sensors in the file: {ids or 'none'})")
    return poses, {"kind": "poses", "file": path.name, "sensor_id": wanted, "sources": rec.metadata.get("sources")}


def workspace_of(calibration=None, workspace=None, station: str | None = None) -> WorkspaceTransform:
    """The transform from a touch recording, from a transform file, or the identity."""
    if calibration is not None and workspace is not None:
        raise ValidationError("give --calibration (touches) or --workspace (a transform file), not both")
    if workspace is not None:
        return read_transform(workspace)
    if calibration is not None:
        poses, _ = read_poses(calibration, station=station)
        return transform_from_touches(*touches_from_poses(poses, str(calibration)), source=Path(calibration).name)
    return IDENTITY


def import_session(taxels, poses, out, *, region: str | None = None, start_time: float = 0.0,
                   full_scale_pa: float | None = None, taxel_sensor: str | None = None, station: str | None = None,
                   clock: ClockMap | None = None, max_offset: float | None = None, calibration=None,
                   workspace=None) -> SessionSummary:
    """Merge a pad recording and a pose recording into one session recording (see the module docstring).

    Args:
        taxels: Tekscan export or MCAP with taxel frames.
        poses: MCAP with the fingertip's poses.
        out: the session .mcap (written as ``out.partial`` and renamed when complete).
        region, start_time, full_scale_pa: as for ``palpate import tekscan`` (exports only).
        taxel_sensor, station: which pad / pose sensor when a file holds several.
        clock: a given clock map (None: estimate it).
        max_offset: bound of the estimate's search, s.
        calibration, workspace: touch recording, or transform JSON (at most one).
    """
    out = Path(out)
    for src in (taxels, poses, calibration, workspace):
        if src is not None and out.exists() and out.resolve() == Path(src).resolve():
            raise ValidationError(f"--out {out} is one of the inputs; write the session elsewhere")
    frames, taxel_source = read_taxels(taxels, region=region, start_time=start_time, sensor_id=taxel_sensor,
                                       full_scale_pa=full_scale_pa)
    samples, pose_source = read_poses(poses, station=station)
    transform = workspace_of(calibration, workspace, station)
    try:  # the streams of the two files disagree: name both
        if clock is not None:
            check_clock_map(frames, samples, clock)
        cmap = clock if clock is not None else estimate_clock_map(frames, samples, max_offset=max_offset)
        merged = merge_session(frames, samples, cmap, transform, sensor_id="fingertip")
    except ValidationError as exc:
        raise ValidationError(f"--taxels {taxels} with --poses {poses}: {exc}") from None
    metadata = {"scenario": None, "sources": [taxel_source, pose_source], "session": merged.metadata()}
    partial = out.with_name(out.name + ".partial")
    try:
        with RecordingWriter(partial, metadata) as w:
            stream = heapq.merge(((f.t, 0, i) for i, f in enumerate(merged.frames)),
                                 ((p.t, 1, i) for i, p in enumerate(merged.poses)))
            for _, kind, i in stream:
                if kind == 0:
                    w.write_taxel(merged.frames[i])
                else:
                    w.write_pose(merged.poses[i])
        os.replace(partial, out)
    except BaseException:
        partial.unlink(missing_ok=True)
        raise
    return SessionSummary(out, len(merged.frames), len(merged.poses), merged.dropped_poses, cmap, transform)


def _is_mcap(path: Path) -> bool:
    try:
        with open(path, "rb") as f:
            return f.read(len(MCAP_MAGIC)) == MCAP_MAGIC
    except OSError as exc:
        raise ValidationError(f"{path}: cannot read: {exc.strerror}") from None


def add_import_command(imports: argparse._SubParsersAction) -> None:
    """Add ``palpate import session`` to the ``import`` group."""
    from palpate.hardware.tekscan.importer import _pressure_pa

    p = imports.add_parser(
        "session", help="merge a tactile pad's recording and a tracker's recording of the same presses",
        description="Merge a Tekscan export (or a taxel MCAP) and a pose MCAP (palpate record liberty) recorded "
                    "apart into one session recording on the pad's clock and in the workspace grid's frame. The "
                    "clock offset and drift are estimated from the presses (printed with their uncertainty) "
                    "unless given; see docs/real_rig.md.")
    p.add_argument("--taxels", required=True, type=Path, help="Tekscan ASCII/CSV export, or an MCAP with taxel frames")
    p.add_argument("--poses", required=True, type=Path, help="MCAP with the fingertip's poses (palpate record liberty)")
    p.add_argument("--out", required=True, type=Path, help="the session recording to write (.mcap)")
    p.add_argument("--force", action="store_true", help="overwrite an existing --out (never an input)")
    p.add_argument("--region", help="R0:R1,C0:C1: the fingertip pad's block of a larger Tekscan map")
    p.add_argument("--start-time", help="ISO 8601 time of the export's first frame (default 0 s)")
    p.add_argument("--full-scale", type=_pressure_pa, metavar="PRESSURE",
                   help="saturation pressure of a pressure export without SATURATION_PRESSURE, e.g. '862 kPa'")
    p.add_argument("--taxel-sensor", help="which pad, when the taxel MCAP holds several")
    p.add_argument("--station", help="which pose sensor: a Liberty station number or a sensor id")
    p.add_argument("--clock-offset", type=float, metavar="S",
                   help="seconds to add to pose times to put them on the pad's clock (default: estimated)")
    p.add_argument("--clock-drift-ppm", type=float, default=0.0, metavar="PPM",
                   help="with --clock-offset: how much faster the pose clock runs, ppm (default 0)")
    p.add_argument("--max-offset", type=float, metavar="S",
                   help="estimate the offset within +-S only (for presses at a steady rhythm)")
    cal = p.add_mutually_exclusive_group()
    cal.add_argument("--calibration", type=Path, metavar="TOUCHES.mcap",
                     help="poses of three touches (origin, +x, +y side) placing the tracker frame on the grid")
    cal.add_argument("--workspace", type=Path, metavar="T.json",
                     help="the transform tracker -> grid: {\"rotation\": 3x3, \"translation_m\": [x, y, z]}")
    p.add_argument("--save-workspace", type=Path, metavar="T.json",
                   help="also write the transform used to this file (to reuse with --workspace)")
    p.set_defaults(func=_run)


def _run(args: argparse.Namespace) -> int:
    for option, value in (("--max-offset", args.max_offset), ("--clock-offset", args.clock_offset),
                          ("--clock-drift-ppm", args.clock_drift_ppm)):
        if value is not None and not math.isfinite(value):
            raise ValidationError(f"{option} must be a finite number, got {value}")
    if args.max_offset is not None and not args.max_offset > 0:
        raise ValidationError(f"--max-offset must be > 0 s (the estimate searches offsets within +-S), got "
                              f"{args.max_offset:g}")
    check_output_file(args.out, inputs=[args.taxels, args.poses, args.calibration, args.workspace],
                      force=args.force)
    if args.save_workspace is not None:
        check_output_file(args.save_workspace, inputs=[args.taxels, args.poses, args.calibration, args.workspace,
                                                       args.out], force=args.force, option="--save-workspace")
    clock = None
    if args.clock_offset is not None:
        clock = ClockMap(offset=args.clock_offset, rate=-args.clock_drift_ppm * 1e-6)
    elif args.clock_drift_ppm:
        raise ValidationError("--clock-drift-ppm goes with --clock-offset (an estimated map has its own drift)")
    summary = import_session(args.taxels, args.poses, args.out, region=args.region,
                             start_time=parse_start_time(args.start_time), full_scale_pa=args.full_scale,
                             taxel_sensor=args.taxel_sensor, station=args.station, clock=clock,
                             max_offset=args.max_offset, calibration=args.calibration, workspace=args.workspace)
    if args.save_workspace is not None:
        write_text(args.save_workspace, json.dumps(summary.transform.to_dict(), indent=2) + "\n")
    print(summary.text())
    return 0
