"""Reader of Tekscan's ASCII/CSV "movie" export (I-Scan, Grip, F-Scan style ``.csv``/``.asf`` files).

Format accepted::

    DATA_TYPE MOVIE                      header: one ``KEY value`` per line, keys case-insensitive; the key may be
    ROWS 6                               separated from its value by spaces, a comma, a colon or '='; trailing
    COLS 6                               commas (spreadsheet padding) are ignored; unknown keys are kept as text
    ROW_SPACING 0.51 cm                  lengths: m, cm, mm, in (a unit is required)
    COL_SPACING 5.08 mm
    SENSEL_AREA 0.26 sq cm               areas: m2, cm2, mm2, in2, also written ``sq cm``, ``cm^2``, ``cm²``
    SECONDS_PER_FRAME 0.01               or FRAMES_PER_SECOND / FRAME_RATE in Hz
    START_FRAME 1                        optional, default: the first frame's number
    END_FRAME 8 / FRAMES 8               optional; checked against the frames found
    UNITS RAW                            RAW (8-bit counts) or a pressure / per-sensel force unit (see below)
    NOISE_THRESHOLD 3                    optional, in UNITS; kept in the metadata, values are not altered
    ASCII_DATA @@                        end of header (a first ``Frame`` line also ends it)

    Frame 1                              or the newer ``Frame 1, 0.000, ...``: fields after the frame number
    0,0,B,...                            are ignored (times come from the frame number, see below)
    ... ROWS lines of COLS comma-separated values; ``B`` marks a cell outside the sensor map
                                         blank lines between frames; CRLF, LF or CR line ends

Decisions (strict validation, liberal spelling):

* ``B`` cells read as 0; :attr:`TekscanMovie.mask` is True where a real sensel is (never ``B`` in any frame).
* Frame time: ``t = (frame_number - START_FRAME) * SECONDS_PER_FRAME`` (s); frame numbers must increase.
* RAW values must be integers in 0..255. A value above 255 is an **error**, not clipped: RAW data from an 8-bit
  sensor cannot exceed it, so such a file is mislabelled (a pressure export) and clipping would hide that.
* Non-RAW units are converted back to the sensor's 8-bit scale, linearly: ``count = round(255 * p / p_sat)``, where
  ``p`` is the pressure in Pa (a per-sensel force in N, lbf or kgf is divided by the sensel area first) and
  ``p_sat`` is the saturation (full-scale) pressure: the header's ``SATURATION_PRESSURE`` (with its unit, or in
  UNITS when it has none) or the ``full_scale_pa`` argument. Pressures above ``p_sat`` are clipped to 255 with a
  :class:`TekscanWarning` (the sensor saturates there too). Units: Pa, kPa, MPa, psi, bar, mmHg, kg/cm2, N/cm2,
  N/mm2 (pressure); N, lbf, kgf (per-sensel force).
* A region ``R0:R1,C0:C1`` (0-based row and column indices, half-open like Python slices, e.g. ``1:5,1:5`` is the
  4x4 block whose top-left sensel is row 1, column 1) selects a pad from a larger map.

Every error is a :class:`~palpate.core.errors.ValidationError` naming the file and line:
``grip.csv:17: expected 4 values, got 3``.

Parsing streams the file in blocks of whole frames (:mod:`palpate.hardware.tekscan.stream`), each parsed by numpy at
C speed; ``benchmarks/tekscan_import.py`` measures it. Only regular files are read, and sizes are bounded before
anything is allocated: ROWS x COLS (:data:`~palpate.hardware.tekscan.header.MAX_SENSELS`), frame numbers, frame
period, and the file itself (``max_bytes``; :func:`read_tekscan` holds every frame in memory, the importer does not).
"""

from __future__ import annotations

import re
import warnings
from dataclasses import dataclass, field, replace

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.perception.streams import TaxelFrame
from palpate.hardware.tekscan.body import to_counts
from palpate.hardware.tekscan.stream import ExportStream, open_export

#: Largest export :func:`read_tekscan` loads into memory by default, bytes.
MAX_MOVIE_BYTES = 1 << 30


class TekscanWarning(UserWarning):
    """Data were changed on import (pressures clipped at the saturation pressure)."""


@dataclass(frozen=True)
class TekscanMovie:
    """A parsed Tekscan movie.

    Attributes:
        counts: 8-bit counts, shape (frames, rows, cols), uint8 (``B`` cells are 0).
        frame_numbers: the ``Frame N`` numbers, shape (frames,).
        t: frame times, s, from the first frame (``(N - START_FRAME) * SECONDS_PER_FRAME``), shape (frames,).
        seconds_per_frame: frame period, s.
        sensel_area: area of one sensel, m^2.
        mask: True where the cell is a real sensel (never ``B``), shape (rows, cols).
        units: the file's UNITS as written (``RAW`` or a pressure/force unit).
        noise_threshold: the file's NOISE_THRESHOLD converted to counts (0 if absent).
        row_spacing, col_spacing: sensel pitch, m (None if the header does not give it).
        region: (r0, r1, c0, c1) of the map this movie holds, in the file's indices.
        header: every header entry as text, keyed by upper-case key (aliases resolved).
        source: file name used in messages.
    """

    counts: np.ndarray
    frame_numbers: np.ndarray
    t: np.ndarray
    seconds_per_frame: float
    sensel_area: float
    mask: np.ndarray
    units: str
    noise_threshold: int
    row_spacing: float | None
    col_spacing: float | None
    region: tuple[int, int, int, int]
    header: dict = field(default_factory=dict)
    source: str = "<string>"

    @property
    def shape(self) -> tuple[int, int]:
        """(rows, cols) of each frame."""
        return self.counts.shape[1], self.counts.shape[2]


