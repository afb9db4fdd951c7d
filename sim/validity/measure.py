"""Each fidelity's force against the FE reference over the validity cases: the validity table.

A case is pressed once per fidelity, robot-exact, 10 mm/s, to just past its deepest depth, at the centre of its
scene (:func:`palpate.sim.validity.cases.case_object`); the force at each of the case's depths is read off the
loading branch and compared with the cached FE reference. The table also records each fidelity's cost (wall time
per simulated second, one run). ``palpate bench`` writes it; models/validity_table.json is the shipped copy
``auto`` reads.
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

from palpate.core.errors import PalpateError, ValidationError
from palpate.core.session.sources import PressTarget
from palpate.core.world.resources import models_dir
from palpate.core.world.scene import Scene
from palpate.sim.analytic import run_analytic_press
from palpate.sim.contact.stack import object_law
from palpate.sim.controller import press_profile
from palpate.sim.flex import run_flex_press
from palpate.sim.rigid import run_rigid_press
from palpate.sim.stability import MAX_DEPTH_OVER_RADIUS, law_depth
from palpate.sim.validity.cases import FAMILIES, TIP_RADIUS, ValidityCase, case_object
from palpate.sim.validity.reference import read_document, reference_force

TABLE_PATH = models_dir() / "validity_table.json"
FORMAT = "palpate-validity"
VERSION = 1
RUNGS = ("analytic", "rigid", "flex")


def loading_force(indentation: np.ndarray, force: np.ndarray, depths) -> np.ndarray:
    """Force (N) at ``depths`` (m) on the loading branch of a trace (up to its deepest point), interpolated."""
    k = int(np.argmax(indentation))
    d, f = indentation[: k + 1], force[: k + 1]
    keep = np.concatenate([[True], np.diff(d) > 0])
    return np.interp(depths, d[keep], f[keep], left=np.nan, right=np.nan)


def press_case(case: ValidityCase, fidelity: str, models: dict | None = None):
    """Press a case once at ``fidelity``; returns (trace, wall time s)."""
    obj = case_object(case)
    scene = Scene((obj,))
    deepest = min(max(case.depths) * 1.03, 0.99 * MAX_DEPTH_OVER_RADIUS * TIP_RADIUS)
    target = PressTarget(0.0, 0.0, depth=deepest, speed=0.01)
    profile = press_profile(target, obj.height, radius=TIP_RADIUS, timestep=0.002)
    t0 = time.perf_counter()
    if fidelity == "flex":
        trace = run_flex_press(scene, obj, target, profile, models=models)
    else:
        law = object_law(obj, 0.0, 0.0, obj.height, TIP_RADIUS, law_depth(profile))
        if fidelity == "analytic":
            # sampled finely so the comparison reads the law, not the interpolation between taxel frames
            trace = run_analytic_press(scene, obj, profile, law=law, rate=1000.0)
        else:
            trace = run_rigid_press(scene, obj, profile, law=law)
    return trace, time.perf_counter() - t0


def measure_table(cases: list[ValidityCase], reference: dict, *, rungs=RUNGS, progress=None) -> dict:
    """The validity table document (see the module docstring); failures are recorded, not raised."""
    rows, failures = [], []
    cost = {r: {"wall_s": 0.0, "sim_s": 0.0} for r in rungs}
    models: dict = {}
    for case in cases:
        ref = reference_force(reference, case)
        errs = {}
        for rung in rungs:
            try:
                trace, wall = press_case(case, rung, models)
            except PalpateError as exc:
                failures.append({"case": case.name, "fidelity": rung, "error": f"{type(exc).__name__}: {exc}"})
                errs[rung] = np.full(len(case.depths), np.nan)
                continue
            cost[rung]["wall_s"] += wall
            cost[rung]["sim_s"] += float(trace.t[-1] - trace.t[0])
            errs[rung] = loading_force(trace.indentation, trace.force, case.depths) / ref - 1.0
        for i, d in enumerate(case.depths):
            rows.append({
                "case": case.name, "family": case.family, "poisson": case.sample.surface.poisson,
                "thickness": case.sample.thickness, "depth": float(d), "feature": case.feature(d),
                "a_over_h": math.sqrt(TIP_RADIUS * d) / case.sample.thickness, "reference_force": float(ref[i]),
                "error": {r: (None if not np.isfinite(errs[r][i]) else float(errs[r][i])) for r in rungs},
            })
        if progress is not None:
            progress(case, {r: errs[r] for r in rungs})
    for c in cost.values():
        c["realtime"] = c["sim_s"] / c["wall_s"] if c["wall_s"] > 0 else None
    return {"format": FORMAT, "version": VERSION, "tip_radius": TIP_RADIUS, "rungs": list(rungs), "rows": rows,
            "cost": cost, "failures": failures}


def load_table(path: Path | str = TABLE_PATH) -> dict:
    """Read and validate a validity table (rows with family, feature, poisson, depth and per-rung errors).

    Raises:
        ValidationError: missing, too large, not JSON, wrong format or a bad row, naming the file and the key.
    """
    raw = read_document(path, "validity table", FORMAT, VERSION,
                        "measure it with `palpate bench` or `.venv/bin/python benchmarks/validity.py`")
    rows = raw.get("rows")
    if not isinstance(rows, list) or not rows:
        raise ValidationError(f"{path}: key 'rows' must be a non-empty list")
    for i, row in enumerate(rows):
        if not isinstance(row, dict) or row.get("family") not in FAMILIES:
            raise ValidationError(f"{path}: rows[{i}].family must be one of {FAMILIES}")
        for key in ("feature", "poisson", "depth"):
            v = row.get(key)
            if not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ValidationError(f"{path}: rows[{i}].{key} must be a finite number")
        err = row.get("error")
        if not isinstance(err, dict) or set(err) - set(RUNGS):
            raise ValidationError(f"{path}: rows[{i}].error must map fidelities {RUNGS} to numbers or null")
        for r, v in err.items():
            if v is not None and (not isinstance(v, (int, float)) or not math.isfinite(v)):
                raise ValidationError(f"{path}: rows[{i}].error.{r} must be a finite number or null")
    return raw
