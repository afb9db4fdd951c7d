"""The header of a Tekscan ASCII/CSV movie export: key aliases, units, and the typed entries the reader needs
(rows, columns, frame period, sensel spacing and area, the conversion of the values to counts), with limits on
sizes that could not come from a real sensor (see :class:`ExportHeader`)."""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

from palpate.core import limits
from palpate.core.errors import ValidationError

FRAME_LINE = re.compile(r"^frame\s*[:#]?\s*(\d+)\s*(?:[,;\s].*)?$", re.IGNORECASE)
ALIASES = {
    "ROW": "ROWS", "NROWS": "ROWS", "NUM_ROWS": "ROWS", "NUMBER_OF_ROWS": "ROWS",
    "COL": "COLS", "COLUMNS": "COLS", "NCOLS": "COLS", "NUM_COLS": "COLS", "NUMBER_OF_COLUMNS": "COLS",
    "COLUMN_SPACING": "COL_SPACING", "ROWSPACING": "ROW_SPACING", "COLSPACING": "COL_SPACING",
    "SENSELAREA": "SENSEL_AREA", "SENSEL_SIZE": "SENSEL_AREA",
    "SEC_PER_FRAME": "SECONDS_PER_FRAME", "SECONDS_PER_FRAMES": "SECONDS_PER_FRAME",
    "FRAME_PERIOD": "SECONDS_PER_FRAME",
    "FPS": "FRAMES_PER_SECOND", "FRAME_RATE": "FRAMES_PER_SECOND",
    "STARTFRAME": "START_FRAME", "ENDFRAME": "END_FRAME", "FRAME_COUNT": "FRAMES", "NUM_FRAMES": "FRAMES",
    "UNIT": "UNITS", "NOISE_TRESHOLD": "NOISE_THRESHOLD", "NOISETHRESHOLD": "NOISE_THRESHOLD",
    "SATURATION": "SATURATION_PRESSURE",
}


LENGTH = {"m": 1.0, "cm": 1e-2, "mm": 1e-3, "in": 0.0254, "inch": 0.0254, "inches": 0.0254}


AREA = {"m2": 1.0, "cm2": 1e-4, "mm2": 1e-6, "in2": 0.0254**2, "inch2": 0.0254**2}


PRESSURE = {"pa": 1.0, "kpa": 1e3, "mpa": 1e6, "psi": 6894.757293168, "bar": 1e5, "mmhg": 133.322387415,
             "kg/cm2": 98066.5, "kgf/cm2": 98066.5, "n/cm2": 1e4, "n/mm2": 1e6}


FORCE = {"n": 1.0, "lbf": 4.4482216152605, "lb": 4.4482216152605, "kgf": 9.80665}


NUMBER_UNIT = re.compile(r"^([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(.*)$")


def unit_key(unit: str) -> str:
    u = unit.strip().strip("()[]").lower().replace("²", "2").replace("^2", "2").replace(".", "").replace(" ", "")
    if u.startswith("sq"):
        u = u[2:] + "2"
    return u


def parse_header(lines: list[str], name: str) -> tuple[dict[str, tuple[str, int]], int]:
    header: dict[str, tuple[str, int]] = {}
    for i, line in enumerate(lines):
        s = line.strip().rstrip(",").strip()
        if not s:
            continue
        if FRAME_LINE.match(s):
            return header, i
        key, value = split_key(s)
        if key == "ASCII_DATA":
            return header, i + 1
        if not re.match(r"^[A-Z][A-Z0-9_]*$", key):
            raise ValidationError(f"{name}:{i + 1}: expected a header line 'KEY value', got {s[:60]!r}")
        if key in header:
            raise ValidationError(f"{name}:{i + 1}: header key {key} given twice (first on line {header[key][1]})")
        header[key] = (value, i + 1)
    raise ValidationError(f"{name}: no 'ASCII_DATA @@' line or 'Frame' line: not a Tekscan ASCII movie export")


KNOWN_KEYS = set(ALIASES) | set(ALIASES.values()) | {
    "ROW_SPACING", "COL_SPACING", "SENSEL_AREA", "ASCII_DATA", "DATA_TYPE", "SENSOR_TYPE", "END_FRAME", "START_FRAME"}


