"""A realism fit on the locations of the per-press parameters, with the pad and the tracker free: does it pass the
predictive check?

The shipped profile was fitted on moments (log means of n1 and a1, CVs, sign shares, leave-one-out); the check it
fails reads the joint [n1, n2, a1, a2]. This fit scores a candidate by, per material and per column of
[n1, n2, a1, a2], the real table's mean against the simulated presses' mean in units of a simulated press's
within-session spread (squared), plus the log ratio of the real and the simulated within-session spreads
(squared): what a discriminant between one session and the real table sees. Free: eight of the profile's parameters
(sensitivity, turn-on pressure, non-linearity, the pulp's area factor and stiffening, the push-back force, the
sponge's plateau strain, the clock wander, tremor) and, of the scenario, the pad's pitch and sensel share (seed 000
does not give them), the tracker's white noise and the moduli of Material_1 and Material_2 (factors). Nelder-Mead
from the shipped values on tuning seeds 2001-2012 (common random numbers); ``--judge`` simulates the 100 fresh
sessions of ``realism_predictive.py --shipped`` (seeds from 1001) for a candidate and runs the predictive check.

Run: .venv/bin/python benchmarks/realism_location_fit.py [--budget 250] [--seeds 12] [--log fit.jsonl]
     .venv/bin/python benchmarks/realism_location_fit.py --judge '{"taxels.sensitivity": 2.2, ...}' [--sessions 100]
"""

from __future__ import annotations

import argparse
import copy
import json
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from pathlib import Path

import numpy as np
from realism_predictive import format_check
from scipy.optimize import minimize

from palpate.core.errors import PalpateError
from palpate.core.perception.param_stats import PARAM_INDEX, table_from_csv
from palpate.core.perception.predictive_check import predictive_check
from palpate.core.world.scenario_file import load_scenario
from palpate.sim.realism.calibrate import free_parameters, simulate_seed, with_moduli
from palpate.sim.realism.profile_file import parse_profile, profile_tables, resolve_profile

REPO = Path(__file__).resolve().parents[1]
#: The search space: key, low, high, searched in log. ``scenario.*`` keys change the scenario, ``young.*`` a
#: reference's modulus (a factor), the others the profile.
SPACE = (
    ("scenario.pitch_mm", 2.0, 5.0, False),
    ("scenario.sensel_share", 0.4, 0.95, False),
    ("taxels.sensitivity", 1.0, 25.0, True),
    ("taxels.activation_kpa", 0.5, 40.0, True),
    ("taxels.nonlinearity", 0.0, 1.0, False),
    ("finger.area_factor", 1.0, 9.5, False),
    ("finger.stiffening_per_mm", 0.3, 3.0, True),
    ("press.push_force_n", 0.5, 4.0, True),
    ("young.Material_1", 0.15, 2.0, True),
    ("young.Material_2", 0.5, 2.0, True),
    ("material.plateau_strain", 0.0, 0.1, False),
    ("scenario.pose_noise_mm", 0.005, 0.3, True),
    ("pose.clock_wander_ms", 0.5, 40.0, True),
    ("press.tremor_mm", 0.005, 0.2, True),
)
IDX = list(PARAM_INDEX)


def values_at(u: np.ndarray) -> dict[str, float]:
    """The candidate at box positions ``u`` (clipped to [0, 1])."""
    out = {}
    for (key, lo, hi, log), x in zip(SPACE, np.clip(u, 0.0, 1.0), strict=True):
        out[key] = float(np.exp(np.log(lo) + x * np.log(hi / lo))) if log else lo + x * (hi - lo)
    return out


def position_of(values: dict[str, float]) -> np.ndarray:
    return np.array([(np.log(values[k] / lo) / np.log(hi / lo)) if log else (values[k] - lo) / (hi - lo)
                     for k, lo, hi, log in SPACE])


def shipped_values(scenario, profile) -> dict[str, float]:
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
    sc = with_moduli(scenario, free_parameters(moduli, scenario.references), [values[k] for k in moduli])
    pitch = values["scenario.pitch_mm"] * 1e-3
    sc = replace(sc, fingertip=replace(sc.fingertip, pitch=pitch, sensel_size=values["scenario.sensel_share"] * pitch),
                 pose=replace(sc.pose, noise_std=values["scenario.pose_noise_mm"] * 1e-3))
    return sc, parse_profile(tables, "<candidate>", profile.name)


