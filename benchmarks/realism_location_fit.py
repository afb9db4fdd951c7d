"""A realism fit on the joint locations of the per-press parameters, with the pad, the press's stops, the pad's
crosstalk and the pulp's area free: does it pass the predictive check?

The shipped profile was fitted on moments (log means of n1 and a1, CVs, sign shares, leave-one-out); the check it
fails reads the joint [n1, n2, a1, a2]. This fit's residuals are, per material and per column of [n1, n2, a1, a2],
the real table's mean less the simulated presses' mean over a spread (``--spread sim``: a simulated press's
within-session spread; ``pooled``: the root mean square of that and the real table's), and the log ratio of the
real and the simulated within-session spreads: what a discriminant between one session and the real table sees.
Free (:data:`SPACE`): the pad's pitch and sensel share (seed 000 does not give them), its sensitivity, turn-on
pressure and its spread, non-linearity and crosstalk, the pulp's area factor, stiffening and stiffness spread, the
press's push-back force, compliance stop and depth spread, the moduli of Material_1 and Material_2 (factors), the
sponge's plateau strain, the tracker's white noise and clock wander. Least squares (trust region reflective, forward
differences of 0.08 box widths) on tuning seeds 2001-2008 (common random numbers), from the shipped values with
``--start`` over them; ``--judge`` simulates 100 fresh sessions from ``--first`` for a candidate and runs the check.

    .venv/bin/python benchmarks/realism_location_fit.py [--budget 15] [--seeds 8] [--spread sim|pooled]
        [--start START.json] [--log fit.jsonl]
    .venv/bin/python benchmarks/realism_location_fit.py --judge CANDIDATE.json [--first 5001] [--sessions 100]

Measured: ``--start benchmarks/data/realism_location_start.json`` (a 4 mm pitch pad of 1.8 mm sensels, the pulp's
area factor 7.9, sensitivity 12, no crosstalk), then ``--spread pooled --budget 12`` from its best, gave
``benchmarks/data/realism_location_fitted.json``; judged on 5001-5100 while fitting and on 1001-1100 to report.
"""

from __future__ import annotations

import argparse
import copy
import json
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares

from palpate.core.errors import PalpateError
from palpate.core.perception.param_stats import PARAM_INDEX, table_from_csv
from palpate.core.perception.predictive_check import predictive_check
from palpate.core.world.scenario_file import load_scenario
from palpate.sim.realism.calibrate import simulate_seed
from palpate.sim.realism.parameters import free_parameters, with_scenario
from palpate.sim.realism.profile_file import parse_profile, profile_tables, resolve_profile

sys.path.insert(0, str(Path(__file__).resolve().parent))
from realism_predictive import format_check  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
SCENARIO = REPO / "scenarios" / "thesis_ch6.toml"
#: The search space: key, low, high, searched in log. ``scenario.*`` keys change the scenario, ``young.*`` a
#: reference's modulus (a factor), the others the profile.
SPACE = (
    ("scenario.pitch_mm", 2.0, 5.0, False),
    ("scenario.sensel_share", 0.4, 0.95, False),
    ("taxels.sensitivity", 1.0, 40.0, True),
    ("taxels.activation_kpa", 0.2, 20.0, True),
    ("taxels.activation_cv", 0.0, 1.0, False),
    ("taxels.nonlinearity", 0.0, 1.0, False),
    ("taxels.crosstalk", 0.0, 0.02, False),
    ("finger.area_factor", 1.0, 9.5, False),
    ("finger.stiffening_per_mm", 0.3, 3.0, True),
    ("finger.stiffness_cv", 0.05, 1.0, True),
    ("press.push_force_n", 0.3, 4.0, True),
    ("press.push_stiffness_n_per_mm", 0.3, 4.0, True),
    ("press.depth_cv", 0.005, 0.3, True),
    ("young.Material_1", 0.1, 2.0, True),
    ("young.Material_2", 0.5, 3.0, True),
    ("material.plateau_strain", 0.0, 0.1, False),
    ("scenario.pose_noise_mm", 0.003, 0.3, True),
    ("pose.clock_wander_ms", 0.5, 40.0, True),
)
IDX = list(PARAM_INDEX)
#: Residuals per candidate: 3 materials x 4 columns x (mean, spread).
RESIDUALS = 24


def values_at(u: np.ndarray) -> dict[str, float]:
    """The candidate at box positions ``u`` (clipped to [0, 1])."""
    out = {}
    for (key, lo, hi, log), x in zip(SPACE, np.clip(u, 0.0, 1.0), strict=True):
        out[key] = float(np.exp(np.log(lo) + x * np.log(hi / lo))) if log else lo + x * (hi - lo)
    return out


def position_of(values: dict[str, float]) -> np.ndarray:
    """Box positions of ``values``, clipped into (0, 1) (a value off its box, such as an unused stop's 0, starts at
    the box's end)."""
    with np.errstate(divide="ignore"):
        u = [(np.log(values[k] / lo) / np.log(hi / lo)) if log else (values[k] - lo) / (hi - lo)
             for k, lo, hi, log in SPACE]
    return np.clip(np.nan_to_num(np.array(u), neginf=0.0, posinf=1.0), 0.01, 0.99)


def shipped_values(scenario, profile) -> dict[str, float]:
    """The shipped scenario's and profile's values of :data:`SPACE`."""
    tables = profile_tables(profile)
    tip = scenario.fingertip
    out = {"scenario.pitch_mm": tip.pitch * 1e3, "scenario.sensel_share": tip.sensel_size / tip.pitch,
           "scenario.pose_noise_mm": scenario.pose.noise_std * 1e3, "young.Material_1": 1.0, "young.Material_2": 1.0}
    for key, *_ in SPACE:
        if key not in out:
            section, name = key.split(".")
            out[key] = float(tables[section][name])
    return out


