"""The FE reference's answers for the validity table, computed once and cached as data (models/reference_tables.json,
validated on load), with the convergence of a few cases under mesh refinement.

Regenerate with ``.venv/bin/python benchmarks/validity.py --reference`` (minutes on two cores).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.files import number_array, read_json
from palpate.core.world.resources import models_dir
from palpate.sim.reference.fe import fe_press
from palpate.sim.validity.cases import TIP_RADIUS, ValidityCase

REFERENCE_PATH = models_dir() / "reference_tables.json"
FORMAT = "palpate-fe-reference"
VERSION = 1
#: Mesh refinement of the shipped reference (surface spacing = smallest contact radius / 12 / refinement).
REFINEMENT = 1.0
#: Cases whose refinement study the file keeps (a thick block, a thin one, a lump).
CONVERGENCE_CASES = ("thick_100mm_nu0.45", "thick_5mm_nu0.49", "lump_hard_1mm")
CONVERGENCE_LEVELS = (0.5, 1.0, 2.0)


def compute_reference(cases: list[ValidityCase], *, refinement: float = REFINEMENT, progress=None,
                      convergence: bool = True) -> dict:
    """Solve every case with the FE reference; return the JSON document (see :func:`load_reference`)."""
    doc = {"format": FORMAT, "version": VERSION, "tip_radius": TIP_RADIUS, "refinement": refinement, "cases": {},
           "convergence": {}}
    for case in cases:
        fe = fe_press(case.sample, TIP_RADIUS, case.depths, refinement=refinement)
        doc["cases"][case.name] = {"describe": case.sample.describe(), "depth": fe.depth.tolist(),
                                   "force": fe.force.tolist(), "contact_radius": fe.contact_radius.tolist(),
                                   "dofs": fe.dofs, "h0": fe.h0}
        if progress is not None:
            progress(case.name, fe)
    if convergence:
        for case in cases:
            if case.name not in CONVERGENCE_CASES:
                continue
            levels = []
            for level in CONVERGENCE_LEVELS:
                fe = fe_press(case.sample, TIP_RADIUS, case.depths, refinement=level)
                levels.append({"refinement": level, "dofs": fe.dofs, "force": fe.force.tolist()})
            doc["convergence"][case.name] = {"depth": list(case.depths), "levels": levels}
    return doc


def _array(path: Path, key: str, value) -> np.ndarray:
    return number_array(value, f"{path}: {key}", 1, max_size=1000)


def read_document(path: Path | str, what: str, fmt: str | None, version: int, missing: str) -> dict:
    """A validity data file (bounded, strict JSON: core.files.read_json) whose ``format`` and ``version`` keys are
    ``fmt`` and ``version``; ``missing`` says how to make it when it does not exist. ``fmt`` None: a file whose
    format predates the ``format`` key (the flex block calibration), known by its ``version`` alone.

    Raises:
        ValidationError: missing, too large, not JSON (NaN included) or of another format, naming the file.
    """
    path = Path(path)
    if not path.exists():
        raise ValidationError(f"{path}: {what} not found; {missing}")
    raw = read_json(path, what)
    got = raw.get("version") if isinstance(raw, dict) else None
    if fmt is None and got != version:
        raise ValidationError(f"{path}: key 'version' must be {version}, got {got!r}")
    if fmt is not None and (got != version or raw.get("format") != fmt):
        raise ValidationError(f"{path}: not a {fmt} file of version {version}")
    return raw


@dataclass(frozen=True)
class ReferenceCase:
    """The FE reference's answer for one case: depth m, force N and contact radius m, each (n,)."""

    depth: np.ndarray
    force: np.ndarray
    contact_radius: np.ndarray


@dataclass(frozen=True)
class ConvergenceLevel:
    """One case solved at one mesh refinement: its degrees of freedom and force (N) at the case's depths."""

    refinement: float
    dofs: int
    force: np.ndarray


@dataclass(frozen=True)
class FEReference:
    """A loaded reference file.

    Attributes:
        cases: case name -> its answer.
        convergence: case name -> the case at each refinement of its study, coarsest first.
        refinement: the refinement the cases were solved at (None if the file does not say).
    """

    cases: dict[str, ReferenceCase]
    convergence: dict[str, tuple[ConvergenceLevel, ...]]
    refinement: float | None


@dataclass(frozen=True)
class ConvergenceRow:
    """A case at one refinement: its dofs and its largest force change against the finest level, %."""

    case: str
    refinement: float
    dofs: int
    max_change_pct: float


