"""Tekscan export -> palpate MCAP recording (the ``palpate import tekscan`` command)."""

from __future__ import annotations

import argparse
import hashlib
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.io.mcap_writer import RecordingWriter
from palpate.core.perception.streams import TaxelFrame
from palpate.core.session.output_guard import check_output_file
from palpate.hardware.tekscan.header import NUMBER_UNIT, PRESSURE, unit_key
from palpate.hardware.tekscan.reader import read_tekscan, select_region


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
    t = when.timestamp()
    if t < 0:
        raise ValidationError(f"--start-time {text!r} is before 1970-01-01, which MCAP log times cannot hold")
    return t


def import_tekscan(path, out, *, region: str | None = None, start_time: float = 0.0, sensor_id: str = "tekscan",
                   full_scale_pa: float | None = None) -> ImportSummary:
    """Convert a Tekscan ASCII/CSV movie export into an MCAP recording with one ``/taxels/<sensor_id>`` topic.

    Args:
        path: the Tekscan export.
        out: the .mcap file to write.
        region: ``R0:R1,C0:C1`` (0-based, half-open) to keep only that block (e.g. the 4x4 fingertip pad).
        start_time: time of the first frame, s (Unix time for absolute stamps; 0 keeps file-relative times).
        sensor_id: topic name of the pad.
        full_scale_pa: saturation pressure, Pa, for pressure exports without SATURATION_PRESSURE.

    Raises:
        ValidationError: bad file, region or arguments (the message names the file and line).
    """
    path = Path(path)
    movie = read_tekscan(path, full_scale_pa=full_scale_pa)
    if region is not None:
        movie = select_region(movie, region)
    if not (np.isfinite(start_time) and start_time >= 0):
        raise ValidationError(f"start_time must be a finite time >= 0 s, got {start_time!r}")
    metadata = {
        "scenario": None,
        "sources": [{
            "kind": "tekscan_ascii", "file": path.name, "sha256": hashlib.sha256(path.read_bytes()).hexdigest(),
            "sensor_id": sensor_id, "region": list(movie.region), "start_time": start_time,
        }],
        "tekscan": {
            "header": movie.header, "units": movie.units, "noise_threshold_counts": movie.noise_threshold,
            "sensor_mask": movie.mask.astype(int).tolist(), "seconds_per_frame": movie.seconds_per_frame,
            "row_spacing_m": movie.row_spacing, "col_spacing_m": movie.col_spacing,
            "frame_numbers": [int(movie.frame_numbers[0]), int(movie.frame_numbers[-1])],
        },
    }
    t = start_time + movie.t
    with RecordingWriter(out, metadata, chunk_size=64 * 1024) as w:
        for ti, c in zip(t, movie.counts, strict=True):
            w.write_taxel(TaxelFrame(float(ti), c, movie.sensel_area, sensor_id))
    flat = movie.counts.reshape(len(movie.counts), -1)
    return ImportSummary(
        out=Path(out), frames=len(movie.counts), shape=movie.shape, duration=float(movie.t[-1] - movie.t[0]),
        start_time=float(t[0]), sensel_area=movie.sensel_area, b_cells=int((~movie.mask).sum()),
        peak_c_P=int(flat.sum(axis=1, dtype=np.int64).max()),
        peak_active=int((flat > movie.noise_threshold).sum(axis=1).max()), region=movie.region,
    )


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
    p.set_defaults(func=_run_import)


def _run_import(args: argparse.Namespace) -> int:
    check_output_file(args.out, inputs=[args.file], force=args.force)
    summary = import_tekscan(args.file, args.out, region=args.region, start_time=parse_start_time(args.start_time),
                             sensor_id=args.sensor_id, full_scale_pa=args.full_scale)
    print(summary.text())
    return 0
