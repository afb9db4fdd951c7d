"""Per-press parameter tables (CSV: ``material,n1,n2,a1,a2``, e.g. seed 000 Tables 6.3-6.5) and rows of mappings."""

from __future__ import annotations

import csv
import math
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from palpate.core import files
from palpate.core.errors import ValidationError
from palpate.core.perception.params import MAX_ABS_PARAM, PARAM_COLUMNS, as_labels, as_params


def read_params_csv(path: str | Path) -> tuple[np.ndarray, list[str], dict[str, np.ndarray]]:
    """Read per-press interaction parameters from a CSV file.

    The header names the columns (any order, case-insensitive); ``material,n1,n2,a1,a2`` are required, any others
    (e.g. run, phi_n, phi_a) are kept. Blank lines and lines starting with ``#`` are skipped.

    Returns:
        (params (n, 4) [n1, n2, a1, a2], labels (n material names), extra columns: name -> (n,) array, float when
        every value is a finite number, str otherwise).

    Raises ValidationError naming the file, line and column of the first bad entry, e.g.
    ``params.csv:7: column 'a1': 'abc' is not a number``.
    """
    path = Path(path)
    name = path.name
    text = files.read_text(path, "params CSV", encoding="utf-8-sig")

    lines = [(i + 1, line) for i, line in enumerate(text.splitlines())]
    content = [(no, line) for no, line in lines if line.strip() and not line.lstrip().startswith("#")]
    if not content:
        raise ValidationError(f"{name}: empty; expected a header with material,n1,n2,a1,a2 and one row per press")
    parsed = []
    for no, line in content:
        # One physical line per record, so every error can name its line.
        try:
            parsed.append((no, next(csv.reader([line], strict=True))))
        except csv.Error as exc:
            raise ValidationError(f"{name}:{no}: not a CSV record: {exc}") from None

    head_no, header = parsed[0]
    header = [h.strip().lower() for h in header]
    dupes = sorted({h for h in header if header.count(h) > 1})
    if dupes:
        raise ValidationError(f"{name}:{head_no}: header repeats column(s) {dupes}")
    if any(not h for h in header):
        raise ValidationError(f"{name}:{head_no}: header has an empty column name (column {header.index('') + 1})")
    missing = [c for c in ("material", *PARAM_COLUMNS) if c not in header]
    if missing:
        raise ValidationError(
            f"{name}:{head_no}: header lacks column(s) {', '.join(repr(c) for c in missing)}; expected at least "
            f"material,n1,n2,a1,a2 (got {','.join(header)})"
        )
    rows = parsed[1:]
    if not rows:
        raise ValidationError(f"{name}: header only; expected one row per press after line {head_no}")
    col = {h: i for i, h in enumerate(header)}
    params = np.empty((len(rows), 4))
    labels: list[str] = []
    raw_extra: dict[str, list[str]] = {h: [] for h in header if h not in ("material", *PARAM_COLUMNS)}
    for r, (no, row) in enumerate(rows):
        if len(row) != len(header):
            raise ValidationError(f"{name}:{no}: has {len(row)} fields, expected {len(header)} ({','.join(header)})")
        label = row[col["material"]].strip()
        if not label:
            raise ValidationError(f"{name}:{no}: column 'material': empty; expected a material name")
        labels.append(label)
        for j, c in enumerate(PARAM_COLUMNS):
            cell = row[col[c]].strip()
            try:
                v = float(cell)
            except ValueError:
                raise ValidationError(f"{name}:{no}: column '{c}': {files.brief(cell)} is not a number") from None
            if not math.isfinite(v) or abs(v) > MAX_ABS_PARAM:
                raise ValidationError(f"{name}:{no}: column '{c}': {files.brief(cell)} is not a finite number")
            params[r, j] = v
        for h in raw_extra:
            raw_extra[h].append(row[col[h]].strip())
    extra = {h: _column_array(vals) for h, vals in raw_extra.items()}
    return params, labels, extra


def _column_array(values: list[str]) -> np.ndarray:
    try:
        arr = np.array([float(v) for v in values])
    except ValueError:
        return np.array(values, dtype=str)
    return arr if np.all(np.isfinite(arr)) else np.array(values, dtype=str)


def rows_to_params(rows) -> tuple[np.ndarray, list[str]]:
    params, labels = [], []
    for i, row in enumerate(rows):
        if not isinstance(row, Mapping):
            raise ValidationError(f"row {i} is a {type(row).__name__}; expected a mapping with material,n1,n2,a1,a2")
        missing = [k for k in ("material", *PARAM_COLUMNS) if k not in row]
        if missing:
            raise ValidationError(f"row {i} lacks key(s) {missing}; expected material,n1,n2,a1,a2")
        vals = []
        for k in PARAM_COLUMNS:
            try:
                vals.append(float(row[k]))
            except (TypeError, ValueError):
                raise ValidationError(f"row {i}: column {k!r}: {files.brief(row[k])} is not a number") from None
        params.append(vals)
        labels.append(row["material"])
    if not params:
        raise ValidationError("no rows; expected one row per press with material,n1,n2,a1,a2")
    return as_params(np.array(params)), as_labels(labels, len(params))