def candidate(scenario, profile, values: dict[str, float]):
    """(scenario, profile) of a candidate."""
    tables = copy.deepcopy(profile_tables(profile))
    tables.pop("provenance", None)
    for key, v in values.items():
        section, name = key.split(".")
        if section not in ("scenario", "young"):
            tables[section][name] = float(v)
    moduli = [k for k in values if k.startswith("young.")]
    sc = with_scenario(scenario, free_parameters(moduli, scenario.references), [values[k] for k in moduli])
    pitch = values["scenario.pitch_mm"] * 1e-3
    sc = replace(sc, fingertip=replace(sc.fingertip, pitch=pitch, sensel_size=values["scenario.sensel_share"] * pitch),
                 pose=replace(sc.pose, noise_std=values["scenario.pose_noise_mm"] * 1e-3))
    return sc, parse_profile(tables, "<candidate>", profile.name)


def session(args):
    """One training session's table, or None when the simulation could not finish it."""
    values, seed = args
    scenario = load_scenario(SCENARIO)
    sc, prof = candidate(scenario, resolve_profile(scenario.realism.profile), values)
    try:
        return simulate_seed(sc, prof, seed, sc.fidelity).table
    except PalpateError:
        return None


def residuals(tables, real, pooled: bool) -> np.ndarray:
    """Per material and column of [n1, n2, a1, a2]: the mean's difference over a spread, and the log spread ratio."""
    out = []
    for m in real.materials:
        rows = [t.of(m)[:, IDX] for t in tables if len(t.of(m)) >= 3]
        spread = np.vstack([r - r.mean(axis=0) for r in rows]).std(axis=0) + 1e-12
        mine = real.of(m)[:, IDX]
        scale = np.sqrt(0.5 * (spread**2 + mine.std(axis=0, ddof=1) ** 2)) if pooled else spread
        out += list((mine.mean(axis=0) - np.vstack(rows).mean(axis=0)) / scale)
        out += list(np.log(mine.std(axis=0, ddof=1) / spread))
    return np.array(out)


def fit(budget: int, seeds: list[int], start: dict[str, float], pooled: bool, log: Path | None) -> None:
    """Least squares from ``start`` (over the shipped values); every better candidate printed (and logged)."""
    scenario = load_scenario(SCENARIO)
    real = table_from_csv(scenario.realism.real_params)
    x0 = position_of(shipped_values(scenario, resolve_profile(scenario.realism.profile)) | start)
    best = [np.inf]
    with ProcessPoolExecutor(2) as ex:
        def fun(u):
            values = values_at(u)
            tables = [t for t in ex.map(session, [(values, s) for s in seeds]) if t is not None]
            if len(tables) < len(seeds) // 2:
                return np.full(RESIDUALS, 10.0)
            r = residuals(tables, real, pooled)
            val = float(np.sum(r**2))
            if val < best[0]:
                best[0] = val
                print(f"{val:8.2f} {json.dumps({k: round(v, 4) for k, v in values.items()})}", flush=True)
                if log is not None:
                    with open(log, "a", encoding="utf-8") as f:
                        f.write(json.dumps({"objective": val, "values": values, "residuals": r.round(2).tolist()})
                                + "\n")
            return r

        least_squares(fun, x0, bounds=(0, 1), diff_step=0.08, max_nfev=budget)


def judge(values: dict[str, float], sessions: int, first: int) -> None:
    """The predictive check of a candidate over ``sessions`` finished sessions from seed ``first``."""
    scenario = load_scenario(SCENARIO)
    real = table_from_csv(scenario.realism.real_params)
    full = shipped_values(scenario, resolve_profile(scenario.realism.profile)) | values
    t0 = time.perf_counter()
    tables, seed = [], first
    with ProcessPoolExecutor(2) as ex:
        while len(tables) < sessions:
            batch = list(range(seed, seed + sessions - len(tables)))
            seed += len(batch)
            tables += [t for t in ex.map(session, [(full, s) for s in batch]) if t is not None]
    print(f"{len(tables)} sessions (seeds {first}-{seed - 1}) in {time.perf_counter() - t0:.0f} s")
    print(format_check(predictive_check(real, tables, list(scenario.references))))


def _values(path: Path | None) -> dict[str, float]:
    if path is None:
        return {}
    values = json.loads(path.read_text(encoding="utf-8"))
    unknown = set(values) - {k for k, *_ in SPACE}
    if unknown:
        raise SystemExit(f"{path}: unknown keys {sorted(unknown)}")
    return {k: float(v) for k, v in values.items()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--budget", type=int, default=15, help="least-squares iterations' function evaluations")
    ap.add_argument("--seeds", type=int, default=8, help="tuning seeds from 2001")
    ap.add_argument("--spread", choices=("sim", "pooled"), default="sim")
    ap.add_argument("--start", type=Path, help="JSON of SPACE values to start from (the rest shipped)")
    ap.add_argument("--log", type=Path, default=None, help="append each better candidate (JSON lines)")
    ap.add_argument("--judge", type=Path, default=None, help="JSON of a candidate's SPACE values (the rest shipped)")
    ap.add_argument("--first", type=int, default=1001, help="first seed the judge simulates")
    ap.add_argument("--sessions", type=int, default=100)
    args = ap.parse_args()
    if args.judge:
        judge(_values(args.judge), args.sessions, args.first)
    else:
        fit(args.budget, list(range(2001, 2001 + args.seeds)), _values(args.start), args.spread == "pooled", args.log)


if __name__ == "__main__":
    main()
