"""The body of a Tekscan movie export, a block of whole frames at a time: ``Frame N`` lines, ROWS lines of COLS
values each, ``B`` outside the sensor map; values to 8-bit counts. Errors name the file and line."""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from palpate.core.errors import ValidationError
from palpate.hardware.tekscan.header import FRAME_LINE, MAX_FRAME_NUMBER


@dataclass(frozen=True)
class FrameBlock:
    """Consecutive frames of an export.

    Attributes:
        numbers: the ``Frame N`` numbers, int64, shape (n,).
        values: the values as written (B read as 0), float64, shape (n, rows, cols).
        is_b: True where a value is ``B``, shape (n, rows, cols).
        line_of_row: the file line (1-based) of each row of values, shape (n * rows,).
        line_of_frame: the file line (1-based) of each ``Frame`` line, shape (n,).
    """

    numbers: np.ndarray
    values: np.ndarray
    is_b: np.ndarray
    line_of_row: np.ndarray
    line_of_frame: np.ndarray


def is_frame_line(stripped: str) -> bool:
    """Whether a stripped line starts a frame (``Frame 12`` or ``Frame 12, 0.120, ...``)."""
    return stripped[:5].lower() == "frame"


def parse_block(lines: list[str], first: int, rows: int, cols: int, name: str) -> FrameBlock:
    """Parse whole frames: ``lines`` are consecutive lines of the body starting at ``Frame`` lines (0-based file
    line index ``first`` for the first one). Frame numbers must increase within the block."""
    body = [s.strip() for s in lines]
    is_frame = np.fromiter((is_frame_line(s) for s in body), dtype=bool, count=len(body))
    is_data = np.fromiter((bool(s) for s in body), dtype=bool, count=len(body)) & ~is_frame
    frame_idx = np.flatnonzero(is_frame)
    data_idx = np.flatnonzero(is_data)
    if len(frame_idx) == 0:
        raise ValidationError(f"{name}: no 'Frame N' line after the header (line {first})")
    if len(data_idx) and data_idx[0] < frame_idx[0]:
        raise ValidationError(f"{name}:{first + data_idx[0] + 1}: values before the first 'Frame N' line")
    numbers = np.empty(len(frame_idx), dtype=np.int64)
    for k, i in enumerate(frame_idx):
        m = FRAME_LINE.match(body[i])
        if not m:
            raise ValidationError(f"{name}:{first + i + 1}: expected 'Frame N', got {body[i][:60]!r}")
        if len(m.group(1).lstrip("0")) > 16 or int(m.group(1)) >= MAX_FRAME_NUMBER:
            raise ValidationError(f"{name}:{first + i + 1}: frame number {m.group(1)[:20]} is too large "
                                  f"(at most {MAX_FRAME_NUMBER - 1})")
        numbers[k] = int(m.group(1))
    if len(numbers) > 1 and np.any(np.diff(numbers) <= 0):
        k = int(np.argmax(np.diff(numbers) <= 0)) + 1
        raise ValidationError(f"{name}:{first + frame_idx[k] + 1}: Frame {numbers[k]} follows Frame {numbers[k - 1]};"
                              " frame numbers must increase")
    owner = np.searchsorted(frame_idx, data_idx, side="right") - 1
    per_frame = np.bincount(owner, minlength=len(frame_idx))
    if np.any(per_frame != rows):
        k = int(np.argmax(per_frame != rows))
        raise ValidationError(f"{name}:{first + frame_idx[k] + 1}: Frame {numbers[k]} has {per_frame[k]} rows of "
                              f"values, expected ROWS = {rows}")
    # Spreadsheet exports pad rows with trailing commas; a missing value inside a row is still an error.
    data = [body[i].rstrip(",").rstrip() for i in data_idx]
    n_fields = np.fromiter((s.count(",") for s in data), dtype=np.int64, count=len(data)) + 1
    if np.any(n_fields != cols):
        j = int(np.argmax(n_fields != cols))
        raise ValidationError(f"{name}:{first + data_idx[j] + 1}: expected {cols} values, got {n_fields[j]}")
    line_of_row = data_idx + first + 1
    values, is_b = _values(data, cols, line_of_row, name)
    n = len(numbers)
    return FrameBlock(numbers, values.reshape(n, rows, cols), is_b.reshape(n, rows, cols), line_of_row,
                      frame_idx + first + 1)


_PLAIN_INTS = re.compile(r"[^0-9,\sBb]")
_PLAIN_FLOATS = re.compile(r"[^0-9eE+\-.,\sBb]")


def _values(data: list[str], cols: int, line_of_row: np.ndarray, name: str) -> tuple[np.ndarray, np.ndarray]:
    """All values of the rows (flat float64, B as 0) and where B was, at C speed (numpy's loadtxt) when the text
    holds only numbers and B; otherwise, or when that fails, value by value so the error names its line."""
    sample = "".join(data)
    if not _PLAIN_FLOATS.search(sample):
        try:
            if not _PLAIN_INTS.search(sample):  # RAW counts: integers, B as -1 (no '-' can be in this text)
                ints = np.loadtxt([s.replace("B", "-1").replace("b", "-1") for s in data], delimiter=",",
                                  dtype=np.int64, ndmin=2).reshape(-1)
                is_b = ints == -1
                return np.where(is_b, 0, ints).astype(np.float64), is_b
            floats = np.loadtxt([s.replace("B", "nan").replace("b", "nan") for s in data], delimiter=",",
                                dtype=np.float64, ndmin=2).reshape(-1)
            is_b = np.isnan(floats)
            floats[is_b] = 0.0
            if np.all(np.isfinite(floats)):
                return floats, is_b
        except ValueError:
            pass
    return _values_one_by_one(",".join(data), cols, line_of_row, name)


def _values_one_by_one(joined: str, cols: int, line_of_row: np.ndarray, name: str) -> tuple[np.ndarray, np.ndarray]:
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
                              f"{str(stripped[k])!r}, expected a finite number")
    return values, is_b


def to_counts(block: FrameBlock, scale: float | None, name: str) -> tuple[np.ndarray, int]:
    """A block's values (in the file's units) as uint8 counts, and how many were clipped at saturation."""
    values = block.values.reshape(-1)
    cols = block.values.shape[2]

    def _first(bad, what):
        k = int(np.argmax(bad))
        return ValidationError(f"{name}:{block.line_of_row[k // cols]}: value {k % cols + 1} is {values[k]:g}, {what}")

    if scale is None:
        bad = (values < 0) | (values > 255) | (values != np.floor(values))
        if np.any(bad):
            raise _first(bad, "expected a RAW count 0..255 (is UNITS right? pressure exports need their unit)")
        return values.astype(np.uint8).reshape(block.values.shape), 0
    if np.any(values < 0):
        raise _first(values < 0, "expected a pressure >= 0")
    scaled = np.rint(values * scale)
    over = int(np.count_nonzero(scaled > 255))
    return np.minimum(scaled, 255).astype(np.uint8).reshape(block.values.shape), over