def session(args):
    """One training session's table, or None when the simulation could not finish it."""
    values, seed = args
    scenario = load_scenario(REPO / "scenarios" / "thesis_ch6.toml")
    sc, prof = candidate(scenario, resolve_profile(scenario.realism.profile), values)
    try:
        return simulate_seed(sc, prof, seed, sc.fidelity).table
    except PalpateError:
        return None


def score(tables, real) -> tuple[float, dict]:
    """The objective (module docstring) and, per material, [means], [z], [log spread ratios]."""
    total, detail = 0.0, {}
    for m in real.materials:
        rows = [t.of(m)[:, IDX] for t in tables if len(t.of(m)) >= 3]
        spread = np.vstack([r - r.mean(axis=0) for r in rows]).std(axis=0) + 1e-12
        mean = np.vstack(rows).mean(axis=0)
        z = (real.of(m)[:, IDX].mean(axis=0) - mean) / spread
        ratio = np.log(real.of(m)[:, IDX].std(axis=0, ddof=1) / spread)
        total += float(np.sum(z**2) + np.sum(ratio**2))
        detail[m] = [np.round(mean, 3).tolist(), np.round(z, 2).tolist(), np.round(ratio, 2).tolist()]
    return total, detail


def fit(budget: int, seeds: list[int], log: Path | None) -> None:
    scenario = load_scenario(REPO / "scenarios" / "thesis_ch6.toml")
    real = table_from_csv(scenario.realism.real_params)
    x0 = position_of(shipped_values(scenario, resolve_profile(scenario.realism.profile)))
    best = [np.inf]
    with ProcessPoolExecutor(2) as ex:
        def objective(u):
            values = values_at(u)
            tables = [t for t in ex.map(session, [(values, s) for s in seeds]) if t is not None]
            if len(tables) < len(seeds) // 2:
                return 1e3
            val, detail = score(tables, real)
            val += 2.0 * (len(seeds) - len(tables)) + 100.0 * float(np.sum(np.clip(u - 1, 0, None) ** 2
                                                                            + np.clip(-u, 0, None) ** 2))
            if val < best[0]:
                best[0] = val
                print(f"{val:8.2f} {json.dumps({k: round(v, 4) for k, v in values.items()})}", flush=True)
                if log is not None:
                    with open(log, "a", encoding="utf-8") as f:
                        f.write(json.dumps({"objective": val, "values": values, "detail": detail}) + "\n")
            return val

        simplex = np.vstack([x0] + [x0 + 0.12 * np.eye(len(x0))[i] * (1 if x0[i] < 0.85 else -1)
                                    for i in range(len(x0))])
        minimize(objective, x0, method="Nelder-Mead",
                 options={"maxfev": budget, "initial_simplex": simplex, "adaptive": True, "fatol": 0.1})


def judge(values: dict[str, float], sessions: int) -> None:
    scenario = load_scenario(REPO / "scenarios" / "thesis_ch6.toml")
    real = table_from_csv(scenario.realism.real_params)
    full = shipped_values(scenario, resolve_profile(scenario.realism.profile)) | values
    t0 = time.perf_counter()
    tables, seed = [], 1001
    with ProcessPoolExecutor(2) as ex:
        while len(tables) < sessions:
            batch = list(range(seed, seed + sessions - len(tables)))
            seed += len(batch)
            tables += [t for t in ex.map(session, [(full, s) for s in batch]) if t is not None]
    print(f"{len(tables)} sessions (seeds 1001-{seed - 1}) in {time.perf_counter() - t0:.0f} s; location score "
          f"{score(tables, real)[0]:.1f}")
    print(format_check(predictive_check(real, tables, list(scenario.references))))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--budget", type=int, default=250)
    ap.add_argument("--seeds", type=int, default=12, help="tuning seeds from 2001")
    ap.add_argument("--log", type=Path, default=None, help="append each better candidate (JSON lines)")
    ap.add_argument("--judge", default=None, help="a candidate's values as JSON (keys of SPACE; the rest shipped)")
    ap.add_argument("--sessions", type=int, default=100)
    args = ap.parse_args()
    if args.judge:
        judge(json.loads(args.judge), args.sessions)
    else:
        fit(args.budget, list(range(2001, 2001 + args.seeds)), args.log)


if __name__ == "__main__":
    main()
