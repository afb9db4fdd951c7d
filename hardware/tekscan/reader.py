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

Parsing is vectorised (numpy over all values of the file at once); ``benchmarks/tekscan_import.py`` measures it.
"""

from __future__ import annotations

import re
import warnings
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.perception.streams import TaxelFrame
from palpate.hardware.tekscan.header import (
    FORCE,
    FRAME_LINE,
    PRESSURE,
    area_entry,
    frame_period,
    int_entry,
    length_entry,
    number_unit,
    parse_header,
    unit_key,
)


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


def read_tekscan(path, *, full_scale_pa: float | None = None) -> TekscanMovie:
    """Read a Tekscan ASCII/CSV movie export (see the module docstring for the format and conversions).

    Args:
        path: the exported file.
        full_scale_pa: saturation pressure, Pa, for non-RAW files whose header lacks SATURATION_PRESSURE.

    Raises:
        ValidationError: unreadable file or bad content, naming the file and line.
    """
    path = Path(path)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise ValidationError(f"{path}: cannot read Tekscan export: {exc.strerror}") from None
    # Tekscan writes Windows-1252/ASCII text; latin-1 maps every byte, so a stray byte becomes a clear parse error
    # on its line rather than a UnicodeDecodeError.
    text = raw.decode("utf-8-sig") if raw.startswith(b"\xef\xbb\xbf") else raw.decode("latin-1")
    return parse_tekscan(text, path.name, full_scale_pa=full_scale_pa)


def parse_tekscan(text: str, name: str = "<string>", *, full_scale_pa: float | None = None) -> TekscanMovie:
    """Parse the text of a Tekscan movie export; ``name`` is used in error messages. See :func:`read_tekscan`."""
    lines = text.replace("\r\n", "\n").replace("\r", "\n").split("\n")
    header, body_start = parse_header(lines, name)

    rows = int_entry(header, "ROWS", name, minimum=1)
    cols = int_entry(header, "COLS", name, minimum=1)
    spf = frame_period(header, name)
    row_sp = length_entry(header, "ROW_SPACING", name)
    col_sp = length_entry(header, "COL_SPACING", name)
    area = area_entry(header, row_sp, col_sp, name)
    units_text = header["UNITS"][0] if "UNITS" in header else "RAW"

    scale = _count_scale(header, units_text, area, full_scale_pa, name)
    noise = number_unit(header, "NOISE_THRESHOLD", name)[0] if "NOISE_THRESHOLD" in header else 0.0

    numbers, values, line_of_row, is_b = _parse_body(lines, body_start, rows, cols, name)
    n = len(numbers)
    counts, threshold = _to_counts(values, scale, noise, line_of_row, cols, name)

    start = int_entry(header, "START_FRAME", name, default=int(numbers[0]), minimum=0)
    if numbers[0] < start:
        raise ValidationError(f"{name}: first frame is Frame {numbers[0]}, before START_FRAME {start} "
                              f"(line {header['START_FRAME'][1]})")
    if "END_FRAME" in header:
        end = int_entry(header, "END_FRAME", name, minimum=start)
        if numbers[-1] > end:
            raise ValidationError(f"{name}: last frame is Frame {numbers[-1]}, after END_FRAME {end} "
                                  f"(line {header['END_FRAME'][1]})")
    if "FRAMES" in header:
        expected = int_entry(header, "FRAMES", name, minimum=1)
        if expected != n:
            raise ValidationError(f"{name}:{header['FRAMES'][1]}: FRAMES says {expected} frames, the file has {n}")

    mask = ~is_b.reshape(n, rows, cols).any(axis=0)
    return TekscanMovie(
        counts=counts.reshape(n, rows, cols), frame_numbers=numbers, t=(numbers - start) * spf,
        seconds_per_frame=spf, sensel_area=area, mask=mask, units=units_text, noise_threshold=threshold,
        row_spacing=row_sp, col_spacing=col_sp, region=(0, rows, 0, cols),
        header={k: v for k, (v, _) in header.items()}, source=name,
    )


def _parse_body(lines, start: int, rows: int, cols: int, name: str):
    """Frame numbers, all values (flat, float), the file line of each value row, and the B mask (flat)."""
    body = [s.strip() for s in lines[start:]]
    is_frame = np.fromiter((s[:5].lower() == "frame" for s in body), dtype=bool, count=len(body))
    is_data = np.fromiter((bool(s) for s in body), dtype=bool, count=len(body)) & ~is_frame
    frame_idx = np.flatnonzero(is_frame)
    data_idx = np.flatnonzero(is_data)
    if len(frame_idx) == 0:
        raise ValidationError(f"{name}: no 'Frame N' line after the header (line {start})")
    if len(data_idx) and data_idx[0] < frame_idx[0]:
        raise ValidationError(f"{name}:{start + data_idx[0] + 1}: values before the first 'Frame N' line")
    numbers = np.empty(len(frame_idx), dtype=np.int64)
    for k, i in enumerate(frame_idx):
        m = FRAME_LINE.match(body[i])
        if not m:
            raise ValidationError(f"{name}:{start + i + 1}: expected 'Frame N', got {body[i][:60]!r}")
        numbers[k] = int(m.group(1))
    if len(numbers) > 1 and np.any(np.diff(numbers) <= 0):
        k = int(np.argmax(np.diff(numbers) <= 0)) + 1
        raise ValidationError(f"{name}:{start + frame_idx[k] + 1}: Frame {numbers[k]} follows Frame {numbers[k - 1]};"
                              " frame numbers must increase")
    owner = np.searchsorted(frame_idx, data_idx, side="right") - 1
    per_frame = np.bincount(owner, minlength=len(frame_idx))
    if np.any(per_frame != rows):
        k = int(np.argmax(per_frame != rows))
        raise ValidationError(f"{name}:{start + frame_idx[k] + 1}: Frame {numbers[k]} has {per_frame[k]} rows of "
                              f"values, expected ROWS = {rows}")
    # Spreadsheet exports pad rows with trailing commas; a missing value inside a row is still an error.
    data = [body[i].rstrip(",").rstrip() for i in data_idx]
    n_fields = np.fromiter((s.count(",") for s in data), dtype=np.int64, count=len(data)) + 1
    if np.any(n_fields != cols):
        j = int(np.argmax(n_fields != cols))
        raise ValidationError(f"{name}:{start + data_idx[j] + 1}: expected {cols} values, got {n_fields[j]}")
    line_of_row = data_idx + start + 1
    joined = ",".join(data)
    values, is_b = _fast_values(joined, len(data) * cols)
    if values is None:  # something unusual in the values: the slow path finds it and names its line
        tokens = np.array(joined.split(","))
        stripped = np.char.strip(tokens)
        is_b = (stripped == "B") | (stripped == "b")
        tokens[is_b] = "0"
        for k, tok in enumerate(tokens):
            try:
                float(tok)
            except ValueError:
                raise ValidationError(f"{name}:{line_of_row[k // cols]}: value {k % cols + 1} is {tok.strip()!r}, "
                                      "expected a number or B") from None
        values = tokens.astype(np.float64)
    bad = ~np.isfinite(values)
    if np.any(bad):
        k = int(np.argmax(bad))
        raise ValidationError(f"{name}:{line_of_row[k // cols]}: value {k % cols + 1} is "
                              f"{joined.split(',')[k].strip()!r}, expected a finite number")
    return numbers, values, line_of_row, is_b


def _count_scale(header, units_text: str, area: float, full_scale_pa, name: str) -> float | None:
    """Counts per unit of the file's values: None for RAW, else 255 / p_sat scaled to the file's unit."""
    unit = unit_key(units_text)
    where = f"{name}:{header['UNITS'][1]}" if "UNITS" in header else name
    if unit in ("raw", "", "counts", "count"):
        return None
    if unit in PRESSURE:
        to_pa = PRESSURE[unit]
    elif unit in FORCE:
        to_pa = FORCE[unit] / area  # per-sensel force -> mean pressure over the sensel
    else:
        raise ValidationError(f"{where}: UNITS {units_text!r} not understood; expected RAW, a pressure "
                              f"({', '.join(PRESSURE)}) or a per-sensel force ({', '.join(FORCE)})")
    if "SATURATION_PRESSURE" in header:
        number, sat_unit = number_unit(header, "SATURATION_PRESSURE", name)
        sat_scale = PRESSURE.get(unit_key(sat_unit)) if sat_unit else to_pa
        if sat_scale is None:
            raise ValidationError(f"{name}:{header['SATURATION_PRESSURE'][1]}: SATURATION_PRESSURE unit {sat_unit!r}"
                                  f" not understood; expected one of {', '.join(PRESSURE)}")
        p_sat = number * sat_scale
    elif full_scale_pa is not None:
        p_sat = float(full_scale_pa)
    else:
        raise ValidationError(f"{where}: UNITS {units_text!r} is not RAW and the header has no SATURATION_PRESSURE; "
                              "give the sensor's full-scale pressure (--full-scale, e.g. '862 kPa') to convert to "
                              "8-bit counts")
    if not (np.isfinite(p_sat) and p_sat > 0):
        raise ValidationError(f"{name}: saturation pressure must be > 0 Pa, got {p_sat}")
    return to_pa * 255.0 / p_sat


_PLAIN_VALUES = re.compile(r"[^0-9eE+\-.,\sBb]")


def _fast_values(joined: str, expected: int) -> tuple[np.ndarray | None, np.ndarray | None]:
    """All values at C speed: numpy's text parser with B as NaN. (None, None) if the text holds anything else
    (letters, empty fields, a NaN of its own), so that the caller reports exactly where."""
    if _PLAIN_VALUES.search(joined):
        return None, None
    with warnings.catch_warnings():
        # numpy signals a parse stop (e.g. an empty field) only by this warning; turn it into the slow path.
        warnings.simplefilter("error", DeprecationWarning)
        try:
            values = np.fromstring(joined.replace("B", "nan").replace("b", "nan"), sep=",")
        except (DeprecationWarning, ValueError):
            return None, None
    if values.shape != (expected,):
        return None, None
    is_b = np.isnan(values)
    values[is_b] = 0.0
    return values, is_b


def _to_counts(values, scale: float | None, noise: float, line_of_row, cols: int, name: str):
    """Values (flat, in the file's units) -> uint8 counts, and the noise threshold in counts."""

    def _first(bad, what):
        k = int(np.argmax(bad))
        return ValidationError(f"{name}:{line_of_row[k // cols]}: value {k % cols + 1} is {values[k]:g}, {what}")

    if scale is None:
        bad = (values < 0) | (values > 255) | (values != np.floor(values))
        if np.any(bad):
            raise _first(bad, "expected a RAW count 0..255 (is UNITS right? pressure exports need their unit)")
        return values.astype(np.uint8), int(np.clip(round(noise), 0, 254))
    if np.any(values < 0):
        raise _first(values < 0, "expected a pressure >= 0")
    scaled = np.rint(values * scale)
    over = scaled > 255
    if np.any(over):
        warnings.warn(f"{name}: {int(over.sum())} values above the saturation pressure were clipped to 255 counts",
                      TekscanWarning, stacklevel=3)
    return np.minimum(scaled, 255).astype(np.uint8), int(np.clip(round(noise * scale), 0, 254))


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
