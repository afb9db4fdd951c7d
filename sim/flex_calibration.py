"""The `flex` fidelity's mesh correction: how much stiffer the trilinear flex block is than the elastic continuum.

A trilinear cell interpolates displacement over an edge comparable to the contact radius, so the block answers a
press with more force than the continuum does, by a factor that depends mostly on the contact radius a over the
cell edge (and a little on the Poisson ratio). The factor is measured once, on a thick block (CAL_HEIGHT deep,
wider than the window, bonded to the table) against the reference for that same block (the layered contact law,
which agrees with the FE reference within ~1%): kappa(a / cell, nu) = F_flex / F_reference. A press divides its
contact forces by kappa at its current contact radius sqrt(R d). Because the calibration block is thick, the factor
is the mesh's alone: a thinner block, a layer or an edge keeps the stiffening its own elasticity gives it (the
previous calibration divided E by a constant fitted to Hertz on a 20 mm block, which cancelled that stiffening).

models/flex_calibration.json holds one table per cell size (cell / tip radius); ``benchmarks/flex_resolution.py
--calibrate`` remeasures it (:func:`palpate.sim.flex_calibrate.measure_calibration`).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.world.resources import models_dir

#: The shipped table.
CALIBRATION_PATH = models_dir() / "flex_calibration.json"
#: Thickness of the calibration block, m (a / thickness < 0.1 over the calibrated presses).
CAL_HEIGHT = 0.06
#: Reference modulus of the calibration (the flex is E-invariant; this only fixes the units), Pa.
CAL_YOUNG = 2.0e5
FORMAT_VERSION = 2
#: Largest calibration file accepted, bytes.
MAX_BYTES = 1_000_000


def _numbers(path: Path, key: str, value, ndim: int) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValidationError(f"{path}: {key} must be numbers") from None
    if arr.ndim != ndim or arr.size == 0 or not np.all(np.isfinite(arr)):
        raise ValidationError(f"{path}: {key} must be a non-empty {ndim}-D array of finite numbers")
    return arr


def load_calibration(path: Path | str = CALIBRATION_PATH) -> dict:
    """Read and validate a calibration file.

    Returns:
        {"tables": [{"cell_over_radius": float, "poisson": (p,), "contact_over_cell": (c,), "factor": (p, c)}],
        "measured_with": dict}, tables sorted by cell_over_radius.

    Raises:
        ValidationError: missing, too large, not JSON, wrong version or a bad key, naming the file and the key.
    """
    path = Path(path)
    try:
        if path.stat().st_size > MAX_BYTES:
            raise ValidationError(f"{path}: {path.stat().st_size} bytes, over the {MAX_BYTES} a calibration may have")
        raw = json.loads(path.read_text())
    except FileNotFoundError:
        raise ValidationError(f"{path}: flex calibration table not found; regenerate it with "
                              "`.venv/bin/python benchmarks/flex_resolution.py --calibrate`") from None
    except json.JSONDecodeError as exc:
        raise ValidationError(f"{path}: not valid JSON (line {exc.lineno}): {exc.msg}") from None
    if not isinstance(raw, dict) or raw.get("version") != FORMAT_VERSION:
        got = raw.get("version") if isinstance(raw, dict) else None
        raise ValidationError(f"{path}: key 'version' must be {FORMAT_VERSION}, got {got!r}")
    tables = raw.get("tables")
    if not isinstance(tables, list) or not tables:
        raise ValidationError(f"{path}: key 'tables' must be a non-empty list")
    out = []
    for i, t in enumerate(tables):
        if not isinstance(t, dict):
            raise ValidationError(f"{path}: tables[{i}] must be an object")
        key = f"tables[{i}]"
        c_r = float(_numbers(path, f"{key}.cell_over_radius", t.get("cell_over_radius"), 0))
        nu = _numbers(path, f"{key}.poisson", t.get("poisson"), 1)
        ac = _numbers(path, f"{key}.contact_over_cell", t.get("contact_over_cell"), 1)
        fac = _numbers(path, f"{key}.factor", t.get("factor"), 2)
        if fac.shape != (len(nu), len(ac)):
            raise ValidationError(f"{path}: {key}.factor must be {len(nu)} x {len(ac)} (poisson x contact_over_cell)")
        if not (c_r > 0 and np.all(np.diff(nu) > 0) and np.all(np.diff(ac) > 0) and np.all(fac > 0)):
            raise ValidationError(f"{path}: {key} needs cell_over_radius > 0, increasing poisson and "
                                  "contact_over_cell, and factors > 0")
        out.append({"cell_over_radius": c_r, "poisson": nu, "contact_over_cell": ac, "factor": fac})
    out.sort(key=lambda t: t["cell_over_radius"])
    return {"tables": out, "measured_with": raw.get("measured_with", {})}


def mesh_factor(contact_over_cell: float, poisson: float, cell_over_radius: float,
                calibration: dict) -> tuple[float, bool]:
    """kappa at contact radius / cell ``contact_over_cell`` and ``poisson`` for cells of ``cell_over_radius``.

    Uses the table of the nearest cell size, bilinear in (poisson, a / cell) and clamped at the table's ends.

    Returns:
        (kappa, extrapolated): extrapolated is True if the cell size is over 5% from the table's, or the point
        lies outside the table.
    """
    tables = calibration["tables"]
    t = min(tables, key=lambda tb: abs(np.log(tb["cell_over_radius"] / cell_over_radius)))
    nu, ac, fac = t["poisson"], t["contact_over_cell"], t["factor"]
    per_nu = np.array([np.interp(contact_over_cell, ac, row) for row in fac])
    kappa = float(np.interp(poisson, nu, per_nu))
    outside = (abs(t["cell_over_radius"] / cell_over_radius - 1.0) > 0.05 or not nu[0] <= poisson <= nu[-1]
               or contact_over_cell > ac[-1] * 1.05)
    return kappa, bool(outside)
