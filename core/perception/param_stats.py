"""Statistics of per-press parameter tables (seed 000's Tables 6.3-6.5 and their simulated counterparts).

A :class:`PressTable` holds, per material, one row per fitted press with the columns of :data:`STAT_COLUMNS`
(n1, n2, Phi_N, a1, a2, Phi_A in the units of the fit). :func:`column_stats` gives what the sim-to-real report and
the realism calibration compare: mean, standard deviation (n - 1), coefficient of variation and the share of
negative values. :func:`energy_distance` is the distance between two tables' distributions of one material used by
both: the two-sample energy distance (Szekely & Rizzo 2004) between the [n1, n2, a1, a2] rows, each column divided
by the reference table's standard deviation, so every parameter counts alike and 0 means the same distribution.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.perception.params_table import read_params_csv

#: Columns of a press table, in order (fit units: counts, mm, mm^2).
STAT_COLUMNS = ("n1", "n2", "phi_n", "a1", "a2", "phi_a")
#: The columns the memory judges (and the energy distance compares).
PARAM_INDEX = (0, 1, 3, 4)


@dataclass(frozen=True)
class PressTable:
    """Per-press parameters by material.

    Attributes:
        materials: names, in order.
        rows: one (k, 6) array per material (columns :data:`STAT_COLUMNS`), aligned with ``materials``.
    """

    materials: tuple[str, ...]
    rows: tuple[np.ndarray, ...]

    def __post_init__(self) -> None:
        if len(self.materials) != len(self.rows):
            raise ValidationError(f"PressTable: {len(self.materials)} materials but {len(self.rows)} row blocks")
        for name, r in zip(self.materials, self.rows, strict=True):
            if r.ndim != 2 or r.shape[1] != len(STAT_COLUMNS) or not np.all(np.isfinite(r)):
                raise ValidationError(f"PressTable: rows of {name!r} must be a finite (k, 6) array, got {r.shape}")

    def of(self, material: str) -> np.ndarray:
        """The (k, 6) rows of ``material``."""
        if material not in self.materials:
            raise ValidationError(f"material {material!r} is not in the table ({', '.join(self.materials)})")
        return self.rows[self.materials.index(material)]


def table_from_fits(fits: Mapping[str, Sequence]) -> PressTable:
    """A table from per-material sequences of fits (objects with n1, n2, phi_n, a1, a2, phi_a; None = unfitted,
    left out)."""
    names, rows = [], []
    for name, seq in fits.items():
        good = [f for f in seq if f is not None]
        names.append(name)
        rows.append(np.array([[float(getattr(f, c)) for c in STAT_COLUMNS] for f in good]).reshape(-1, 6))
    return PressTable(tuple(names), tuple(rows))


def table_from_csv(path: str | Path) -> PressTable:
    """A table from a per-press CSV (``material,n1,n2,a1,a2`` and the residual columns ``phi_n,phi_a``)."""
    return table_from_columns(path, *read_params_csv(path))


def table_from_columns(path: str | Path, params: np.ndarray, labels: Sequence[str],
                       extra: Mapping[str, np.ndarray]) -> PressTable:
    """A table from what :func:`~palpate.core.perception.params_table.read_params_csv` read from ``path`` (named in
    errors), for a caller that also needs the file's other columns."""
    missing = [c for c in ("phi_n", "phi_a") if c not in extra or extra[c].dtype.kind != "f"]
    if missing:
        raise ValidationError(f"{path}: the sim-to-real comparison needs numeric column(s) {missing} (the fits' "
                              "residual sums, as seed 000's tables give)")
    full = np.column_stack([params[:, 0], params[:, 1], extra["phi_n"], params[:, 2], params[:, 3], extra["phi_a"]])
    names = list(dict.fromkeys(labels))
    lab = np.asarray(labels)
    return PressTable(tuple(names), tuple(full[lab == n] for n in names))


@dataclass(frozen=True)
class ColumnStats:
    """Statistics of one column of one material: mean, standard deviation (n - 1), coefficient of variation
    (sd / |mean|; None when the mean is 0), share of negative values, count."""

    mean: float
    sd: float
    cv: float | None
    negative_fraction: float
    n: int


def column_stats(values) -> ColumnStats:
    """Statistics of one column (at least two finite values)."""
    v = np.asarray(values, dtype=float).reshape(-1)
    if len(v) < 2 or not np.all(np.isfinite(v)):
        raise ValidationError(f"column statistics need at least two finite values, got {v.tolist()}")
    mean = float(v.mean())
    sd = float(v.std(ddof=1))
    return ColumnStats(mean, sd, sd / abs(mean) if mean != 0 else None, float(np.mean(v < 0)), len(v))


def energy_distance(x: np.ndarray, y: np.ndarray, scale: np.ndarray) -> float:
    """Two-sample energy distance 2 E|X - Y| - E|X - X'| - E|Y - Y'| between rows x (n, d) and y (m, d), each column
    divided by ``scale`` (d,) first; >= 0, 0 for identical samples."""
    s = np.where(np.asarray(scale, dtype=float) > 0, scale, 1.0)
    a, b = np.asarray(x, dtype=float) / s, np.asarray(y, dtype=float) / s
    if len(a) < 1 or len(b) < 1:
        raise ValidationError("energy distance needs at least one row on each side")

    def mean_dist(p: np.ndarray, q: np.ndarray) -> float:
        return float(np.mean(np.linalg.norm(p[:, None, :] - q[None, :, :], axis=-1)))

    return max(2.0 * mean_dist(a, b) - mean_dist(a, a) - mean_dist(b, b), 0.0)


def material_distance(sim: np.ndarray, real: np.ndarray) -> float:
    """:func:`energy_distance` of [n1, n2, a1, a2] rows of one material, standardised by the real table's sd."""
    idx = list(PARAM_INDEX)
    return energy_distance(sim[:, idx], real[:, idx], real[:, idx].std(axis=0, ddof=1))
