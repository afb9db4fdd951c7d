"""Exploration policies on many scenes in seconds: presses answered from the haptic memory, no physics.

The same seeded scenes as benchmarks/exploration.py (its scene generator), the same trained memory and the same
policies, map and post-processing; only the press is replaced: pressing a cell returns a posterior drawn from
the memory's predicted outcomes for the cell's true material (palpate.core.planning.outcomes.outcome_posteriors, the
Gaussians of seed 000 eq. 6.13-6.14). That is what the physics benchmark's presses look like on these scenes
(walls are kept away from cell centres there), and on seeds 0-23 this script reproduces its info_gain/raster
median. Use it to compare policies or settings on enough scenes for the median to mean something, and on seeds
the settings were not tuned on (--seed0 100).

Run: .venv/bin/python benchmarks/exploration_offline.py [--scenes N] [--seed0 S] [--policies a,b]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from exploration import ACCURACY, ROWS, chosen_rows, make_source_for, scene_dict  # noqa: E402
from family_runs import planned_on, postprocess  # noqa: E402

from palpate.core.mapping.accuracy import map_accuracy
from palpate.core.mapping.calibration import MapCalibration
from palpate.core.mapping.geometry import MapGeometry
from palpate.core.mapping.grids import new_map
from palpate.core.planning.outcomes import outcome_posteriors
from palpate.core.planning.registry import make_policy
from palpate.core.session.progress import Progress
from palpate.core.session.training import train_memory
from palpate.core.world.scenario_file import parse_scenario
from palpate.core.world.workspace import ground_truth_map, map_geometries


def presses_to_accuracy(policy, geom: MapGeometry, truth: np.ndarray, answers: np.ndarray, seed: int,
                        calibration: MapCalibration) -> int | None:
    """Presses until the post-processed map reaches ACCURACY (None if the policy stops or the budget, one press
    per cell, runs out first); the map is calibrated as the scenario says, like a run's."""
    grid = new_map(geom)
    rng = np.random.default_rng(seed)
    last = None
    for k in range(truth.size + 1):
        # scored on the reported map, planned on it without the wall tempering, as a run does
        reported = postprocess(grid, calibration)
        post = planned_on(grid, calibration, reported)
        if (map_accuracy(reported.probabilities, truth) or 0.0) >= ACCURACY:
            return k
        if k == truth.size:
            return None
        t = policy.next_target(grid, post, last)
        if t is None:
            return None
        grid.update_cell(t.ix, t.iy, calibration.evidence(answers[truth[t.iy, t.ix], rng.integers(answers.shape[1])]))
        last = (t.ix, t.iy)
    return None


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", type=int, default=72, help="number of seeded scenes (default 72)")
    parser.add_argument("--seed0", type=int, default=0, help="first scene seed (default 0)")
    parser.add_argument("--policies", default="raster,max_entropy,info_gain_entropy,info_gain",
                        help=f"comma-separated rows (known: {','.join(ROWS)}); raster is always run")
    parser.add_argument("--samples", type=int, default=40, help="predicted outcomes per material to draw from")
    args = parser.parse_args()
    rows = chosen_rows(args.policies, parser)

    t0 = time.perf_counter()
    base = parse_scenario(scene_dict(0, "analytic", "raster", 1), "bench")
    memory = train_memory(base, make_source_for(base), np.arange(3) + 1000, Progress(enabled=False)).memory
    answers = outcome_posteriors(memory, args.samples, seed=99)
    needed: dict[str, list[int | None]] = {p: [] for p in rows}
    cells: list[int] = []
    seeds = range(args.seed0, args.seed0 + args.scenes)
    for s in seeds:
        for row in rows:
            kind, objective = ROWS[row]
            sc = parse_scenario(scene_dict(s, "analytic", kind, 1, 1, objective), f"scene{s}")
            ex = sc.exploration
            geom = map_geometries(sc)[sc.objects[0].spec.name]
            truth = ground_truth_map(sc.objects[0], sc, geom)
            regions = [(c - 1, r - 1) for c, r in sc.objects[0].regions]
            policy = make_policy(kind, cells=regions, seed=s, memory=memory, objective=ex.objective,
                                 feature_size=ex.feature_size, certainty=ex.calibration.extrapolation_certainty)
            needed[row].append(presses_to_accuracy(policy, geom, truth, answers, s, ex.calibration))
        cells.append(int(truth.size))
    print(f"{args.scenes} scenes (seeds {seeds.start}-{seeds.stop - 1}), presses answered from the memory's predicted "
          f"outcomes; presses to {ACCURACY:.0%} accuracy of the post-processed map")
    print(f"{'policy':<18} {'median':>7} {'reached':>8} {'ratio to raster: median [q1, q3]':>34} {'mean':>6}")
    raster = needed["raster"]
    for row in rows:
        got = needed[row]
        reached = [v for v in got if v is not None]
        # a scene never mapped counts as one press more than there are cells, so failures cannot flatter it
        vals = [v if v is not None else c + 1 for v, c in zip(got, cells, strict=True)]
        ratios = np.array([v / r for v, r in zip(vals, raster, strict=True) if r])
        print(f"{row:<18} {np.median(vals):7.1f} {len(reached):>4}/{len(got):<3} "
              f"{np.median(ratios):14.3f} [{np.percentile(ratios, 25):.2f}, {np.percentile(ratios, 75):.2f}]"
              f"{np.mean(ratios):12.3f}")
    print(f"total {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
