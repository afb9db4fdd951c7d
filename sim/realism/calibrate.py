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

The scenario's moduli may be fitted too (free parameters ``young.<material>``: a factor on that reference material's
Young's modulus): with a compliant finger n1 no longer scales with the modulus, so moduli chosen from the table's
ratios of mean n1 under a rigid finger are not those that reproduce them. The fitted moduli are not part of the
profile: they are reported (``provenance.moduli_kpa``) for the scenario's ``young_kpa``.
"""

from __future__ import annotations

import copy
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
from palpate.sim.realism.profile import RealismProfile
from palpate.sim.realism.profile_file import parse_profile, profile_tables
from palpate.sim.realism.search import SEARCHES, BudgetSpent, objective_of, run_search
from palpate.sim.source import SimSource


@dataclass(frozen=True)
class FreeParameter:
    """One fitted parameter: its key in the profile file (``section.key``, file units) and its search box.

    ``off``: a value outside the box that turns the parameter off (``press.tail_dof`` = 0); a start there begins
    at the box's end nearest to off (``hi``: the gentlest tail).
    """

    key: str
    lo: float
    hi: float
    log: bool = False
    off: float | None = None

    def value(self, u: float) -> float:
        """The parameter at position u in [0, 1] of its box."""
        u = float(np.clip(u, 0.0, 1.0))
        if self.log:
            return float(np.exp(np.log(self.lo) + u * (np.log(self.hi) - np.log(self.lo))))
        return self.lo + u * (self.hi - self.lo)

    def position(self, v: float) -> float:
        """The position in [0, 1] of the value v (clipped into the box)."""
        if self.off is not None and v == self.off:
            return 1.0
        v = float(np.clip(v, self.lo, self.hi))
        if self.log:
            return float((np.log(v) - np.log(self.lo)) / (np.log(self.hi) - np.log(self.lo)))
        return (v - self.lo) / (self.hi - self.lo)


#: Parameters the command may fit, with their search boxes (physically plausible ranges; docs/realism.md).
FREE_PARAMETERS = {p.key: p for p in (
    FreeParameter("finger.stiffness_n_per_mm", 0.2, 5.0, log=True),
    FreeParameter("finger.stiffening_per_mm", 0.0, 3.0),
    # Up to just below the profile's own bound ([0, 10)): Serina et al. 1998's ~1 cm^2 at 1 N asks ~7.9 (area
    # pi R area_factor delta, R 8 mm, delta 0.51 mm at 1 N on the shipped pulp; docs/realism.md), beyond the
    # old box's 4.
    FreeParameter("finger.area_factor", 1.0, 9.5),
    FreeParameter("finger.stiffness_cv", 0.0, 0.8),
    FreeParameter("finger.pressure_exponent", 0.5, 2.5),
    FreeParameter("press.speed_cv", 0.0, 0.4),
    FreeParameter("press.depth_cv", 0.0, 0.4),
    FreeParameter("press.tilt_deg", 0.0, 12.0),
    FreeParameter("press.slip", 0.0, 0.3),
    FreeParameter("press.tremor_mm", 0.0, 0.3),
    FreeParameter("press.force_scale", 0.05, 1.0, log=True),
    FreeParameter("press.push_force_n", 0.0, 2.0),
    FreeParameter("press.push_depth_scale", 1.0, 4.0),
    FreeParameter("press.push_stiffness_n_per_mm", 0.0, 3.0),
    FreeParameter("press.tail_dof", 1.5, 50.0, log=True, off=0.0),
    FreeParameter("taxels.sensitivity", 0.5, 99.9, log=True),  # the profile refuses 100 ([0.01, 100))
    FreeParameter("taxels.gain_spread", 0.0, 0.3),
    FreeParameter("taxels.gain_drift", 0.0, 0.08),
    FreeParameter("taxels.hysteresis", 0.0, 0.3),
    FreeParameter("taxels.creep", 0.0, 0.2),
    FreeParameter("taxels.nonlinearity", 0.0, 3.0),
    FreeParameter("taxels.activation_kpa", 0.0, 5.0),
    FreeParameter("taxels.activation_cv", 0.0, 1.5),
    FreeParameter("pose.latency_ms", -30.0, 30.0),
    FreeParameter("pose.clock_offset_ms", 0.0, 60.0),
    FreeParameter("pose.clock_wander_ms", 0.0, 60.0),
    FreeParameter("material.relaxation", 0.0, 0.6),
    FreeParameter("material.softening", 0.0, 0.3),
    FreeParameter("material.plateau_strain", 0.02, 0.2),
    FreeParameter("material.densify_strain", 0.1, 0.4),
)}
#: What the command fits unless told otherwise: location (pulp stiffness, pad sensitivity) and spread.
DEFAULT_FREE = ("finger.stiffness_n_per_mm", "finger.stiffening_per_mm", "finger.stiffness_cv", "press.depth_cv",
                "taxels.sensitivity", "taxels.nonlinearity", "taxels.gain_drift", "pose.clock_wander_ms",
                "material.relaxation")


#: Search box of a factor on a reference material's modulus (``young.<material>``): the scenario's moduli are
#: taken as right to within a factor of 3 (a foam is not a steel; an unbounded factor lets a modulus stand in for
#: whatever the other parameters cannot reproduce).
MODULUS_FACTOR_BOX = (1.0 / 3.0, 3.0)


#: The pad's geometry, which seed 000 does not give: its sensel pitch (mm; Tekscan pads of 4x4 sensels on a
#: fingertip space them ~1.8-3.2 mm apart) and the share of it a sensel's side covers (the rest is the gap between
#: sensels). The scenario's [fingertip] pitch_mm and sensel_mm, not the profile's.
PAD_PARAMETERS = {p.key: p for p in (FreeParameter("pad.pitch_mm", 1.8, 3.2), FreeParameter("pad.fill", 0.5, 1.0))}


def free_parameters(keys: Sequence[str], references: Sequence[str] = ()) -> tuple[FreeParameter, ...]:
    """The free parameters named by ``keys`` (``young.<material>`` for one of ``references``, ``pad.*`` of
    :data:`PAD_PARAMETERS`); ValidationError naming the unknown ones and the known."""
    moduli = {f"young.{m}": FreeParameter(f"young.{m}", *MODULUS_FACTOR_BOX, log=True) for m in references}
    known = {**FREE_PARAMETERS, **PAD_PARAMETERS, **moduli}
    unknown = [k for k in keys if k not in known]
    if unknown or not keys:
        raise ValidationError(f"unknown free parameter(s) {unknown or '(none given)'}; known: {', '.join(known)}")
    if len(set(keys)) != len(keys):
        raise ValidationError(f"free parameters repeat: {list(keys)}")
    return tuple(known[k] for k in keys)


def _scenario_key(key: str) -> bool:
    """Whether a free parameter is the scenario's (a modulus factor, the pad) rather than the profile's."""
    return key.startswith(("young.", "pad."))


def with_scenario(scenario: Scenario, free: Sequence[FreeParameter], values: Sequence[float]) -> Scenario:
    """The scenario with each ``young.<material>`` factor applied to that material's modulus and the pad's
    ``pad.pitch_mm`` and ``pad.fill`` (sensel side over pitch) set."""
    materials = dict(scenario.materials)
    tip = scenario.fingertip
    pitch, fill = tip.pitch * 1e3, tip.sensel_size / tip.pitch
    for p, v in zip(free, values, strict=True):
        if p.key.startswith("young."):
            entry = materials[p.key[6:]]
            materials[p.key[6:]] = replace(entry, material=replace(entry.material, young=entry.material.young * v))
        elif p.key == "pad.pitch_mm":
            pitch = float(v)
        elif p.key == "pad.fill":
            fill = float(v)
    if any(p.key.startswith("pad.") for p in free):
        tip = replace(tip, pitch=pitch * 1e-3, sensel_size=fill * pitch * 1e-3)
    return replace(scenario, materials=materials, fingertip=tip)


def with_values(profile: RealismProfile, free: Sequence[FreeParameter], values: Sequence[float],
                name: str | None = None) -> RealismProfile:
    """The profile with each free parameter set to its value (file units), validated as a file would be."""
    tables = copy.deepcopy(profile_tables(profile))
    for p, v in zip(free, values, strict=True):
        section, key = p.key.split(".", 1)
        if _scenario_key(p.key):
            continue  # the scenario's, not the profile's (with_scenario)
        tables.setdefault(section, {})[key] = float(v)
    if name is not None:
        tables["profile"]["name"] = name
    tables.pop("provenance", None)
    return parse_profile(tables, "<calibration>", profile.name)


def current_values(profile: RealismProfile, free: Sequence[FreeParameter],
                   scenario: Scenario | None = None) -> list[float]:
    """The free parameters' values in ``profile`` (file units): a modulus factor is 1, the pad's are
    ``scenario``'s (ValidationError without it)."""
    tables = profile_tables(profile)
    out = []
    for p in free:
        if p.key.startswith("young."):
            out.append(1.0)
        elif p.key.startswith("pad."):
            if scenario is None:
                raise ValidationError(f"{p.key} is the scenario's pad: its value needs the scenario")
            tip = scenario.fingertip
            out.append(tip.pitch * 1e3 if p.key == "pad.pitch_mm" else tip.sensel_size / tip.pitch)
        else:
            out.append(float(tables[p.key.split(".")[0]][p.key.split(".")[1]]))
    return out


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
