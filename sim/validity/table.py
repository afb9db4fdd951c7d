"""The validity table as data: one row per case and depth with each fidelity's force error against the FE reference,
each fidelity's cost, and what failed.

models/validity_table.json is read once, here, at the file boundary (:func:`load_table`, validated with size
limits) into frozen dataclasses; :meth:`ValidityTable.to_dict` writes the same JSON document back.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from types import MappingProxyType

from palpate.core.errors import ValidationError
from palpate.core.files import per_file_version
from palpate.core.world.resources import models_dir
from palpate.sim.validity.cases import FAMILIES
from palpate.sim.validity.reference import read_document

TABLE_PATH = models_dir() / "validity_table.json"
FORMAT = "palpate-validity"
VERSION = 1
RUNGS = ("analytic", "rigid", "flex")


@dataclass(frozen=True)
class ValidityRow:
    """One case at one depth.

    Attributes:
        case: the case's name (:mod:`palpate.sim.validity.cases`).
        family: one of FAMILIES.
        poisson: Poisson ratio of the surface material.
        thickness: sample thickness, m.
        depth: indentation, m.
        feature: the family's dimensionless value (thickness / a, skin / a, lump depth / a or edge distance / a,
            a = sqrt(R d)).
        a_over_h: contact radius over thickness.
        reference_force: the FE reference's force, N.
        error: fidelity -> signed relative force error against the reference (None where the fidelity failed).
    """

    case: str
    family: str
    poisson: float
    thickness: float
    depth: float
    feature: float
    a_over_h: float
    reference_force: float
    error: dict[str, float | None]

    def to_dict(self) -> dict:
        """The row as the table file writes it."""
        return {"case": self.case, "family": self.family, "poisson": self.poisson, "thickness": self.thickness,
                "depth": self.depth, "feature": self.feature, "a_over_h": self.a_over_h,
                "reference_force": self.reference_force, "error": dict(self.error)}


@dataclass(frozen=True)
class RungCost:
    """What one fidelity cost over a run's cases: wall time and simulated time, s."""

    wall_s: float
    sim_s: float

    @property
    def realtime(self) -> float | None:
        """Simulated seconds per wall second (None if nothing ran)."""
        return self.sim_s / self.wall_s if self.wall_s > 0 else None


@dataclass(frozen=True)
class RungFailure:
    """A fidelity that could not press a case, and the error it raised."""

    case: str
    fidelity: str
    error: str


@dataclass(frozen=True)
class ValidityTable:
    """The validity table (see the module docstring).

    Attributes:
        tip_radius: the tip radius every case was pressed with, m.
        rungs: the fidelities measured.
        rows: one per case and depth.
        cost: fidelity -> its cost over the run.
        failures: presses that raised instead of giving a force.
    """

    tip_radius: float
    rungs: tuple[str, ...]
    rows: tuple[ValidityRow, ...]
    cost: Mapping[str, RungCost]
    failures: tuple[RungFailure, ...] = ()

    def to_dict(self) -> dict:
        """The JSON document (models/validity_table.json's format)."""
        cost = {r: {"wall_s": c.wall_s, "sim_s": c.sim_s, "realtime": c.realtime} for r, c in self.cost.items()}
        return {"format": FORMAT, "version": VERSION, "tip_radius": self.tip_radius, "rungs": list(self.rungs),
                "rows": [r.to_dict() for r in self.rows], "cost": cost,
                "failures": [{"case": f.case, "fidelity": f.fidelity, "error": f.error} for f in self.failures]}