def split_key(s: str) -> tuple[str, str]:
    """'Sensel area = 0.26 sq cm' -> ('SENSEL_AREA', '0.26 sq cm'): the longest run of up to 3 leading words that
    names a known key (else the first word) is the key; separators may be spaces, ',', ':' or '='."""
    words = list(re.finditer(r"[^\s,:=]+", s))
    for n in (3, 2, 1):
        if len(words) < n:
            continue
        key = "_".join(w.group(0) for w in words[:n]).upper().replace("-", "_")
        key = ALIASES.get(key, key)
        if n == 1 or key in KNOWN_KEYS:
            return key, s[words[n - 1].end():].lstrip(" \t,:=").rstrip(", \t")
    return "", s


def number_unit(header, key: str, name: str) -> tuple[float, str]:
    value, line = header[key]
    m = NUMBER_UNIT.match(value)
    if not m:
        raise ValidationError(f"{name}:{line}: {key} must be a number (with its unit), got {value!r}")
    number = float(m.group(1))
    if not np.isfinite(number):
        raise ValidationError(f"{name}:{line}: {key} must be finite, got {value!r}")
    return number, m.group(2).strip()


def int_entry(header, key: str, name: str, *, default: int | None = None, minimum: int = 0) -> int:
    if key not in header:
        if default is None:
            raise ValidationError(f"{name}: header has no {key} line (expected e.g. '{key} 4' before ASCII_DATA @@)")
        return default
    value, line = header[key]
    if not re.fullmatch(r"[-+]?\d+", value):
        raise ValidationError(f"{name}:{line}: {key} must be a whole number, got {value!r}")
    if len(value.lstrip("+-").lstrip("0")) > 16:
        raise ValidationError(f"{name}:{line}: {key} {value[:20]}... is too large (more than 16 digits)")
    number = int(value)
    if number < minimum:
        raise ValidationError(f"{name}:{line}: {key} must be >= {minimum}, got {number}")
    return number


def frame_period(header, name: str) -> float:
    if "SECONDS_PER_FRAME" in header:
        spf, unit = number_unit(header, "SECONDS_PER_FRAME", name)
        scale = {"": 1.0, "s": 1.0, "sec": 1.0, "ms": 1e-3}.get(unit.lower())
        key = "SECONDS_PER_FRAME"
    elif "FRAMES_PER_SECOND" in header:
        hz, unit = number_unit(header, "FRAMES_PER_SECOND", name)
        scale = 1.0 if unit.lower() in ("", "hz", "fps") else None
        spf = 1.0 / hz if hz > 0 else -1.0
        key = "FRAMES_PER_SECOND"
    else:
        raise ValidationError(f"{name}: header has no SECONDS_PER_FRAME (or FRAMES_PER_SECOND) line")
    line = header[key][1]
    if scale is None:
        raise ValidationError(f"{name}:{line}: {key} has unit {unit!r}, expected s or ms (Hz for a rate)")
    if not spf > 0:
        raise ValidationError(f"{name}:{line}: {key} must be > 0, got {header[key][0]!r}")
    return spf * scale


def length_entry(header, key: str, name: str) -> float | None:
    if key not in header:
        return None
    number, unit = number_unit(header, key, name)
    scale = LENGTH.get(unit_key(unit))
    if scale is None or not number > 0:
        raise ValidationError(f"{name}:{header[key][1]}: {key} must be a positive length with a unit "
                              f"({', '.join(LENGTH)}), got {header[key][0]!r}")
    lo, hi = limits.limit("length_min_m"), limits.limit("length_m")
    if not lo <= number * scale <= hi:
        raise limits.implausible(f"{name}:{header[key][1]}: {key}", number * scale, lo, hi, "m", "length_min_m",
                                 "length_m")
    return number * scale


