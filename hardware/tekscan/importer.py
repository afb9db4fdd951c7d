"""Tekscan export -> palpate MCAP recording (the ``palpate import tekscan`` command)."""

from __future__ import annotations

import argparse
import hashlib
import os
import warnings
from collections.abc import Iterator
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.io.mcap_writer import RecordingWriter
from palpate.core.perception.streams import TaxelFrame
from palpate.core.session.output_guard import check_output_file
from palpate.hardware.tekscan.body import to_counts
from palpate.hardware.tekscan.header import NUMBER_UNIT, PRESSURE, unit_key
from palpate.hardware.tekscan.reader import TekscanWarning, parse_region
from palpate.hardware.tekscan.stream import MAX_EXPORT_BYTES, ExportStream, open_export


@dataclass(frozen=True)
class ImportSummary:
    """What an import wrote.

    Attributes:
        out: the MCAP file.
        frames: number of taxel frames.
        shape: (rows, cols) of each frame after region selection.
        duration: time from first to last frame, s.
        start_time: time of the first frame, s (Unix epoch if a start time was given, else 0).
        sensel_area: m^2.
        b_cells: cells of the selected region outside the sensor map (``B``).
        peak_c_P: largest sum of counts over a frame.
        peak_active: most sensels above the noise threshold in one frame.
        region: (r0, r1, c0, c1) in the file's map.
    """

    out: Path
    frames: int
    shape: tuple[int, int]
    duration: float
    start_time: float
    sensel_area: float
    b_cells: int
    peak_c_P: int
    peak_active: int
    region: tuple[int, int, int, int]

    def text(self) -> str:
        """A short human-readable summary (areas in mm^2)."""
        r0, r1, c0, c1 = self.region
        rate = f"at {(self.frames - 1) / self.duration:.1f} Hz" if self.duration > 0 else "(one frame)"
        return (f"wrote {self.out}: {self.frames} frames of {self.shape[0]}x{self.shape[1]} sensels "
                f"(region {r0}:{r1},{c0}:{c1}, {self.b_cells} B cells), {self.duration:.3f} s {rate}, "
                f"sensel area {self.sensel_area * 1e6:.3f} mm^2, peak c_P {self.peak_c_P}, "
                f"peak active sensels {self.peak_active}")


def parse_start_time(text: str | None) -> float:
    """ISO 8601 date-time -> Unix time, s. A time without a zone is taken as UTC. None -> 0."""
    if text is None:
        return 0.0
    try:
        when = datetime.fromisoformat(text.strip().replace("Z", "+00:00"))
    except ValueError:
        raise ValidationError(
            f"--start-time {text!r} is not an ISO 8601 date-time (e.g. 2024-05-02T14:30:00Z)") from None
    if when.tzinfo is None:
        when = when.replace(tzinfo=UTC)
    try:
        t = when.timestamp()
    except (OverflowError, ValueError, OSError):
        t = float("inf")
    if t < 0:
        raise ValidationError(f"--start-time {text!r} is before 1970-01-01, which MCAP log times cannot hold")
    if not t < MAX_LOG_TIME:
        raise ValidationError(f"--start-time {text!r} is after {_LAST_DATE}, which MCAP log times (unsigned 64-bit "
                              "ns since 1970) cannot hold")
    return t


#: Latest time a recording can hold, s since 1970 (MCAP log times are unsigned 64-bit nanoseconds).
MAX_LOG_TIME = (2**64 - 1) / 1e9
_LAST_DATE = datetime.fromtimestamp(int(MAX_LOG_TIME), UTC).strftime("%Y-%m-%d")