def _number(path, key: str, value, *, positive: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or (
            positive and value <= 0):
        raise ValidationError(f"{path}: {key} must be a finite{' positive' if positive else ''} number")
    return float(value)


def _text(path, key: str, value) -> str:
    if not isinstance(value, str) or len(value) > 10_000:
        raise ValidationError(f"{path}: {key} must be a string")
    return value


def _row(path, i: int, row) -> ValidityRow:
    if not isinstance(row, dict) or row.get("family") not in FAMILIES:
        raise ValidationError(f"{path}: rows[{i}].family must be one of {FAMILIES}")
    num = {key: _number(path, f"rows[{i}].{key}", row.get(key))
           for key in ("feature", "poisson", "depth", "thickness", "a_over_h", "reference_force")}
    err = row.get("error")
    if not isinstance(err, dict) or set(err) - set(RUNGS):
        raise ValidationError(f"{path}: rows[{i}].error must map fidelities {RUNGS} to numbers or null")
    error = {r: None if err.get(r) is None else _number(path, f"rows[{i}].error.{r}", err[r]) for r in RUNGS
             if r in err}
    return ValidityRow(case=_text(path, f"rows[{i}].case", row.get("case")), family=row["family"],
                       error=error, **num)


def _cost(path, raw) -> dict[str, RungCost]:
    if not isinstance(raw, dict) or set(raw) - set(RUNGS):
        raise ValidationError(f"{path}: key 'cost' must map fidelities {RUNGS} to their cost")
    out = {}
    for rung, c in raw.items():
        if not isinstance(c, dict):
            raise ValidationError(f"{path}: cost.{rung} must be an object")
        out[rung] = RungCost(wall_s=_number(path, f"cost.{rung}.wall_s", c.get("wall_s")),
                             sim_s=_number(path, f"cost.{rung}.sim_s", c.get("sim_s")))
    return out


def _failures(path, raw) -> tuple[RungFailure, ...]:
    if not isinstance(raw, list):
        raise ValidationError(f"{path}: key 'failures' must be a list")
    out = []
    for i, f in enumerate(raw):
        if not isinstance(f, dict):
            raise ValidationError(f"{path}: failures[{i}] must be an object")
        out.append(RungFailure(case=_text(path, f"failures[{i}].case", f.get("case")),
                               fidelity=_text(path, f"failures[{i}].fidelity", f.get("fidelity")),
                               error=_text(path, f"failures[{i}].error", f.get("error"))))
    return tuple(out)


def table_from_document(raw: dict, path: Path | str = "validity table") -> ValidityTable:
    """The table in a JSON document of the table file's format (``path`` names it in errors).

    Raises:
        ValidationError: a missing or bad key, naming the file and the key.
    """
    rows = raw.get("rows")
    if not isinstance(rows, list) or not rows:
        raise ValidationError(f"{path}: key 'rows' must be a non-empty list")
    rungs = raw.get("rungs", list(RUNGS))
    if (not isinstance(rungs, list) or not rungs or not all(isinstance(r, str) for r in rungs)
            or not set(rungs) <= set(RUNGS) or len(set(rungs)) != len(rungs)):
        raise ValidationError(f"{path}: key 'rungs' must list distinct fidelities of {RUNGS}")
    return ValidityTable(tip_radius=_number(path, "tip_radius", raw.get("tip_radius"), positive=True),
                         rungs=tuple(rungs), rows=tuple(_row(path, i, r) for i, r in enumerate(rows)),
                         cost=_cost(path, raw.get("cost", {})), failures=_failures(path, raw.get("failures", [])))


def load_table(path: Path | str = TABLE_PATH) -> ValidityTable:
    """Read and validate a validity table file, once per file version (:func:`palpate.core.files.per_file_version`:
    every source and every choice shares it).

    Raises:
        ValidationError: missing, too large, not JSON, wrong format or a bad row, naming the file and the key.
    """
    return _tables(path)


def _read_table(path: Path) -> ValidityTable:
    raw = read_document(path, "validity table", FORMAT, VERSION,
                        "measure it with `palpate bench` or `.venv/bin/python benchmarks/validity.py`")
    table = table_from_document(raw, path)
    return replace(table, cost=MappingProxyType(dict(table.cost)))  # one table serves every caller: read-only


_tables = per_file_version(_read_table)