def _levels(path: Path, name: str, study) -> tuple[ConvergenceLevel, ...]:
    levels = study.get("levels") if isinstance(study, dict) else None
    if not isinstance(levels, list) or len(levels) > 100:
        raise ValidationError(f"{path}: convergence.{name}.levels must be a list of at most 100 levels")
    out = []
    for i, lev in enumerate(levels):
        key = f"convergence.{name}.levels[{i}]"
        refinement, dofs = (lev.get("refinement"), lev.get("dofs")) if isinstance(lev, dict) else (None, None)
        if isinstance(refinement, bool) or not isinstance(refinement, (int, float)) or not refinement > 0:
            raise ValidationError(f"{path}: {key}.refinement must be a positive number")
        if isinstance(dofs, bool) or not isinstance(dofs, int) or dofs <= 0:
            raise ValidationError(f"{path}: {key}.dofs must be a positive integer")
        out.append(ConvergenceLevel(refinement=float(refinement), dofs=dofs,
                                    force=_array(path, f"{key}.force", lev.get("force"))))
    return tuple(out)


def load_reference(path: Path | str = REFERENCE_PATH) -> FEReference:
    """Read and validate a reference file: each case's depth, force and contact radius, and the convergence study.

    Raises:
        ValidationError: missing, too large, not JSON, wrong format/version, or a bad case, naming file and key.
    """
    path = Path(path)
    raw = read_document(path, "FE reference tables", FORMAT, VERSION,
                        "compute them with `.venv/bin/python benchmarks/validity.py --reference`")
    if raw.get("tip_radius") != TIP_RADIUS:
        raise ValidationError(f"{path}: key 'tip_radius' must be {TIP_RADIUS} m, got {raw.get('tip_radius')!r}")
    cases = raw.get("cases")
    if not isinstance(cases, dict) or not cases:
        raise ValidationError(f"{path}: key 'cases' must be a non-empty object")
    out = {}
    for name, c in cases.items():
        if not isinstance(c, dict):
            raise ValidationError(f"{path}: cases.{name} must be an object")
        d = _array(path, f"cases.{name}.depth", c.get("depth"))
        f = _array(path, f"cases.{name}.force", c.get("force"))
        a = _array(path, f"cases.{name}.contact_radius", c.get("contact_radius"))
        if not (len(d) == len(f) == len(a)):
            raise ValidationError(f"{path}: cases.{name}: depth, force and contact_radius differ in length")
        if np.any(d <= 0) or np.any(np.diff(d) <= 0) or np.any(f <= 0) or np.any(np.diff(f) <= 0):
            raise ValidationError(f"{path}: cases.{name}: depths and forces must be positive and increasing")
        out[name] = ReferenceCase(depth=d, force=f, contact_radius=a)
    convergence = raw.get("convergence", {})
    if not isinstance(convergence, dict):
        raise ValidationError(f"{path}: key 'convergence' must be an object")
    refinement = raw.get("refinement")
    if refinement is not None and (isinstance(refinement, bool) or not isinstance(refinement, (int, float))):
        raise ValidationError(f"{path}: key 'refinement' must be a number")
    return FEReference(cases=out, convergence={n: _levels(path, n, c) for n, c in convergence.items()},
                       refinement=None if refinement is None else float(refinement))


def reference_force(reference: FEReference, case: ValidityCase) -> np.ndarray:
    """The reference force (N) at each of the case's depths, from the loaded file.

    Raises:
        ValidationError: the file lacks the case or was computed at other depths (regenerate it).
    """
    entry = reference.cases.get(case.name)
    if entry is None:
        raise ValidationError(f"the FE reference file has no case {case.name!r}; regenerate it with "
                              "`.venv/bin/python benchmarks/validity.py --reference`")
    if len(entry.depth) != len(case.depths) or not np.allclose(entry.depth, case.depths, rtol=1e-9):
        raise ValidationError(f"the FE reference for {case.name!r} was computed at other depths; regenerate it")
    return entry.force


def convergence_rows(reference: FEReference) -> list[ConvergenceRow]:
    """The refinement study as rows: each case at each refinement, its dofs and its largest force change against
    the finest level, %."""
    rows = []
    for name, levels in reference.convergence.items():
        if not levels:
            continue
        finest = levels[-1].force
        for lev in levels:
            change = (100.0 * float(np.max(np.abs(lev.force / finest - 1.0))) if lev.force.shape == finest.shape
                      else math.nan)
            rows.append(ConvergenceRow(case=name, refinement=lev.refinement, dofs=lev.dofs, max_change_pct=change))
    return rows
