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
import json
import math
import os
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from palpate.core.alignment.calibration import (
    IDENTITY,
    WorkspaceTransform,
    read_transform,
    touches_from_poses,
    transform_from_touches,
)
from palpate.core.alignment.clock import ClockMap, estimate_clock_map_arrays
from palpate.core.alignment.clock_check import check_clock_map_arrays
from palpate.core.alignment.merge import map_poses, session_metadata
from palpate.core.errors import ValidationError
from palpate.core.files import write_text
from palpate.core.io.mcap_reader import read_recording
from palpate.core.io.mcap_writer import RecordingWriter
from palpate.core.perception.streams import PoseSample, TaxelFrame, frames_to_arrays, poses_to_arrays
from palpate.core.session.output_guard import check_output_file
from palpate.hardware.tekscan.importer import file_sha256, parse_start_time, region_blocks, region_of
from palpate.hardware.tekscan.stream import open_export

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


@dataclass(frozen=True)
class TaxelStream:
    """One pad's frames as the import needs them: the times and c_P of every frame at once (16 bytes a frame, what
    the clock estimate works on) and the frames themselves again on demand, so a Tekscan export of any length is
    read twice in bounded memory instead of held whole.

    Attributes:
        t: frame times, s (taxel clock).
        c_p: each frame's sum of counts.
        source: the description written to the session's metadata.
        frames: a fresh iterator over the frames, in time order, at each call.
    """

    t: np.ndarray
    c_p: np.ndarray
    source: dict
    frames: Callable[[], Iterator[TaxelFrame]]


def read_taxels(path, *, region: str | None = None, start_time: float = 0.0, sensor_id: str | None = None,
                full_scale_pa: float | None = None) -> TaxelStream:
    """The pad's frames from a Tekscan export (streamed) or an MCAP recording, and a source description for the
    metadata."""
    path = Path(path)
    if _is_mcap(path):
        rec = read_recording(path)
        ids = sorted({f.sensor_id for f in rec.frames})
        if sensor_id is None and len(ids) > 1:
            raise ValidationError(f"{path}: several taxel pads {ids}; choose one with --taxel-sensor")
        wanted = sensor_id or (ids[0] if ids else None)
        frames = [f for f in rec.frames if f.sensor_id == wanted]
        if not frames:
            raise ValidationError(f"{path}: no taxel frames{f' of {wanted!r}' if wanted else ''} "
                                  "(topics /palpate/taxels/... or /taxels/...)")
        t, counts, _ = frames_to_arrays(frames)
        return TaxelStream(t, counts.reshape(len(t), -1).sum(axis=1, dtype=np.int64).astype(float),
                           {"kind": "mcap", "file": path.name, "sensor_id": wanted,
                            "sources": rec.metadata.get("sources")}, lambda: iter(frames))
    sid = sensor_id or "tekscan"
    stream = open_export(path, full_scale_pa=full_scale_pa)
    box = region_of(stream, region)
    header = stream.header
    times, c_ps = [], []
    for t, counts, _, _ in region_blocks(stream, box, start_time):
        times.append(t)
        c_ps.append(counts.reshape(len(t), -1).sum(axis=1, dtype=np.int64).astype(float))
    t = np.concatenate(times)
    if np.any(np.diff(t) <= 0):
        raise ValidationError(f"{path.name}: frame times do not increase (check SECONDS_PER_FRAME)")

    def frames() -> Iterator[TaxelFrame]:
        # the second reading: the file was read whole once, so it is the same export unless changed meanwhile
        again = open_export(path, full_scale_pa=full_scale_pa)
        for ts, counts, _, _ in region_blocks(again, box, start_time):
            for ti, c in zip(ts, counts, strict=True):
                yield TaxelFrame(float(ti), c, header.sensel_area, sid)

    return TaxelStream(t, np.concatenate(c_ps), {
        "kind": "tekscan_ascii", "file": path.name, "sha256": file_sha256(path), "sensor_id": sid,
        "region": list(box), "start_time": start_time, "seconds_per_frame": header.seconds_per_frame,
        "noise_threshold_counts": header.noise_counts}, frames)


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
    taxels_in = read_taxels(taxels, region=region, start_time=start_time, sensor_id=taxel_sensor,
                            full_scale_pa=full_scale_pa)
    samples, pose_source = read_poses(poses, station=station)
    transform = workspace_of(calibration, workspace, station)
    t, c_p = taxels_in.t, taxels_in.c_p
    try:  # the streams of the two files disagree: name both
        tp, pos, _ = poses_to_arrays(samples)
        if clock is not None:
            check_clock_map_arrays(t, c_p, tp, pos, clock)
        cmap = clock if clock is not None else estimate_clock_map_arrays(t, c_p, tp, pos, max_offset=max_offset)
        kept, dropped = map_poses(float(t[0]), float(t[-1]), samples, cmap, transform, sensor_id="fingertip")
    except ValidationError as exc:
        raise ValidationError(f"--taxels {taxels} with --poses {poses}: {exc}") from None
    del samples
    metadata = {"scenario": None, "sources": [taxels_in.source, pose_source],
                "session": session_metadata(cmap, transform, dropped)}
    partial = out.with_name(out.name + ".partial")
    n_frames = 0
    try:
        with RecordingWriter(partial, metadata) as w:
            k = 0  # poses written; a pose at a frame's time goes after the frame
            for frame in taxels_in.frames():
                while k < len(kept) and kept[k].t < frame.t:
                    w.write_pose(kept[k])
                    k += 1
                w.write_taxel(frame)
                n_frames += 1
            for pose in kept[k:]:
                w.write_pose(pose)
        if n_frames != len(t):
            raise ValidationError(f"--taxels {taxels}: the export changed while it was read ({len(t)} frames, then "
                                  f"{n_frames})")
        os.replace(partial, out)
    except BaseException:
        partial.unlink(missing_ok=True)
        raise
    return SessionSummary(out, n_frames, len(kept), dropped, cmap, transform)


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
