"""Which of a realism profile's free parameters one real 10-press-per-material table identifies.

The shipped profile (models/realism/thesis_ch6.toml) was fitted by ``palpate calibrate realism --fit-a2-sign`` to
seed 000's table (10 presses per material) with the free parameters its ``[provenance.free]`` lists. This measures,
through the calibration's own statistics (:data:`~palpate.sim.realism.calibrate.MOMENTS` per material, in units of
:data:`~palpate.sim.realism.calibrate.SCALES_WITH_A2_SIGN`), how well such a table pins each of them down:

1. *Local identifiability* at the shipped values. Each parameter is moved by +-``--step`` in its box position u
   (:class:`~palpate.sim.realism.parameters.FreeParameter`, clipped to [0, 1]) and the moments' Jacobian J (per
   unit of u, i.e. per box width) is the central difference averaged over ``--jacobian-seeds`` simulated sessions
   with common random numbers (the same seeds for + and -). The negative shares enter J smoothed, as the
   calibration's objective has them. Sigma is the covariance of ONE session's moment vector over ``--sessions``
   sessions (other seeds) at the shipped values, with the plain statistics (what a real table gives), plus a
   ridge of ``--ridge`` tolerance^2 on its diagonal (loo_self of a well-separated material hardly varies), its
   inverse scaled by (N - p - 2) / (N - 1) (Hartlap et al. 2007, the bias of an inverted sample covariance).
   The Fisher information of one table's moments is I = J^T Sigma^-1 J; printed: the Cramer-Rao sd of each u
   (sqrt diag I^-1), the sd if all others were known (1 / sqrt I_ii; also with the Jacobian's own Monte Carlo
   noise taken out of I_ii), the CR sd from each half of the Jacobian's seeds, the sd the calibration's unweighted
   objective would reach with its tuning seeds (the method-of-moments sandwich with Sigma (1 + 1/S)), and the
   eigen-structure of I with what the Jacobian's noise adds along each direction. That noise inflates I, so the
   CR sds are optimistic where an eigenvalue is not well above it. Last, a backward elimination: which parameters
   a table identifies once the worst-determined are fixed at their values. A parameter is *identifiable*
   when its CR sd is below ``--threshold`` (0.15) of its box, *weakly (alone)* when only 1 / sqrt I_ii is.
2. *Recovery* at the size used: for each generating seed one session at the shipped values plays the real table,
   and :func:`~palpate.sim.realism.calibrate.calibrate` fits the same free parameters from a start moved
   ``--offset`` box widths off the truth (towards the box's far side: + where u < 0.5, - otherwise; the moduli
   through the scenario, then calibrate's own matching of the moduli to mean n1 moves them) with the shipped
   protocol's tuning seeds (101-104; two report seeds, whose statistics are not used), ``--budget`` candidates
   (default 100) of which ``--design`` a Latin hypercube (default 20; 1: the search from the start, as the
   shipped fit), ``--search`` (trust-region, the command's default, or nelder-mead, as the shipped fit). Printed:
   recovered against true values and the objective at the truth against the fit's.

    .venv/bin/python benchmarks/realism_identifiability.py [--quick] [--jacobian-seeds 48] [--sessions 300]
        [--step 0.05] [--ridge 1e-3] [--threshold 0.15] [--generators 7001,7002,7003] [--budget 100] [--design 20]
        [--search trust-region] [--offset 0.3] [--tune-seeds 101,102,103,104] [--report-seeds 201,202] [--no-recovery]

``--quick`` (a smoke run, about a minute): 2 Jacobian seeds, 30 sessions, no recovery.
"""

from __future__ import annotations

import argparse
import os
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from palpate.core.errors import PalpateError, ValidationError
from palpate.core.perception.param_stats import PressTable
from palpate.core.world.scenario import Scenario
from palpate.core.world.scenario_file import load_scenario
from palpate.sim.realism.calibrate import (
    MOMENTS,
    SCALES_WITH_A2_SIGN,
    calibrate,
    objective,
    real_moments,
    sim_moments,
    simulate_seed,
)
from palpate.sim.realism.parameters import FreeParameter, current_values, free_parameters, with_scenario, with_values
from palpate.sim.realism.profile import RealismProfile
from palpate.sim.realism.profile_file import resolve_profile
from palpate.sim.realism.search import FAILED, SEARCHES