def import_tekscan(path, out, *, region: str | None = None, start_time: float = 0.0, sensor_id: str = "tekscan",
                   full_scale_pa: float | None = None, max_bytes: int = MAX_EXPORT_BYTES) -> ImportSummary:
    """Convert a Tekscan ASCII/CSV movie export into an MCAP recording with one ``/taxels/<sensor_id>`` topic.

    The export is streamed (memory does not grow with its length) into ``out`` + ``.partial``, which becomes
    ``out`` only when every frame has been read and written: a bad file leaves nothing behind, and ``out`` may not
    be the export itself. The metadata holds the header and the source file's name; the sensor mask (cells never
    ``B``) and the frame number range, known only at the end, are in the last annotation, ``tekscan_import``.

    Args:
        path: the Tekscan export.
        out: the .mcap file to write.
        region: ``R0:R1,C0:C1`` (0-based, half-open) to keep only that block (e.g. the 4x4 fingertip pad).
        start_time: time of the first frame, s (Unix time for absolute stamps; 0 keeps file-relative times).
        sensor_id: topic name of the pad.
        full_scale_pa: saturation pressure, Pa, for pressure exports without SATURATION_PRESSURE.
        max_bytes: largest export read, bytes.

    Raises:
        ValidationError: bad file, region or arguments (the message names the file and line).
    """
    path, out = Path(path), Path(out)
    if not (np.isfinite(start_time) and 0 <= start_time < MAX_LOG_TIME):
        raise ValidationError(f"start_time must be a time in [0, {MAX_LOG_TIME:.4g}) s, got {start_time!r}")
    if out.exists() and path.exists() and out.resolve() == path.resolve():
        raise ValidationError(f"--out {out} is the Tekscan export being imported; write the recording elsewhere")
    stream = open_export(path, full_scale_pa=full_scale_pa, max_bytes=max_bytes)
    h = stream.header
    r0, r1, c0, c1 = region_of(stream, region)
    metadata = {
        "scenario": None,
        "sources": [{"kind": "tekscan_ascii", "file": path.name, "sha256": file_sha256(path), "sensor_id": sensor_id,
                     "region": [r0, r1, c0, c1], "start_time": start_time}],
        "tekscan": {
            "header": {k: v for k, (v, _) in h.entries.items()}, "units": h.units,
            "noise_threshold_counts": h.noise_counts, "seconds_per_frame": h.seconds_per_frame,
            "row_spacing_m": h.row_spacing, "col_spacing_m": h.col_spacing,
        },
    }
    partial = out.with_name(out.name + ".partial")
    stats = _Stats(np.zeros((r1 - r0, c1 - c0), dtype=bool))
    try:
        with RecordingWriter(partial, metadata, chunk_size=64 * 1024) as w:
            for t, counts, is_b, over in region_blocks(stream, (r0, r1, c0, c1), start_time):
                for ti, c in zip(t, counts, strict=True):
                    w.write_taxel(TaxelFrame(float(ti), c, h.sensel_area, sensor_id))
                stats.add(t, counts, is_b, over, h.noise_counts)
            w.write_annotation(stats.t1, "tekscan_import", {
                "frames": stats.frames, "frame_numbers":
                [stream.first_number, stream.last_number], "sensor_mask": (~stats.b_any).astype(int).tolist()})
        os.replace(partial, out)
    except BaseException:
        partial.unlink(missing_ok=True)
        raise
    if stats.clipped:
        warnings.warn(f"{path.name}: {stats.clipped} values above the saturation pressure were clipped to 255 "
                      "counts", TekscanWarning, stacklevel=2)
    return ImportSummary(
        out=out, frames=stats.frames, shape=(r1 - r0, c1 - c0), duration=stats.t1 - stats.t0, start_time=stats.t0,
        sensel_area=h.sensel_area, b_cells=int(stats.b_any.sum()), peak_c_P=stats.peak_c_p,
        peak_active=stats.peak_active, region=(r0, r1, c0, c1))


def region_of(stream: ExportStream, region: str | None) -> tuple[int, int, int, int]:
    """(r0, r1, c0, c1) of ``region`` (``R0:R1,C0:C1``; None: the whole map), checked against the export's map."""
    h = stream.header
    r0, r1, c0, c1 = parse_region(region) if region is not None else (0, h.rows, 0, h.cols)
    if not (0 <= r0 < r1 <= h.rows and 0 <= c0 < c1 <= h.cols):
        raise ValidationError(f"{stream.name}: region {r0}:{r1},{c0}:{c1} lies outside the {h.rows}x{h.cols} map "
                              f"(rows 0..{h.rows}, cols 0..{h.cols}, half-open)")
    return r0, r1, c0, c1


