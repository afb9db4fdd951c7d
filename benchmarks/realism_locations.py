"""Where the realism model puts the per-press parameters' locations, and what can move them: the shipped profile's
simulated training sessions (scenarios/thesis_ch6.toml) against seed 000's Tables 6.3-6.5, per material, in the
means of n1, n2, a1, a2 and the fit residuals Phi_N, Phi_A (logs), and each calibratable parameter
(sim/realism/calibrate.py's FREE_PARAMETERS) set alone to either end of its box. A location no parameter moves
towards the real table is one the model's structure (not its values) misses. ``--pose-noise-mm`` repeats the
baseline with the tracker's white position noise set to each value (the scenario's default is 0.2 mm per axis).

Sessions use common seeds for every setting; a setting the simulation cannot press (the rigid drive falling short)
is named and skipped.

Run: .venv/bin/python benchmarks/realism_locations.py [--seeds 3] [--first-seed 501] [--pose-noise-mm 0.2,0.05,0]
     [--no-scan]
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from palpate.core.errors import PalpateError
from palpate.core.perception.param_stats import table_from_csv
from palpate.core.world.scenario_file import load_scenario
from palpate.sim.realism.calibrate import simulate_seed
from palpate.sim.realism.parameters import FREE_PARAMETERS, free_parameters, with_values
from palpate.sim.realism.profile_file import resolve_profile

REPO = Path(__file__).resolve().parents[1]
#: Columns of a press table (param_stats.STAT_COLUMNS order) and how each location is compared.
COLUMNS = ("n1", "n2", "phi_n", "a1", "a2", "phi_a")
LOGGED = ("phi_n", "phi_a")


def locations(scenario, profile, seeds) -> dict[str, np.ndarray]:
    """Per material, the mean of each column over every fitted press of the sessions on ``seeds``."""
    rows: dict[str, list] = {m: [] for m in scenario.references}
    for seed in seeds:
        run = simulate_seed(scenario, profile, seed, scenario.fidelity)
        for m in rows:
            rows[m].append(run.table.of(m))
    return {m: np.vstack(r).mean(axis=0) for m, r in rows.items()}


def shown(loc: dict[str, np.ndarray]) -> list[float]:
    """The locations as printed: log of Phi_N and Phi_A, the others as they are; materials in turn."""
    return [float(np.log(v[j]) if c in LOGGED else v[j]) for v in loc.values() for j, c in enumerate(COLUMNS)]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--first-seed", type=int, default=501)
    ap.add_argument("--pose-noise-mm", default="", help="comma-separated tracker noise values to try, mm")
    ap.add_argument("--no-scan", action="store_true", help="skip the one-parameter scan")
    args = ap.parse_args()
    scenario = load_scenario(REPO / "scenarios" / "thesis_ch6.toml")
    profile = resolve_profile(scenario.realism.profile)
    real_table = table_from_csv(scenario.realism.real_params)
    real = {m: real_table.of(m).mean(axis=0) for m in scenario.references}
    seeds = list(range(args.first_seed, args.first_seed + args.seeds))
    t0 = time.process_time()
    base = locations(scenario, profile, seeds)
    names = [f"{m[-1]}:{c if c not in LOGGED else 'ln ' + c}" for m in base for c in COLUMNS]
    print(f"locations per material (1, 2, 3 = Material_1..3), {len(seeds)} sessions of 10 presses each, seeds "
          f"{seeds[0]}-{seeds[-1]}")
    print(f"{'setting':36} " + " ".join(f"{n:>10}" for n in names))
    print(f"{'real table':36} " + " ".join(f"{v:10.2f}" for v in shown(real)))
    print(f"{'shipped profile':36} " + " ".join(f"{v:10.2f}" for v in shown(base)))
    for text in filter(None, args.pose_noise_mm.split(",")):
        noisy = replace(scenario, pose=replace(scenario.pose, noise_std=float(text) * 1e-3))
        print(f"{'pose noise ' + text + ' mm':36} " + " ".join(f"{v:10.2f}" for v in shown(
            locations(noisy, profile, seeds))))
    if not args.no_scan:
        print("\nchange from the shipped profile with one parameter at an end of its box (real - shipped first)")
        gap = np.array(shown(real)) - np.array(shown(base))
        print(f"{'real - shipped':36} " + " ".join(f"{v:10.2f}" for v in gap))
        for key in FREE_PARAMETERS:
            p = free_parameters([key], scenario.references)[0]
            for value in (p.lo, p.hi):
                label = f"{key} = {value:g}"
                try:
                    loc = locations(scenario, with_values(profile, [p], [value]), seeds)
                except PalpateError as err:
                    print(f"{label:36} not pressed: {str(err)[:80]}")
                    continue
                change = np.array(shown(loc)) - np.array(shown(base))
                print(f"{label:36} " + " ".join(f"{v:10.2f}" for v in change), flush=True)
    print(f"\nCPU {time.process_time() - t0:.0f} s")


if __name__ == "__main__":
    main()