REPO = Path(__file__).resolve().parent.parent
SHORT = {"log_mean_n1": "mean_n1", "log_mean_a1": "mean_a1", "log_cv_n1": "cv_n1", "log_cv_a1": "cv_a1",
         "negative_n2": "neg_n2", "negative_a2": "neg_a2", "loo_self": "loo"}


@dataclass(frozen=True)
class Setup:
    """The scenario, the shipped profile, its free parameters and their shipped values (file units, box u)."""

    scenario: Scenario
    profile: RealismProfile
    free: tuple[FreeParameter, ...]
    truth: np.ndarray
    u_truth: np.ndarray
    fidelity: str

    @property
    def materials(self) -> tuple[str, ...]:
        return tuple(self.scenario.references)

    def labels(self) -> list[str]:
        """One label per moment of the flattened (material, moment) vector."""
        return [f"{m[:2]}{m[-1]}.{SHORT[k]}" if m.startswith("Material_") else f"{m}.{SHORT[k]}"
                for m in self.materials for k in MOMENTS]


def session(setup: Setup, values, seed: int, smooth: bool, scenario: Scenario | None = None) -> np.ndarray:
    """The moments of one simulated training session (flattened, materials x :data:`MOMENTS`) with the free
    parameters at ``values`` (file units; moduli as factors on ``scenario``'s, default the shipped scenario's)."""
    sc = with_scenario(scenario or setup.scenario, setup.free, values)
    run = simulate_seed(sc, with_values(setup.profile, setup.free, values), seed, setup.fidelity)
    return sim_moments([run], setup.materials, setup.scenario.references, smooth).ravel()


def jacobian_samples(setup: Setup, seeds, step: float, log) -> tuple[np.ndarray, int]:
    """Per seed the central difference of the (smoothed) moments with respect to each parameter's box position,
    shape (seeds, moments, parameters) (NaN where a side failed), and how many differences failed."""
    p = len(setup.free)
    out = np.full((len(seeds), len(setup.materials) * len(MOMENTS), p), np.nan)
    failed = 0
    for i in range(p):
        lo, hi = max(setup.u_truth[i] - step, 0.0), min(setup.u_truth[i] + step, 1.0)
        sides = []
        for u in (hi, lo):
            v = setup.truth.copy()
            v[i] = setup.free[i].value(u)
            sides.append(v)
        for k, s in enumerate(seeds):
            try:
                out[k, :, i] = (session(setup, sides[0], s, True) - session(setup, sides[1], s, True)) / (hi - lo)
            except (PalpateError, ValidationError) as exc:
                failed += 1
                log(f"    {setup.free[i].key} seed {s}: {exc}")
        log(f"  d/du {setup.free[i].key:<28} u {lo:.3f}..{hi:.3f}  ({time.process_time():.0f} s CPU so far)")
    return out, failed


def session_samples(setup: Setup, seeds, log) -> tuple[np.ndarray, int]:
    """One session's plain moments per seed at the shipped values, shape (sessions, moments); failures left out."""
    rows, failed = [], 0
    for k, s in enumerate(seeds):
        try:
            rows.append(session(setup, setup.truth, s, False))
        except (PalpateError, ValidationError) as exc:
            failed += 1
            log(f"    session {s}: {exc}")
        if (k + 1) % 50 == 0:
            log(f"  {k + 1} sessions ({time.process_time():.0f} s CPU so far)")
    return np.array(rows), failed


@dataclass(frozen=True)
class Identifiability:
    """Fisher information of one table's moments and what follows from it (all in box units u)."""

    jac: np.ndarray  # (moments, parameters), per box width, in tolerances
    jac_se: np.ndarray
    fisher: np.ndarray
    fisher_noise: np.ndarray  # what the Jacobian's Monte Carlo noise adds to J^T Sigma^-1 J on average
    cr_sd: np.ndarray
    alone_sd: np.ndarray
    alone_sd_denoised: np.ndarray  # 1 / sqrt(I_ii - noise_ii), inf where that is <= 0
    cr_sd_halves: np.ndarray  # (2, parameters): from each half of the Jacobian's seeds
    sandwich_sd: np.ndarray
    eigval: np.ndarray
    eigvec: np.ndarray
    sigma_sd: np.ndarray  # sd of each moment of one session, in tolerances


def _inv_sd(fisher: np.ndarray) -> np.ndarray:
    """sqrt(diag(fisher^-1)), eigenvalues floored at 1e-12 of the largest (a direction the information does not
    determine makes every parameter loading on it practically unbounded)."""
    w, v = np.linalg.eigh(fisher)
    w = np.maximum(w, 1e-12 * max(w.max(), 1e-300))
    return np.sqrt(np.einsum("ij,j,ij->i", v, 1.0 / w, v))


