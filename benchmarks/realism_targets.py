"""The realism targets for scenarios/thesis_ch6.toml's training presses, on seeds the realism profile was not tuned on.

For each seed (as the scenario seed of ``palpate run``; 6 is the main job's), simulate the training protocol with the
scenario's realism profile and print, per material: the simulated / real CV of n1 and a1 (target within +-30%), the
difference in presses of 10 with n2 < 0 (target within 2) and the leave-one-out mean posterior of the material
itself (target: Material_1 0.82 +- 0.06, the others >= 0.95). The last lines say on how many seeds each target holds.

    .venv/bin/python benchmarks/realism_targets.py [--seeds 6,301,302,303,304,305] [--scenario S.toml]
        [--profile NAME_OR_PATH] [--set taxels.activation_kpa=2 --set taxels.activation_cv=0.5 ...]
        [--scenario-set fingertip.pitch_mm=4 --scenario-set training.depth_mm=3 ...] [--write-presses OUT.csv]

``--profile`` replaces the scenario's realism profile and ``--set`` changes one of its calibratable parameters (the
keys of ``palpate calibrate realism --free``, file units), so a candidate is measured before it is fitted or shipped.
``--scenario-set`` changes the pad's geometry, the training press or the tracker's noise (the keys of
:data:`SCENARIO_KEYS`, the scenario file's units). ``--write-presses`` keeps every simulated press in a CSV
(pooled over the seeds by benchmarks/realism_ceiling.py). The checks are
:func:`palpate.core.perception.realism_targets.check_targets`. Each material's line also shows the mean a1 and a2
and the share of presses with a2 < 0 (real: 3.0 / 2.9 / 10.9, +13.5 / +3.5 / -70 and 0 / 0.3 / 1.0); the last lines
give them averaged over the seeds.
"""

from __future__ import annotations

import argparse
import csv
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.perception.param_stats import STAT_COLUMNS, table_from_csv
from palpate.core.perception.realism_targets import TARGETS, check_targets
from palpate.core.world.scenario import Scenario
from palpate.core.world.scenario_file import load_scenario
from palpate.sim.realism.calibrate import simulate_seed
from palpate.sim.realism.parameters import free_parameters, with_values
from palpate.sim.realism.profile_file import resolve_profile

REPO = Path(__file__).resolve().parent.parent
#: ``--scenario-set`` keys (file units, mm) -> (the Scenario's section, its attribute); values are stored in m.
SCENARIO_KEYS = {
    "fingertip.pitch_mm": ("fingertip", "pitch"),
    "fingertip.sensel_mm": ("fingertip", "sensel_size"),
    "fingertip.radius_mm": ("fingertip", "radius"),
    "training.depth_mm": ("training", "depth"),
    "sensors.pose.noise_mm": ("pose", "noise_std"),
}


def with_scenario_values(scenario: Scenario, pairs: list[tuple[str, float]]) -> Scenario:
    """The scenario with the pad's geometry, the training press or the tracker's noise changed (keys of
    SCENARIO_KEYS, values in mm)."""
    changes: dict[str, dict[str, float]] = {}
    for key, value in pairs:
        if key not in SCENARIO_KEYS:
            raise ValueError(f"--scenario-set: unknown key {key!r}; known: {', '.join(SCENARIO_KEYS)}")
        section, attribute = SCENARIO_KEYS[key]
        changes.setdefault(section, {})[attribute] = value * 1e-3
    # one replace per section, so its checks (a sensel no larger than the pitch) see all of its new values at once
    return replace(scenario, **{s: replace(getattr(scenario, s), **kw) for s, kw in changes.items()})


def write_presses(path: Path, rows: list[list]) -> None:
    """Every simulated press as a CSV row (seed, material, run, then :data:`STAT_COLUMNS`), which
    :func:`~palpate.core.perception.param_stats.table_from_csv` reads back pooled over the seeds."""
    with open(path, "w", encoding="utf-8", newline="") as f:
        out = csv.writer(f)
        out.writerow(["seed", "material", "run", *STAT_COLUMNS])
        out.writerows([[seed, name, k, *(repr(float(v)) for v in vals)] for seed, name, k, *vals in rows])


