"""Choosing the map's press, extrapolation and wall reliability: calibration of physics maps under each setting.

MapCalibration.wall_reliability (core/mapping/calibration.py, wall_tempered) lowers a pressed cell's certainty
where a pressed edge-neighbour reads otherwise, at post-processing time; press_reliability and
extrapolation_certainty set what a press and eq. 6.15 may claim. Each policy's simulated runs (analytic fidelity,
every cell pressed once, as benchmarks/exploration_families.py --physics) have their maps rebuilt at 20/35/50/100%
of the cells pressed and post-processed with each setting. Raster's presses do not depend on the map, so one
raster run per scene serves every setting (its presses' posteriors fused again); another policy (info_gain) runs
once per (press, extrapolation) pair, since both change what it plans on, and its maps serve every wall
reliability. Printed: the ECE of the most probable material, its accuracy and mean confidence, overall and for the
cells with a wall within a press's reach (a neighbour sharing an edge holds another true material) and the others.
The pooled ECE can hide a wall cell that is sure and wrong behind a clear cell that is right and unsure in the same
bin; the "grouped" ECE, the two groups' ECEs weighted by their cells, cannot. The setting is chosen by the rule of
docs/results.md ("Press, extrapolation and wall reliability chosen together"): the lowest mean grouped ECE over
the policies with every policy's pooled ECE at most MAX_POOLED_ECE.

Choose on tuning seeds (--split tuning), report on the report seeds once chosen.

Run: .venv/bin/python benchmarks/exploration_wall_sweep.py [--split tuning|report] [--physics K]
     [--policies raster,info_gain] [--wall 1,0.8,0.6] [--press 0.94,0.98] [--extrapolation 0.95,1] [--first N]
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from family_runs import CALIBRATION_AT, ROWS, checkpoint_maps, physics_explore, postprocess  # noqa: E402
from scene_families import REPORT_SEEDS, TUNING_SEEDS, scene  # noqa: E402

from palpate.core.mapping.accuracy import decided_labels  # noqa: E402
from palpate.core.mapping.calibration import DEFAULT_CALIBRATION, MapCalibration, reliability_table  # noqa: E402
from palpate.core.mapping.neighbourhood import shift_slices  # noqa: E402

#: The rule's bound on every policy's pooled ECE, and the score margin within which a smaller change wins.
MAX_POOLED_ECE = 0.03
NEAR = 0.002


def near_wall(truth: np.ndarray) -> np.ndarray:
    """(ny, nx) cells with an edge-neighbour of another true material."""
    ny, nx = truth.shape
    out = np.zeros(truth.shape, dtype=bool)
    for dy, dx in ((0, 1), (1, 0)):
        a, b = shift_slices(dy, dx, ny, nx)
        differ = (truth[a] != truth[b]) & (truth[a] >= 0) & (truth[b] >= 0)
        out[a] |= differ
        out[b] |= differ
    return out


def _samples(res, cal, truth: np.ndarray, wall: np.ndarray, walls: list[float]) -> dict:
    """Per wall reliability: [(confidence, right, near a wall)] of the decided cells with a truth at every
    checkpoint of run ``res``, its presses fused with ``cal``."""
    checkpoints = {max(1, int(round(f * truth.size))) for f in CALIBRATION_AT}
    out: dict = {w: [] for w in walls}
    for _, grid in checkpoint_maps(res, cal, checkpoints):
        for w in walls:
            p = np.asarray(postprocess(grid, dataclasses.replace(cal, wall_reliability=w)).probabilities)
            label, decided = decided_labels(p)
            keep = decided & (truth >= 0)
            out[w].append((p.max(axis=-1)[keep], (label == truth)[keep], wall[keep]))
    return out


def scene_samples(fs, policies: list[str], settings: list[tuple[float, float, float]]) -> dict:
    """Per (policy, (press, extrapolation, wall) reliability): [(confidence, right, near a wall)] of the decided
    cells with a truth at every checkpoint. Raster's presses do not read the map, so one raster run is fused again
    with every setting; any other policy runs once per (press, extrapolation) pair, which change what it plans
    on (the wall reliability does not: the policies plan on the map without it)."""
    out: dict = {}
    fused_pairs = sorted({(p, e) for p, e, _ in settings})
    walls = {pair: [w for p, e, w in settings if (p, e) == pair] for pair in fused_pairs}
    for policy in policies:
        raster = None
        for press, extrap in fused_pairs:
            if policy == "raster":
                raster = raster or physics_explore(fs, "raster")
                res, cal = raster
            else:
                res, cal = physics_explore(fs, policy, calibration=dataclasses.replace(
                    DEFAULT_CALIBRATION, press_reliability=press, extrapolation_certainty=extrap))
            cal = dataclasses.replace(cal, press_reliability=press, extrapolation_certainty=extrap)
            truth = np.asarray(res.truth)
            for w, parts in _samples(res, cal, truth, near_wall(truth), walls[(press, extrap)]).items():
                out[(policy, (press, extrap, w))] = parts
    return out


def chosen(scores: dict, pooled: dict, shipped: MapCalibration, max_pooled: float, near: float):
    """The setting the rule picks (docs/results.md): the lowest score among those whose pooled ECE is at most
    ``max_pooled`` for every policy; one within ``near`` of it that moves the shipped press, then extrapolation,
    reliability less wins instead. None when no setting is allowed."""
    allowed = [s for s in scores if pooled[s] <= max_pooled]
    if not allowed:
        return None
    low = min(scores[s] for s in allowed)
    return min((s for s in allowed if scores[s] <= low + near),
               key=lambda s: (abs(s[0] - shipped.press_reliability),
                              abs(s[1] - shipped.extrapolation_certainty), scores[s]))


def numbers(parser: argparse.ArgumentParser, text: str, flag: str) -> list[float]:
    """Comma-separated numbers in (0, 1]; anything else is a usage error."""
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        parser.error(f"{flag} takes numbers, got {text!r}")
    if not all(0 < v <= 1 for v in values):
        parser.error(f"{flag} values must lie in (0, 1]")
    return values


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--split", default="tuning", choices=("tuning", "report"))
    parser.add_argument("--physics", type=int, default=12, help="scenes (default 12)")
    parser.add_argument("--first", type=int, default=None, help="first seed (default: the split's first)")
    parser.add_argument("--policies", default="raster", help=f"comma-separated, of {', '.join(ROWS)}")
    parser.add_argument("--wall", default="1,0.9,0.8,0.7,0.6,0.5",
                        help="wall reliabilities to compare, comma-separated, each in (0, 1]")
    parser.add_argument("--press", default=f"{DEFAULT_CALIBRATION.press_reliability:g}",
                        help="press reliabilities to compare, comma-separated, each in (0, 1]")
    parser.add_argument("--extrapolation", default=f"{DEFAULT_CALIBRATION.extrapolation_certainty:g}",
                        help="extrapolation certainties to compare, comma-separated, each in (0, 1]")
    args = parser.parse_args()
    policies = [p.strip() for p in args.policies.split(",") if p.strip()]
    if not policies or any(p not in ROWS for p in policies):
        parser.error(f"--policies takes rows of {', '.join(ROWS)}, got {args.policies!r}")
    settings = [(p, e, w) for p in numbers(parser, args.press, "--press")
                for e in numbers(parser, args.extrapolation, "--extrapolation")
                for w in numbers(parser, args.wall, "--wall")]
    seeds = TUNING_SEEDS if args.split == "tuning" else REPORT_SEEDS
    first = seeds[0] if args.first is None else args.first
    if first not in seeds:
        parser.error(f"--first {first} is not a {args.split} seed")
    t0 = time.perf_counter()
    pooled: dict = {}
    for s in range(first, first + args.physics):
        for key, parts in scene_samples(scene(s), policies, settings).items():
            pooled.setdefault(key, []).extend(parts)
        print(f"seed {s} done ({time.perf_counter() - t0:.0f} s)", flush=True)
    print(f"\n{args.split} seeds {first}-{first + args.physics - 1}, physics (analytic), checkpoints "
          f"{CALIBRATION_AT}: grouped ECE; ECE / accuracy / mean confidence (cells) of all cells, of those with a "
          "wall at an edge, of the others")
    score = {s: 0.0 for s in settings}
    worst_pooled = {s: 0.0 for s in settings}
    for policy in policies:
        for setting in settings:
            parts = pooled[(policy, setting)]
            conf = np.concatenate([c for c, _, _ in parts])
            right = np.concatenate([r for _, r, _ in parts])
            wall = np.concatenate([w for _, _, w in parts])
            line = ""
            grouped = 0.0
            for name, sel in (("all", np.ones(conf.size, bool)), ("wall", wall), ("clear", ~wall)):
                t = reliability_table(conf[sel], right[sel])
                if name == "all":
                    worst_pooled[setting] = max(worst_pooled[setting], t.ece)
                else:
                    grouped += t.ece * t.cells / max(conf.size, 1)
                line += (f"  {name} {t.ece:.4f} / {np.mean(right[sel]):.3f} / {np.mean(conf[sel]):.3f}"
                         f" ({t.cells})")
            score[setting] += grouped / len(policies)
            print(f"{policy:<10} press {setting[0]:<5g} extrapolation {setting[1]:<5g} wall {setting[2]:<5g} "
                  f"grouped {grouped:.4f} " + line)
    print(f"\nscore: mean grouped ECE over {', '.join(policies)}; pooled: the largest pooled ECE of them")
    for setting in sorted(settings, key=score.get):
        print(f"press {setting[0]:<5g} extrapolation {setting[1]:<5g} wall {setting[2]:<5g} score "
              f"{score[setting]:.4f} pooled {worst_pooled[setting]:.4f}")
    pick = chosen(score, worst_pooled, DEFAULT_CALIBRATION, MAX_POOLED_ECE, NEAR)
    picked = "none allowed" if pick is None else f"press {pick[0]:g}, extrapolation {pick[1]:g}, wall {pick[2]:g}"
    print(f"the rule's pick (pooled <= {MAX_POOLED_ECE:g}, within {NEAR:g} of the lowest: least change from the "
          f"shipped press, then extrapolation): {picked}")
    print(f"\ntotal {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