def identifiability(d: np.ndarray, moments: np.ndarray, ridge: float, tune_seeds: int) -> Identifiability:
    """From per-seed differences ``d`` (seeds, moments, parameters) and sessions' ``moments`` (sessions,
    moments), both in file units of the statistics."""
    scale = np.tile(SCALES_WITH_A2_SIGN, d.shape[1] // len(MOMENTS))
    d = d / scale[None, :, None]
    ok = ~np.isnan(d).any(axis=1)  # (seeds, parameters)
    k = ok.sum(axis=0)
    jac = np.array([np.nanmean(d[:, :, i], axis=0) for i in range(d.shape[2])]).T
    jac_se = np.array([np.nanstd(d[:, :, i], axis=0, ddof=1) / np.sqrt(k[i]) for i in range(d.shape[2])]).T
    z = moments / scale[None, :]
    n, q = z.shape
    sigma = np.cov(z, rowvar=False) + ridge * np.eye(q)
    w = np.linalg.inv(sigma) * max(n - q - 2, 1) / (n - 1)
    fisher = jac.T @ w @ jac
    # the same from each half of the Jacobian's seeds: how much the CR sd itself moves with the Monte Carlo
    halves = []
    for part in (d[: len(d) // 2], d[len(d) // 2:]):
        jh = np.array([np.nanmean(part[:, :, i], axis=0) for i in range(d.shape[2])]).T
        halves.append(_inv_sd(jh.T @ w @ jh))
    # E[Jhat^T W Jhat] = J^T W J + tr(W Cov(jhat_a, jhat_b)): the Jacobian's noise inflates I
    both = ok.all(axis=1)
    r = d[both] - d[both].mean(axis=0)
    noise = np.einsum("kma,mn,knb->ab", r, w, r) / max(both.sum() - 1, 1) / max(both.sum(), 1)
    # the calibration's estimator: unit weights on the tolerance-scaled moments, its simulated side the mean of S
    # tuning seeds (independent of the table): Var = (J'J)^-1 J' Sigma (1 + 1/S) J (J'J)^-1
    jtj_inv = np.linalg.pinv(jac.T @ jac)
    sandwich = jtj_inv @ jac.T @ (np.cov(z, rowvar=False) * (1 + 1 / tune_seeds)) @ jac @ jtj_inv
    eigval, eigvec = np.linalg.eigh(fisher)
    order = np.argsort(eigval)[::-1]
    return Identifiability(jac, jac_se, fisher, noise, _inv_sd(fisher), 1 / np.sqrt(np.diag(fisher)),
                           1 / np.sqrt(np.clip(np.diag(fisher - noise), 1e-300, None)), np.array(halves),
                           np.sqrt(np.clip(np.diag(sandwich), 0, None)), eigval[order], eigvec[:, order],
                           np.sqrt(np.diag(np.cov(z, rowvar=False))))


def _short(key: str) -> str:
    return key.split(".", 1)[1]


def _sd(x: float) -> str:
    return f"{x:.3f}" if x <= 1 else ">1"


def _file_sd(p: FreeParameter, u: float, sd_u: float) -> str:
    """An sd in box units as the file's units at u (a factor for a log box)."""
    if sd_u > 1:
        return "-"
    if p.log:
        return f"x{np.exp(sd_u * np.log(p.hi / p.lo)):.3g}"
    return f"{sd_u * (p.hi - p.lo):.3g}"


def report_local(setup: Setup, res: Identifiability, threshold: float, tune_seeds: int) -> str:
    names = [_short(p.key) for p in setup.free]
    labels = setup.labels()
    w = max(len(n) for n in names) + 2
    lines = ["", "Jacobian d(moment / tolerance) / d(box position u): tolerances per box width (mean over the "
             "Jacobian seeds; in parentheses: within 2 standard errors of 0)",
             f"{'moment':<16}{'1-table sd':>11}" + "".join(f"{n[:12]:>13}" for n in names)]
    for m, lab in enumerate(labels):
        cells = []
        for i in range(len(names)):
            v, se = res.jac[m, i], res.jac_se[m, i]
            cells.append(f"{v:>13.2f}" if abs(v) >= 2 * se else f"{f'({v:.2f})':>13}")
        lines.append(f"{lab:<16}{res.sigma_sd[m]:>11.2f}" + "".join(cells))
    lines += ["", f"Per parameter (box units u; identifiable: CR sd < {threshold} of the box; weakly (alone): only "
              "1/sqrt(I_ii) is)",
              f"{'parameter':<{w}}{'true':>10}{'u':>7}{'CR sd':>8}{'file':>9}{'alone':>8}{'halves':>14}"
              f"{'alone-nz':>10}{'calib':>8}  verdict"]
    for i, p in enumerate(setup.free):
        cr, alone = res.cr_sd[i], res.alone_sd[i]
        verdict = "identifiable" if cr < threshold else "weakly (alone)" if alone < threshold else "not identifiable"
        halves = f"{_sd(res.cr_sd_halves[0, i])}/{_sd(res.cr_sd_halves[1, i])}"
        lines.append(f"{names[i]:<{w}}{setup.truth[i]:>10.4g}{setup.u_truth[i]:>7.3f}{_sd(cr):>8}"
                     f"{_file_sd(p, setup.u_truth[i], cr):>9}{_sd(alone):>8}{halves:>14}"
                     f"{_sd(res.alone_sd_denoised[i]):>10}{_sd(res.sandwich_sd[i]):>8}  {verdict}")
    lines += ["  CR sd: sqrt(diag I^-1); file: the same in the file's units (xF: a factor); alone: 1/sqrt(I_ii), the "
              "others known; halves: CR sd from each half of the Jacobian seeds; alone-nz: alone with the "
              "Jacobian's Monte Carlo noise taken out of I_ii; >1: more than the whole box; calib: sd of the "
              f"calibration's own estimator (unit weights on the tolerance-scaled moments, {tune_seeds} tuning "
              "seeds), linearised",
              "", "Eigen-structure of I (box units): sd along each direction = 1/sqrt(eigenvalue); noise: what the "
              "Jacobian's Monte Carlo noise adds to the eigenvalue on average (v' N v); components |c| < 0.1 left "
              "blank",
              f"{'eigenvalue':>11}{'noise':>8}{'sd':>8}" + "".join(f"{n[:12]:>13}" for n in names)]
    for j, lam in enumerate(res.eigval):
        v = res.eigvec[:, j]
        comps = "".join(f"{c:>13.2f}" if abs(c) >= 0.1 else f"{'':>13}" for c in v)
        lines.append(f"{lam:>11.3g}{v @ res.fisher_noise @ v:>8.3g}{1 / np.sqrt(max(lam, 1e-300)):>8.3f}{comps}")
    return "\n".join(lines)


def report_elimination(setup: Setup, res: Identifiability, threshold: float) -> str:
    """Backward elimination on I: fix (at its value) the parameter with the largest CR sd, recompute the others'
    from the information of those left, until every one left is below the threshold."""
    names = [_short(p.key) for p in setup.free]
    keep = list(range(len(names)))
    lines = ["", f"Backward elimination (fix the worst at its value, CR sd of the rest from their block of I; stop "
             f"when all < {threshold})", "".join(f"{n[:12]:>13}" for n in names) + "  fixed next"]
    while keep:
        sd = _inv_sd(res.fisher[np.ix_(keep, keep)])
        full = np.full(len(names), np.nan)
        full[keep] = sd
        worst = keep[int(np.argmax(sd))]
        done = sd.max() < threshold
        lines.append("".join(f"{'fixed':>13}" if np.isnan(x) else f"{_sd(x):>13}" for x in full)
                     + ("  (all identifiable)" if done else f"  {names[worst]}"))
        if done:
            break
        keep.remove(worst)
    return "\n".join(lines)


def start_point(setup: Setup, offset: float) -> np.ndarray:
    """The box positions of the start: each truth moved ``offset`` towards its box's far side."""
    return np.where(setup.u_truth < 0.5, setup.u_truth + offset, setup.u_truth - offset)


def recovery(setup: Setup, generator: int, args, log) -> dict:
    """Fit a session simulated at the shipped values (seed ``generator``) from the off-truth start."""
    run = simulate_seed(setup.scenario, with_values(setup.profile, setup.free, setup.truth), generator,
                        setup.fidelity)
    table = PressTable(run.table.materials, run.table.rows)
    u0 = start_point(setup, args.offset)
    v0 = np.array([p.value(u) for p, u in zip(setup.free, u0, strict=True)])
    moduli = np.array([p.key.startswith("young.") for p in setup.free])
    # the start's moduli go through the scenario (a profile carries none); the fit's factors are on that scenario
    start_scenario = with_scenario(setup.scenario, setup.free, v0)
    start = with_values(setup.profile, setup.free, v0, name="start")
    real = real_moments(table, setup.materials)

    def j_at(values, scenario):
        try:
            sim = np.mean([session(setup, values, s, True, scenario).reshape(real.shape) for s in args.tune],
                          axis=0)
        except (PalpateError, ValidationError):
            return FAILED  # a tuning session the drive cannot follow: the search scores such a candidate the same
        return objective(sim, real, SCALES_WITH_A2_SIGN)

    j_truth = j_at(setup.truth, setup.scenario)
    j_start = j_at(v0, setup.scenario)
    # the report seeds are not used here; calibrate skips one whose session fails (a press the rigid drive cannot
    # follow, ~3% of sessions on the hard foam), so two of them
    result = calibrate(table, start_scenario, start, setup.free, tune_seeds=args.tune, report_seeds=args.report,
                       budget=args.budget, fidelity=setup.fidelity, name="recovered",
                       table_name=f"session {generator}", design=args.design, fit_a2_sign=True, search=args.search,
                       log=log)
    prov = result.profile.provenance["free"]
    fitted = np.array([prov[p.key] * (v0[i] if moduli[i] else 1.0) for i, p in enumerate(setup.free)])
    return {"seed": generator, "fit": fitted, "u_fit": np.array([p.position(v) for p, v in zip(setup.free, fitted,
                                                                                              strict=True)]),
            "u_start": u0, "start": v0, "j_truth": j_truth, "j_start": j_start, "j_fit": result.objective,
            "evaluations": result.evaluations}


def report_recovery(setup: Setup, fits: list[dict], cr_sd: np.ndarray) -> str:
    names = [_short(p.key) for p in setup.free]
    w = max(len(n) for n in names) + 2
    head = f"{'parameter':<{w}}{'true':>9}{'start':>9}" + "".join(f"{'seed ' + str(f['seed']):>18}" for f in fits)
    lines = ["", "Recovery: fitted value (file units) and box error u_fit - u_true; moduli as factors on the shipped "
             "scenario's", head]
    for i, n in enumerate(names):
        cells = "".join(f"{f['fit'][i]:>9.3g}{f['u_fit'][i] - setup.u_truth[i]:>+9.2f}" for f in fits)
        lines.append(f"{n:<{w}}{setup.truth[i]:>9.3g}{fits[0]['start'][i]:>9.3g}{cells}")
    rms = [np.sqrt(np.mean((f["u_fit"] - setup.u_truth) ** 2)) for f in fits]
    lines.append(f"{'rms box error':<{w}}{'':>9}{np.sqrt(np.mean((fits[0]['u_start'] - setup.u_truth) ** 2)):>9.2f}"
                 + "".join(f"{'':>9}{r:>9.2f}" for r in rms))
    lines.append("Objective (tuning seeds, a2's sign fitted): at the truth / at the start / at the fit; evaluations")
    for f in fits:
        verdict = "fit below truth: the table cannot tell them apart" if f["j_fit"] < f["j_truth"] else \
            "fit above truth: search not converged to the truth's level"
        lines.append(f"  seed {f['seed']}: {f['j_truth']:8.2f} / {f['j_start']:8.2f} / {f['j_fit']:8.2f}; "
                     f"{f['evaluations']}  ({verdict})")
    within = np.mean([np.abs(f["u_fit"] - setup.u_truth) <= 2 * cr_sd for f in fits], axis=0)
    lines.append("share of fits within 2 CR sd of the truth: " + ", ".join(
        f"{n} {s:.2f}" for n, s in zip(names, within, strict=True)))
    return "\n".join(lines)


def _seeds(text: str) -> list[int]:
    return [int(s) for s in text.split(",") if s.strip()]


def main() -> int:
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, "1")
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", type=Path, default=REPO / "scenarios" / "thesis_ch6.toml")
    ap.add_argument("--profile", default=str(REPO / "models" / "realism" / "thesis_ch6.toml"),
                    help="the profile whose [provenance.free] parameters are studied at its values")
    ap.add_argument("--free", default=None, help="comma-separated free parameters (default: the profile's "
                    "[provenance.free])")
    ap.add_argument("--fidelity", default=None, help="default: the scenario's")
    ap.add_argument("--jacobian-seeds", type=int, default=48, help="sessions per finite difference (default 48)")
    ap.add_argument("--jacobian-seed0", type=int, default=5001)
    ap.add_argument("--sessions", type=int, default=300, help="sessions for Sigma (default 300)")
    ap.add_argument("--session-seed0", type=int, default=6001)
    ap.add_argument("--step", type=float, default=0.05, help="finite-difference step in box units (default 0.05)")
    ap.add_argument("--ridge", type=float, default=1e-3, help="ridge on Sigma, in tolerance^2 (default 1e-3)")
    ap.add_argument("--threshold", type=float, default=0.15, help="CR sd (box widths) for identifiable")
    ap.add_argument("--generators", default="7001,7002,7003", help="seeds of the sessions that play the table")
    ap.add_argument("--budget", type=int, default=100, help="candidates per recovery fit (default 100)")
    ap.add_argument("--design", type=int, default=20, help="Latin hypercube points among them (default 20; 1: the "
                    "search from the start, as the shipped fit)")
    ap.add_argument("--search", default="trust-region", choices=SEARCHES,
                    help="the recovery fits' search after the design (default trust-region, the command's)")
    ap.add_argument("--offset", type=float, default=0.3, help="start's distance from the truth in box units")
    ap.add_argument("--tune-seeds", default="101,102,103,104")
    ap.add_argument("--report-seeds", default="201,202", help="the fit's report seeds (unused here)")
    ap.add_argument("--no-recovery", action="store_true")
    ap.add_argument("--quick", action="store_true", help="smoke run: 2 Jacobian seeds, 30 sessions, no recovery")
    ap.add_argument("--verbose", action="store_true", help="every candidate of the recovery fits")
    args = ap.parse_args()
    if args.quick:
        args.jacobian_seeds, args.sessions, args.no_recovery = 2, 30, True
    args.tune, args.report = _seeds(args.tune_seeds), _seeds(args.report_seeds)

    def log(s: str) -> None:
        print(s, flush=True)

    scenario = load_scenario(args.scenario)
    profile = resolve_profile(args.profile)
    keys = args.free.split(",") if args.free else list(profile.provenance["free"])
    free = free_parameters(keys, scenario.references)
    truth = np.array(current_values(profile, free))
    setup = Setup(scenario, profile, free, truth, np.array([p.position(v) for p, v in zip(free, truth, strict=True)]),
                  args.fidelity or scenario.fidelity)
    print(f"realism identifiability: profile {profile.name} on scenario {scenario.name} ({setup.fidelity}), "
          f"{len(free)} free parameters; moments {len(setup.labels())} ({len(MOMENTS)} per material, tolerances "
          f"SCALES_WITH_A2_SIGN); step {args.step} u; {args.jacobian_seeds} Jacobian seeds from "
          f"{args.jacobian_seed0}; {args.sessions} sessions for Sigma from {args.session_seed0}; ridge {args.ridge}",
          flush=True)
    t0 = time.process_time()
    d, failed_d = jacobian_samples(setup, range(args.jacobian_seed0, args.jacobian_seed0 + args.jacobian_seeds),
                                   args.step, log)
    t_jac = time.process_time() - t0
    z, failed_s = session_samples(setup, range(args.session_seed0, args.session_seed0 + args.sessions), log)
    t_sig = time.process_time() - t0 - t_jac
    res = identifiability(d, z, args.ridge, len(args.tune))
    print(f"Jacobian: {2 * args.jacobian_seeds * len(free)} sessions, {failed_d} differences failed, "
          f"{t_jac:.0f} s CPU; Sigma: {len(z)} sessions ({failed_s} failed), {t_sig:.0f} s CPU")
    print(report_local(setup, res, args.threshold, len(args.tune)), flush=True)
    print(report_elimination(setup, res, args.threshold), flush=True)
    if not args.no_recovery:
        print(f"\nRecovery: generating seeds {args.generators}; start {args.offset} box widths off the truth "
              f"(+ where u < 0.5, - otherwise); tuning seeds {args.tune}, report seeds {args.report}, budget "
              f"{args.budget}, design {args.design}, search {args.search}, --fit-a2-sign", flush=True)
        fits = []
        for g in _seeds(args.generators):
            t1 = time.process_time()
            fits.append(recovery(setup, g, args, log if args.verbose else lambda s: None))
            print(f"  seed {g}: objective {fits[-1]['j_fit']:.2f} (truth {fits[-1]['j_truth']:.2f}), "
                  f"{time.process_time() - t1:.0f} s CPU", flush=True)
        print(report_recovery(setup, fits, res.cr_sd))
    print(f"\ntotal {time.process_time() - t0:.0f} s CPU")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