def _pairs(items: list[str], option: str) -> list[tuple[str, float]]:
    """KEY=VALUE strings as (key, float) pairs; ValueError naming the option on a malformed one."""
    pairs = [item.split("=", 1) for item in items]
    if any(len(pair) != 2 for pair in pairs):
        raise ValueError(f"{option} takes KEY=VALUE, got {items}")
    return [(k, float(v)) for k, v in pairs]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", type=Path, default=REPO / "scenarios" / "thesis_ch6.toml")
    ap.add_argument("--seeds", default="6,301,302,303,304,305")
    ap.add_argument("--profile", help="realism profile to measure instead of the scenario's (name or .toml)")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="set a calibratable profile parameter, e.g. taxels.activation_cv=0.5 (repeatable)")
    ap.add_argument("--scenario-set", action="append", default=[], metavar="KEY=VALUE",
                    help=f"change the scenario, mm: {', '.join(SCENARIO_KEYS)} (repeatable)")
    ap.add_argument("--write-presses", type=Path, metavar="CSV",
                    help="write every simulated press (seed, material, run, n1 ... phi_a) to this CSV")
    args = ap.parse_args()
    try:
        sets, scenario_sets = _pairs(args.set, "--set"), _pairs(args.scenario_set, "--scenario-set")
        scenario = with_scenario_values(load_scenario(args.scenario), scenario_sets)
    except (ValueError, ValidationError) as err:
        print(f"realism_targets: {err}", file=sys.stderr)
        return 2
    if scenario.realism.real_params is None:
        print("the scenario names no [realism] real_params", file=sys.stderr)
        return 2
    real = table_from_csv(scenario.realism.real_params)
    profile = resolve_profile(args.profile or scenario.realism.profile)
    tuned = set(profile.provenance.get("tune_seeds", []))
    if sets:
        free = free_parameters([k for k, _ in sets])
        profile = with_values(profile, free, [v for _, v in sets], name=f"{profile.name}+set")
    if sets or scenario_sets:
        print("set " + ", ".join(f"{k}={v:g}" for k, v in sets + scenario_sets))
    seeds = [int(s) for s in args.seeds.split(",")]
    print(f"profile {profile.name} (tuned on seeds {sorted(tuned) or 'n/a'}), scenario {scenario.name}, "
          f"fidelity {scenario.fidelity}")
    refs = list(scenario.references)
    passed = np.zeros((len(refs), len(TARGETS)), dtype=int)
    # per material, per seed: mean a1, mean a2, share of a2 < 0, leave-one-out self posterior
    cutaneous: dict[str, list[list[float]]] = {name: [] for name in refs}
    rows, dropped = [], 0
    for seed in seeds:
        t0 = time.perf_counter()
        run = simulate_seed(scenario, profile, seed, scenario.fidelity)
        check = check_targets(run.table, real, run.loo_self, refs)
        passed += check.held
        flags = []
        for i, name in enumerate(refs):
            sim = run.table.of(name)
            rows += [[seed, name, k + 1, *row] for k, row in enumerate(sim)]
            cutaneous[name].append([np.mean(sim[:, 3]), np.mean(sim[:, 4]), np.mean(sim[:, 4] < 0),
                                    run.loo_self[i]])
            miss = ["" if ok else "!" for ok in check.held[i]]
            cv = check.cv_ratio[i]
            flags.append(f"{name}: cv n1 x{cv[0]:.2f}{miss[0]} a1 x{cv[1]:.2f}{miss[1]} n2<0 "
                         f"{check.negative_n2[i]:+.0f}{miss[2]} loo {run.loo_self[i]:.2f}{miss[3]} | "
                         f"a1 {np.mean(sim[:, 3]):.2f} a2 {np.mean(sim[:, 4]):+.0f} a2<0 {np.mean(sim[:, 4] < 0):.1f}")
        mark = " (tuning seed)" if seed in tuned else ""
        lost = ", ".join(f"{n} {k}" for n, k in run.dropped.items() if k)
        mark += f" (presses dropped, fit failed: {lost})" if lost else ""
        dropped += sum(run.dropped.values())
        print(f"seed {seed}{mark} [{time.perf_counter() - t0:.1f} s]\n  " + "\n  ".join(flags))
    print(f"targets held on {len(seeds)} seeds ('!' marks a miss):")
    for i, name in enumerate(refs):
        for j, target in enumerate(TARGETS):
            print(f"  {name + ' ' + target:<24} {passed[i, j]}/{len(seeds)}")
    print(f"  {'all':<24} {passed.sum()}/{len(seeds) * passed.size}")
    total = len(seeds) * len(refs) * scenario.training.presses_per_material
    print(f"presses dropped (fit failed): {dropped} of {total}")
    if args.write_presses:
        write_presses(args.write_presses, rows)
        print(f"wrote the {len(rows)} simulated presses to {args.write_presses}")
    print(f"mean over the {len(seeds)} seeds, simulated (real):")
    for name in scenario.references:
        a1, a2, neg, loo = np.mean(cutaneous[name], axis=0)
        ref = real.of(name)
        print(f"  {name}: a1 {a1:.2f} ({np.mean(ref[:, 3]):.2f}) a2 {a2:+.1f} ({np.mean(ref[:, 4]):+.1f}) "
              f"a2<0 {neg:.2f} ({np.mean(ref[:, 4] < 0):.2f}) loo {loo:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