_REGION = re.compile(r"^\s*(\d+)\s*:\s*(\d+)\s*,\s*(\d+)\s*:\s*(\d+)\s*$")


def read_tekscan(path, *, full_scale_pa: float | None = None, max_bytes: int = MAX_MOVIE_BYTES) -> TekscanMovie:
    """Read a Tekscan ASCII/CSV movie export into memory (see the module docstring for the format and conversions).

    Args:
        path: the exported file (a regular file).
        full_scale_pa: saturation pressure, Pa, for non-RAW files whose header lacks SATURATION_PRESSURE.
        max_bytes: largest file read, bytes (the frames are held in memory: about a third of the file's size).
            ``palpate import tekscan`` streams instead and takes far larger files.

    Raises:
        ValidationError: unreadable, non-regular or too large file, or bad content, naming the file and line.
    """
    return movie_of(open_export(path, full_scale_pa=full_scale_pa, max_bytes=max_bytes))


def parse_tekscan(text: str, name: str = "<string>", *, full_scale_pa: float | None = None) -> TekscanMovie:
    """Parse the text of a Tekscan movie export; ``name`` is used in error messages. See :func:`read_tekscan`."""
    return movie_of(ExportStream(iter([text]), name, full_scale_pa=full_scale_pa))


def movie_of(stream: ExportStream) -> TekscanMovie:
    """Every frame of an export stream, as one :class:`TekscanMovie`."""
    h = stream.header
    counts, numbers, b_any, clipped = [], [], np.zeros((h.rows, h.cols), dtype=bool), 0
    for block in stream.blocks():
        c, over = to_counts(block, h.scale, stream.name)
        counts.append(c)
        numbers.append(block.numbers)
        b_any |= block.is_b.any(axis=0)
        clipped += over
    if clipped:
        warnings.warn(f"{stream.name}: {clipped} values above the saturation pressure were clipped to 255 counts",
                      TekscanWarning, stacklevel=3)
    numbers = np.concatenate(numbers)
    return TekscanMovie(
        counts=np.concatenate(counts), frame_numbers=numbers, t=stream.times(numbers),
        seconds_per_frame=h.seconds_per_frame, sensel_area=h.sensel_area, mask=~b_any, units=h.units,
        noise_threshold=h.noise_counts, row_spacing=h.row_spacing, col_spacing=h.col_spacing,
        region=(0, h.rows, 0, h.cols), header={k: v for k, (v, _) in h.entries.items()}, source=stream.name,
    )


def parse_region(text: str) -> tuple[int, int, int, int]:
    """Parse ``R0:R1,C0:C1`` (0-based, half-open) into (r0, r1, c0, c1). Raises ValidationError if malformed."""
    m = _REGION.match(text or "")
    if not m:
        raise ValidationError(f"region {text!r} must read R0:R1,C0:C1 (0-based, half-open), e.g. '1:5,1:5'")
    r0, r1, c0, c1 = (int(g) for g in m.groups())
    if r1 <= r0 or c1 <= c0:
        raise ValidationError(f"region {text!r} is empty: needs R0 < R1 and C0 < C1")
    return r0, r1, c0, c1


def select_region(movie: TekscanMovie, region: str | tuple[int, int, int, int]) -> TekscanMovie:
    """The sub-map ``region`` (a string ``R0:R1,C0:C1`` or a tuple, 0-based half-open) of a movie.

    Raises ValidationError if the region does not lie inside the map.
    """
    r0, r1, c0, c1 = parse_region(region) if isinstance(region, str) else tuple(int(v) for v in region)
    rows, cols = movie.shape
    if not (0 <= r0 < r1 <= rows and 0 <= c0 < c1 <= cols):
        raise ValidationError(f"{movie.source}: region {r0}:{r1},{c0}:{c1} lies outside the {rows}x{cols} map "
                              f"(rows 0..{rows}, cols 0..{cols}, half-open)")
    base_r, base_c = movie.region[0], movie.region[2]
    return replace(movie, counts=np.ascontiguousarray(movie.counts[:, r0:r1, c0:c1]),
                   mask=movie.mask[r0:r1, c0:c1].copy(),
                   region=(base_r + r0, base_r + r1, base_c + c0, base_c + c1))


def movie_frames(movie: TekscanMovie, *, start_time: float = 0.0, sensor_id: str = "tekscan") -> list[TaxelFrame]:
    """The movie as taxel frames at ``start_time + movie.t`` (s)."""
    t = start_time + movie.t
    return [TaxelFrame(float(ti), c, movie.sensel_area, sensor_id) for ti, c in zip(t, movie.counts, strict=True)]