def region_blocks(stream: ExportStream, region: tuple[int, int, int, int], start_time: float = 0.0
                  ) -> Iterator[tuple[np.ndarray, np.ndarray, np.ndarray, int]]:
    """An export's frames block by block, in bounded memory: (times s from ``start_time``, counts (n, rows, cols)
    uint8 of the region, its ``B`` cells (n, rows, cols) bool, values clipped at saturation)."""
    r0, r1, c0, c1 = region
    for block in stream.blocks():
        counts, over = to_counts(block, stream.header.scale, stream.name)
        t = start_time + stream.times(block.numbers)
        if not t[-1] < MAX_LOG_TIME:
            k = int(np.argmax(~(t < MAX_LOG_TIME)))
            raise ValidationError(f"{stream.name}:{int(block.line_of_frame[k])}: Frame {block.numbers[k]} "
                                  f"falls {t[k]:.4g} s after 1970, later than a recording can hold "
                                  f"({_LAST_DATE}); check the frame numbers, SECONDS_PER_FRAME and --start-time")
        yield t, np.ascontiguousarray(counts[:, r0:r1, c0:c1]), block.is_b[:, r0:r1, c0:c1], over


def file_sha256(path: Path) -> str:
    """SHA-256 of a file, read in 1 MiB pieces."""
    sha = hashlib.sha256()
    with open(path, "rb") as f:
        while chunk := f.read(1 << 20):
            sha.update(chunk)
    return sha.hexdigest()


@dataclass
class _Stats:
    """What the import summary reports, gathered block by block."""

    b_any: np.ndarray
    frames: int = 0
    t0: float = 0.0
    t1: float = 0.0
    peak_c_p: int = 0
    peak_active: int = 0
    clipped: int = 0

    def add(self, t: np.ndarray, counts: np.ndarray, is_b: np.ndarray, clipped: int, noise: int) -> None:
        flat = counts.reshape(len(counts), -1)
        if self.frames == 0:
            self.t0 = float(t[0])
        self.t1 = float(t[-1])
        self.frames += len(counts)
        self.peak_c_p = max(self.peak_c_p, int(flat.sum(axis=1, dtype=np.int64).max()))
        self.peak_active = max(self.peak_active, int((flat > noise).sum(axis=1).max()))
        self.b_any |= is_b.any(axis=0)
        self.clipped += clipped


def _pressure_pa(text: str) -> float:
    m = NUMBER_UNIT.match(text.strip())
    scale = PRESSURE.get(unit_key(m.group(2))) if m else None
    if scale is None or not float(m.group(1)) > 0:
        raise argparse.ArgumentTypeError(f"{text!r} is not a positive pressure with a unit, e.g. '862 kPa'")
    return float(m.group(1)) * scale


def add_import_command(imports: argparse._SubParsersAction) -> None:
    """Add ``palpate import tekscan FILE --out REC.mcap [...]`` to the ``import`` group."""
    p = imports.add_parser(
        "tekscan", help="import a Tekscan ASCII/CSV movie export into an MCAP recording",
        description="Convert a Tekscan ASCII/CSV movie export into an MCAP recording (topic /taxels/SENSOR_ID).")
    p.add_argument("file", type=Path, help="the Tekscan export (.csv/.asf)")
    p.add_argument("--out", type=Path, required=True, help="the MCAP recording to write")
    p.add_argument("--force", action="store_true", help="overwrite an existing --out (never the export itself)")
    p.add_argument("--region", help="R0:R1,C0:C1: keep only this block of the map (0-based, half-open), "
                                    "e.g. 1:5,1:5 for a 4x4 pad")
    p.add_argument("--start-time", help="ISO 8601 date-time of the first frame (default: times from 0 s)")
    p.add_argument("--sensor-id", default="tekscan", help="sensor name, gives the topic /taxels/ID (default tekscan)")
    p.add_argument("--full-scale", type=_pressure_pa, metavar="PRESSURE",
                   help="saturation pressure, e.g. '862 kPa', for pressure exports without SATURATION_PRESSURE")
    p.add_argument("--max-bytes", type=int, default=MAX_EXPORT_BYTES, metavar="N",
                   help=f"largest export read, bytes (default {MAX_EXPORT_BYTES >> 30} GiB; the import streams, "
                        "so memory does not grow with the file)")
    p.set_defaults(func=_run_import)


def _run_import(args: argparse.Namespace) -> int:
    check_output_file(args.out, inputs=[args.file], force=args.force)
    summary = import_tekscan(args.file, args.out, region=args.region, start_time=parse_start_time(args.start_time),
                             sensor_id=args.sensor_id, full_scale_pa=args.full_scale, max_bytes=args.max_bytes)
    print(summary.text())
    return 0
