"""Each fidelity's force against the FE reference over the validity cases: the validity table.

A case is pressed once per fidelity, robot-exact, 10 mm/s, to just past its deepest depth (but never past the depth
every rung holds, :data:`palpate.sim.limits.MAX_DEPTH_OVER_THICKNESS` of the thickness: a depth there is read at the
trace's deepest point when that lies within READ_SHORT of it), at the centre of its scene
(:func:`palpate.sim.validity.cases.case_object`); the force at each of the case's depths is read off the loading
branch and compared with the cached FE reference. The table also records each fidelity's cost (wall time per
simulated second, one run). ``palpate bench`` writes it; models/validity_table.json is the shipped copy ``auto``
reads.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from palpate.core.errors import PalpateError
from palpate.core.session.sources import PressTarget
from palpate.core.world.scene import Scene
from palpate.sim.analytic import run_analytic_press
from palpate.sim.contact.stack import object_law
from palpate.sim.controller import press_profile
from palpate.sim.flex.press import run_flex_press
from palpate.sim.flex.tables import FlexTables, load_flex_tables
from palpate.sim.limits import MAX_DEPTH_OVER_THICKNESS
from palpate.sim.rigid import run_rigid_press
from palpate.sim.stability import MAX_DEPTH_OVER_RADIUS, law_depth
from palpate.sim.trace import PhysicsTrace
from palpate.sim.validity.cases import TIP_RADIUS, ValidityCase, case_object
from palpate.sim.validity.reference import FEReference, reference_force
from palpate.sim.validity.table import RUNGS, RungCost, RungFailure, ValidityRow, ValidityTable

#: A depth at most this share past a trace's deepest point is read there (a press stopped at the depth limit ends
#: within 0.02% of it: flex 0.9998 mm of 1 mm, analytic a rounding error short).
READ_SHORT = 1e-3


def loading_force(indentation: np.ndarray, force: np.ndarray, depths) -> np.ndarray:
    """Force (N) at ``depths`` (m) on the loading branch of a trace (up to its deepest point), interpolated; NaN
    past the deepest point by over READ_SHORT."""
    k = int(np.argmax(indentation))
    d, f = indentation[: k + 1], force[: k + 1]
    keep = np.concatenate([[True], np.diff(d) > 0])
    at = np.asarray(depths, dtype=float)
    deepest = float(d[keep][-1])
    at = np.where((at > deepest) & (at <= deepest * (1.0 + READ_SHORT)), deepest, at)
    return np.interp(at, d[keep], f[keep], left=np.nan, right=np.nan)


@dataclass(frozen=True)
class CasePress:
    """One press of a case: its physics trace and the wall time it took, s."""

    trace: PhysicsTrace
    wall_s: float


def press_case(case: ValidityCase, fidelity: str, models: dict | None = None,
               tables: FlexTables | None = None) -> CasePress:
    """Press a case once at ``fidelity`` (``models``: built flex windows, reused across cases; ``tables``: flex's
    calibration tables, read by the press itself when None)."""
    obj = case_object(case)
    scene = Scene((obj,))
    deepest = min(max(case.depths) * 1.03, 0.99 * MAX_DEPTH_OVER_RADIUS * TIP_RADIUS,
                  MAX_DEPTH_OVER_THICKNESS * obj.height)
    target = PressTarget(0.0, 0.0, depth=deepest, speed=0.01)
    profile = press_profile(target, obj.height, radius=TIP_RADIUS, timestep=0.002)
    t0 = time.perf_counter()
    if fidelity == "flex":
        trace = run_flex_press(scene, obj, target, profile, models=models, tables=tables)
    else:
        law = object_law(obj, 0.0, 0.0, obj.height, TIP_RADIUS, law_depth(profile))
        if fidelity == "analytic":
            # sampled finely so the comparison reads the law, not the interpolation between taxel frames
            trace = run_analytic_press(scene, obj, profile, law=law, rate=1000.0)
        else:
            trace = run_rigid_press(scene, obj, profile, law=law)
    return CasePress(trace=trace, wall_s=time.perf_counter() - t0)


def measure_table(cases: list[ValidityCase], reference: FEReference, *, rungs=RUNGS, progress=None) -> ValidityTable:
    """The validity table (see the module docstring); failures are recorded, not raised."""
    rows, failures = [], []
    wall = dict.fromkeys(rungs, 0.0)
    simulated = dict.fromkeys(rungs, 0.0)
    models: dict = {}
    # read once, so a flex press's wall time is its physics, not three table reads
    tables = load_flex_tables() if "flex" in rungs else None
    for case in cases:
        ref = reference_force(reference, case)
        errs = {}
        for rung in rungs:
            try:
                run = press_case(case, rung, models, tables)
            except PalpateError as exc:
                failures.append(RungFailure(case=case.name, fidelity=rung, error=f"{type(exc).__name__}: {exc}"))
                errs[rung] = np.full(len(case.depths), np.nan)
                continue
            wall[rung] += run.wall_s
            simulated[rung] += float(run.trace.t[-1] - run.trace.t[0])
            errs[rung] = loading_force(run.trace.indentation, run.trace.force, case.depths) / ref - 1.0
        for i, d in enumerate(case.depths):
            rows.append(ValidityRow(
                case=case.name, family=case.family, poisson=case.sample.surface.poisson,
                thickness=case.sample.thickness, depth=float(d), feature=case.feature(d),
                a_over_h=math.sqrt(TIP_RADIUS * d) / case.sample.thickness, reference_force=float(ref[i]),
                error={r: (None if not np.isfinite(errs[r][i]) else float(errs[r][i])) for r in rungs}))
        if progress is not None:
            progress(case, {r: errs[r] for r in rungs})
    return ValidityTable(tip_radius=TIP_RADIUS, rungs=tuple(rungs), rows=tuple(rows),
                         cost={r: RungCost(wall_s=wall[r], sim_s=simulated[r]) for r in rungs},
                         failures=tuple(failures))