def area_entry(header, row_sp, col_sp, name: str) -> float:
    if "SENSEL_AREA" not in header:
        if row_sp is None or col_sp is None:
            raise ValidationError(f"{name}: header has no SENSEL_AREA (nor ROW_SPACING and COL_SPACING to derive it)")
        area = row_sp * col_sp
        hi = limits.limit("sensel_area_m2")
        if area > hi:
            raise limits.implausible(f"{name}: ROW_SPACING x COL_SPACING (the sensel area)", area,
                                     limits.limit("length_min_m") ** 2, hi, "m^2", "sensel_area_m2")
        return area
    number, unit = number_unit(header, "SENSEL_AREA", name)
    scale = AREA.get(unit_key(unit))
    if scale is None or not number > 0:
        raise ValidationError(f"{name}:{header['SENSEL_AREA'][1]}: SENSEL_AREA must be a positive area with a unit "
                              f"(cm2, sq cm, mm2, in2, m2), got {header['SENSEL_AREA'][0]!r}")
    lo, hi = limits.limit("length_min_m") ** 2, limits.limit("sensel_area_m2")
    if not lo <= number * scale <= hi:
        raise limits.implausible(f"{name}:{header['SENSEL_AREA'][1]}: SENSEL_AREA", number * scale, lo, hi, "m^2",
                                 "length_min_m", "sensel_area_m2")
    return number * scale


# Limits on what a header may declare, checked before anything is allocated. Tekscan's largest maps have a few
# thousand sensels (a 2288-sensel hand map, 44x52 mats); these bounds are far above any real sensor and stop a typo
# or a hostile file from asking for gigabytes per frame.
MAX_SIDE = 4096
MAX_SENSELS = 1 << 20
# Longest frame period accepted, s: a Tekscan movie samples at 1 Hz or faster; hours per frame is a unit mistake.
MAX_FRAME_PERIOD = 3600.0
# Frame numbers beyond this cannot be times on a float64 clock to the frame (2^53): a damaged or hostile file.
MAX_FRAME_NUMBER = 1 << 53


@dataclass(frozen=True)
class ExportHeader:
    """The typed header of an export.

    Attributes:
        rows, cols: sensels per frame.
        seconds_per_frame: frame period, s.
        sensel_area: m^2.
        row_spacing, col_spacing: sensel pitch, m (None when not given).
        units: UNITS as written (RAW when absent).
        scale: counts per unit of the file's values (None for RAW).
        noise: NOISE_THRESHOLD in the file's units (0 when absent).
        entries: every header entry as (text, line), keyed by upper-case key (aliases resolved).
    """

    rows: int
    cols: int
    seconds_per_frame: float
    sensel_area: float
    row_spacing: float | None
    col_spacing: float | None
    units: str
    scale: float | None
    noise: float
    entries: dict = field(default_factory=dict)

    @property
    def noise_counts(self) -> int:
        """The noise threshold converted to counts (0..254)."""
        scaled = self.noise if self.scale is None else self.noise * self.scale
        return int(np.clip(round(scaled), 0, 254))


def export_header(header: dict[str, tuple[str, int]], name: str, full_scale_pa: float | None = None) -> ExportHeader:
    """The typed header from the entries :func:`parse_header` returns; ValidationError naming file and line."""
    rows = int_entry(header, "ROWS", name, minimum=1)
    cols = int_entry(header, "COLS", name, minimum=1)
    if rows > MAX_SIDE or cols > MAX_SIDE or rows * cols > MAX_SENSELS:
        raise ValidationError(f"{name}: a {rows} x {cols} map is larger than any Tekscan sensor (at most {MAX_SIDE} "
                              f"rows or columns and {MAX_SENSELS} sensels are read); check ROWS and COLS")
    spf = frame_period(header, name)
    if spf > MAX_FRAME_PERIOD:
        raise ValidationError(f"{name}: a frame period of {spf:g} s is longer than {MAX_FRAME_PERIOD:g} s; check "
                              "SECONDS_PER_FRAME (in s) or FRAMES_PER_SECOND (in Hz)")
    row_sp = length_entry(header, "ROW_SPACING", name)
    col_sp = length_entry(header, "COL_SPACING", name)
    area = area_entry(header, row_sp, col_sp, name)
    units = header["UNITS"][0] if "UNITS" in header else "RAW"
    scale = count_scale(header, units, area, full_scale_pa, name)
    noise = number_unit(header, "NOISE_THRESHOLD", name)[0] if "NOISE_THRESHOLD" in header else 0.0
    return ExportHeader(rows, cols, spf, area, row_sp, col_sp, units, scale, noise, dict(header))


def count_scale(header, units_text: str, area: float, full_scale_pa, name: str) -> float | None:
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
