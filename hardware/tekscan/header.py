"""The header of a Tekscan ASCII/CSV movie export: key aliases, units, and the typed entries the reader needs
(rows, columns, frame period, sensel spacing and area)."""

from __future__ import annotations

import re

import numpy as np

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
    return number * scale


def area_entry(header, row_sp, col_sp, name: str) -> float:
    if "SENSEL_AREA" not in header:
        if row_sp is None or col_sp is None:
            raise ValidationError(f"{name}: header has no SENSEL_AREA (nor ROW_SPACING and COL_SPACING to derive it)")
        return row_sp * col_sp
    number, unit = number_unit(header, "SENSEL_AREA", name)
    scale = AREA.get(unit_key(unit))
    if scale is None or not number > 0:
        raise ValidationError(f"{name}:{header['SENSEL_AREA'][1]}: SENSEL_AREA must be a positive area with a unit "
                              f"(cm2, sq cm, mm2, in2, m2), got {header['SENSEL_AREA'][0]!r}")
    return number * scale
