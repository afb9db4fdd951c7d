"""Fit a realism profile to a real per-press parameter table: the method of simulated moments.

The table (``palpate memory``'s CSV: material, n1, n2, a1, a2, phi_n, phi_a; e.g. seed 000's Tables 6.3-6.5) gives,
per material, the statistics of :mod:`~palpate.sim.realism.moments` (``MOMENTS``): the location of n1 and a1 (log
of the mean), their spread (log of the coefficient of variation), the shares of negative n2 and a2, and how well
leave-one-out cross-validation reads the material as itself (mean posterior, Table 6.7); all but a2's sign are
fitted (``SCALES``; with ``fit_a2_sign`` that too, ``SCALES_WITH_A2_SIGN``; ``tolerances`` replaces any).
A candidate profile is scored by simulating the scenario's training protocol (its reference materials, presses,
depth, force, speed, fingertip and sensors) on each *tuning* seed with common random numbers, computing the same
statistics per seed (samples of the same size as the table's, so a CV is compared with a CV of as many presses) and
averaging them over the seeds; the objective is the sum of squared differences to the table's, each divided by the
tolerance. Negative shares enter the objective smoothed (a logistic step a tenth of the column's
spread wide) so the objective is continuous; every report uses the plain shares.

Search: a Latin hypercube over the free parameters' box (seeded), then from its best point a trust region on a
fitted linear model of the residuals, or Nelder-Mead (:mod:`~palpate.sim.realism.search`), within the box, until
the evaluation budget is spent. Deterministic: the same table, scenario, start profile, free parameters, seeds,
search and budget give the same profile. The fitted profile is then simulated on *report* seeds it was not tuned on,
and its statistics there are what the profile's provenance and the command report.

The scenario's moduli (``young.<material>``, a factor on a reference material's Young's modulus: with a compliant
finger n1 no longer scales with it) and its pad (``pad.*``) may be fitted too; not part of the profile, they are
reported (``provenance.moduli_kpa``, ``pad_mm``) for the scenario's ``young_kpa`` and ``[fingertip]``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from palpate.core.errors import PalpateError, ValidationError
from palpate.core.perception.param_stats import PressTable, table_from_fits
from palpate.core.session.progress import Progress
from palpate.core.session.training import train_memory, training_seeds
from palpate.core.world.scenario import Scenario
from palpate.core.world.scene import Scene
from palpate.sim.realism.moments import (  # noqa: F401 (the calibration's statistics, imported from here too)
    MOMENTS,
    SCALES,
    SCALES_WITH_A2_SIGN,
    objective,
    real_moments,
    table_moments,
    with_tolerances,
)
from palpate.sim.realism.parameters import FreeParameter, current_values, with_scenario, with_values
from palpate.sim.realism.profile import RealismProfile
from palpate.sim.realism.search import SEARCHES, BudgetSpent, objective_of, run_search
from palpate.sim.source import SimSource


@dataclass(frozen=True)
class SeedRun:
    """One simulated training session of every reference material: its table, its leave-one-out diagonal and, per
    material, the presses left out of the table because their fit failed."""

    seed: int
    table: PressTable
    loo_self: np.ndarray
    dropped: dict[str, int] = field(default_factory=dict)


def realism_source_maker(scenario: Scenario, profile: RealismProfile, fidelity: str):
    """``make(objects, seed, variability)`` of simulated sources on the scenario's fingertip and sensors with
    ``profile`` (as :func:`palpate.core.session.sources.scenario_source_maker`, with a profile object instead of
    the scenario's named one): what a candidate profile trains with."""

    def make_source(objects, s, variability):
        scene = Scene(objects, scenario.fingertip, scenario.taxels, scenario.pose)
        return SimSource(scene, fidelity=fidelity, seed=s, variability=variability, realism=profile)

    return make_source


def simulate_seed(scenario: Scenario, profile: RealismProfile, seed: int, fidelity: str) -> SeedRun:
    """Train on the scenario's references as ``palpate run`` would with ``seed`` as the scenario seed."""
    sc = replace(scenario, seed=int(seed))
    result = train_memory(sc, realism_source_maker(scenario, profile, fidelity), training_seeds(sc),
                          Progress(enabled=False))
    table = table_from_fits({name: [r.fit for r in rs] for name, rs in result.presses.items()})
    return SeedRun(int(seed), table, np.diag(result.crossval.mean_posterior).copy(), result.dropped)


def sim_moments(runs: Sequence[SeedRun], materials: Sequence[str], references: Sequence[str],
                smooth: bool) -> np.ndarray:
    """The moments (:mod:`~palpate.sim.realism.moments`) averaged over seeds (each seed's from its own presses)."""
    idx = [list(references).index(m) for m in materials]
    return np.mean([table_moments(r.table, materials, r.loo_self[idx], smooth) for r in runs], axis=0)


def match_moduli(table: PressTable, scenario: Scenario, start: RealismProfile, free: Sequence[FreeParameter],
                 values: Sequence[float], moduli: Sequence[int], seed: int, fidelity: str,
                 log: Callable[[str], None], steps: int = 5) -> list[float]:
    """The start's modulus factors moved until each fitted material's mean n1 matches the table's (secant steps in
    log-log on one seed; n1 grows with the modulus), so the search starts where the locations already agree."""
    values = list(values)
    slope = {i: 0.5 for i in moduli}  # d log n1 / d log E: 1 with a rigid finger, less with a compliant one
    previous: dict[int, tuple[float, float]] = {}
    for _ in range(steps):
        try:
            run = simulate_seed(with_scenario(scenario, free, values), with_values(start, free, values), seed, fidelity)
        except (PalpateError, ValidationError) as exc:
            log(f"  matching moduli stopped: {exc}")
            break
        for i in moduli:
            name = free[i].key[6:]
            sim, real = float(np.mean(run.table.of(name)[:, 0])), float(np.mean(table.of(name)[:, 0]))
            if sim <= 0:
                continue
            x, y = np.log(values[i]), np.log(sim)
            if i in previous and abs(x - previous[i][0]) > 1e-6:
                slope[i] = float(np.clip((y - previous[i][1]) / (x - previous[i][0]), 0.1, 2.0))
            previous[i] = (x, y)
            values[i] = free[i].value(free[i].position(float(np.exp(x + (np.log(real) - y) / slope[i]))))
        log("  moduli matched to the mean n1: " + ", ".join(f"{free[i].key}={values[i]:.3g}" for i in moduli))
    return values


@dataclass(frozen=True)
class Calibration:
    """The result of :func:`calibrate`.

    Attributes:
        profile: the fitted profile (its provenance records the fit).
        materials: the materials compared, in order.
        real, tuned, report: (M, len(MOMENTS)) moments of the table, of the fitted profile on the tuning seeds and
            on the report seeds (plain negative shares).
        objective: the objective at the fitted profile (tuning seeds).
        evaluations: how many candidates were simulated.
        report_runs: the fitted profile's runs on the report seeds.
    """

    profile: RealismProfile
    materials: tuple[str, ...]
    real: np.ndarray
    tuned: np.ndarray
    report: np.ndarray
    objective: float
    evaluations: int
    report_runs: tuple[SeedRun, ...]


def calibrate(table: PressTable, scenario: Scenario, start: RealismProfile, free: Sequence[FreeParameter], *,
              tune_seeds: Sequence[int], report_seeds: Sequence[int], budget: int, fidelity: str | None = None,
              name: str = "fitted", table_name: str = "table", search_seed: int = 0, design: int | None = None,
              fit_a2_sign: bool = False, search: str = "trust-region", tolerances: dict[str, float] | None = None,
              log: Callable[[str], None] = lambda s: None) -> Calibration:
    """Fit ``free`` parameters of ``start`` to ``table`` (module docstring). ``budget``: candidates simulated,
    whichever search asks for them; ``design``: how many of them the Latin hypercube takes (None: a third of the
    budget, at least 2 per parameter; 0: the search straight from the start, to refine a fitted profile);
    ``search``: what follows the design (:data:`~palpate.sim.realism.search.SEARCHES`); ``fit_a2_sign``: the share
    of a2 < 0 in the objective too (``SCALES_WITH_A2_SIGN``; off: ``SCALES``, as every shipped fit);
    ``tolerances``: statistic name (``MOMENTS``) -> tolerance replacing its default (inf: not fitted)."""
    from scipy.stats import qmc

    materials = tuple(m for m in table.materials if m in scenario.references)
    missing = [m for m in table.materials if m not in scenario.references]
    if missing or not materials:
        raise ValidationError(f"{table_name}: material(s) {missing or list(table.materials)} are not reference "
                              f"materials of scenario {scenario.name!r} ({', '.join(scenario.references)})")
    overlap = sorted(set(tune_seeds) & set(report_seeds))
    if overlap or not tune_seeds or not report_seeds:
        raise ValidationError(f"tuning and report seeds must be non-empty and disjoint; shared: {overlap}")
    if budget < 2:
        raise ValidationError(f"the evaluation budget must be >= 2, got {budget}")
    if search not in SEARCHES:
        raise ValidationError(f"unknown search {search!r}; known: {', '.join(SEARCHES)}")
    fidelity = fidelity or scenario.fidelity
    real = real_moments(table, materials)
    scales = with_tolerances(SCALES_WITH_A2_SIGN if fit_a2_sign else SCALES, tolerances or {})
    history: list[tuple[float, np.ndarray]] = []
    fitted_cols = np.isfinite(scales)
    failed = np.full(len(materials) * int(fitted_cols.sum()), np.nan)  # the searches' mark of a failed candidate
    seen: dict[bytes, np.ndarray] = {}

    def residuals(u: np.ndarray) -> np.ndarray:
        u = np.clip(np.asarray(u, dtype=float), 0.0, 1.0)
        if u.tobytes() in seen:
            return seen[u.tobytes()]
        if len(history) >= budget:
            raise BudgetSpent
        values = [p.value(x) for p, x in zip(free, u, strict=True)]
        try:
            prof, sc = with_values(start, free, values), with_scenario(scenario, free, values)
            runs = [simulate_seed(sc, prof, s, fidelity) for s in tune_seeds]
            sim = sim_moments(runs, materials, scenario.references, smooth=True)
            r = ((sim - real) / scales[None, :])[:, fitted_cols].ravel()
        except (PalpateError, ValidationError) as exc:
            r = failed
            log(f"  candidate failed: {exc}")
        j = objective_of(r)
        seen[u.tobytes()] = r
        history.append((j, u))
        best = min(h[0] for h in history)
        log(f"  {len(history):4d}/{budget}  objective {j:10.3f}  best {best:10.3f}  " + ", ".join(
            f"{p.key.split('.')[1]}={v:.3g}" for p, v in zip(free, values, strict=True)))
        return r

    d = len(free)
    start_values = current_values(start, free, scenario)
    moduli = [i for i, p in enumerate(free) if p.key.startswith("young.")]
    if moduli:
        start_values = match_moduli(table, scenario, start, free, start_values, moduli, tune_seeds[0], fidelity, log)
    u0 = np.array([p.position(v) for p, v in zip(free, start_values, strict=True)])
    n_design = min(max(2 * d + 2, budget // 3), budget - 1) if design is None else min(max(design, 1), budget - 1)
    points = qmc.LatinHypercube(d=d, seed=search_seed).random(n_design - 1) if n_design > 1 else np.empty((0, d))
    for u in [u0, *points]:
        residuals(u)
    run_search(search, residuals, min(history, key=lambda h: h[0])[1], budget - len(history), seed=search_seed)
    j_best, u_best = min(history, key=lambda h: h[0])
    values = [p.value(x) for p, x in zip(free, u_best, strict=True)]
    fitted, fitted_scenario = with_values(start, free, values, name=name), with_scenario(scenario, free, values)
    tune_runs = [simulate_seed(fitted_scenario, fitted, s, fidelity) for s in tune_seeds]
    report_runs, report_failed = [], {}
    for s in report_seeds:  # a session that fails on a report seed is reported, it does not discard the fit
        try:
            report_runs.append(simulate_seed(fitted_scenario, fitted, s, fidelity))
        except PalpateError as exc:
            report_failed[str(s)] = f"{type(exc).__name__}: {exc}"
            log(f"  report seed {s} failed: {exc}")
    if not report_runs:
        raise PalpateError(f"calibrate: the fitted profile failed on every report seed {list(report_seeds)}: "
                           f"{report_failed}")
    report_runs = tuple(report_runs)
    tuned = sim_moments(tune_runs, materials, scenario.references, smooth=False)
    report = sim_moments(report_runs, materials, scenario.references, smooth=False)
    tip = fitted_scenario.fingertip
    provenance = {
        "method": "method of simulated moments (sim/realism/calibrate.py): per material log mean n1 and a1, log CV "
                  "of n1 and a1, share of n2 < 0, leave-one-out self posterior, "
                  + ("share of a2 < 0; " if fit_a2_sign else "(a2's sign reported only); ")
                  + f"Latin hypercube then {search}",
        "search": search,
        "fit_a2_sign": bool(fit_a2_sign),
        "tolerances": {m: float(x) for m, x in zip(MOMENTS, scales, strict=True) if np.isfinite(x)},  # the fitted
        "table": table_name, "scenario": scenario.name, "fidelity": fidelity, "started_from": start.name,
        "tune_seeds": [int(s) for s in tune_seeds], "report_seeds": [int(r.seed) for r in report_runs],
        "report_seeds_failed": report_failed,
        "evaluations": len(history), "design": n_design, "objective": j_best, "search_seed": int(search_seed),
        "free": {p.key: v for p, v in zip(free, values, strict=True)},
        "moduli_kpa": {m: fitted_scenario.materials[m].material.young * 1e-3 for m in scenario.references},
        "pad_mm": {"pitch": tip.pitch * 1e3, "sensel": tip.sensel_size * 1e3},
        "moments": {"names": list(MOMENTS), "materials": list(materials),
                    **{f"real_{m}": real[i].tolist() for i, m in enumerate(materials)},
                    **{f"tuned_{m}": tuned[i].tolist() for i, m in enumerate(materials)},
                    **{f"report_{m}": report[i].tolist() for i, m in enumerate(materials)}},
    }
    fitted = replace(fitted, provenance=provenance,
                     description=f"fitted by palpate calibrate realism to {table_name} on scenario {scenario.name} "
                                 f"({fidelity}), from {start.name}")
    return Calibration(fitted, materials, real, tuned, report, j_best, len(history), report_runs)
