"""Exploration of voxel maps: info_gain's accuracy objective in 3-D against its entropy objective, max_entropy and
raster, with physics presses.

Seeded layered blocks, 5 mm voxels two layers deep (10 mm): a base material, a skin 3-8 mm thick of another over
part of the top, a box buried 4-8 mm down, and a column through the whole height; three reference materials (20,
115, 450 kPa) and the voxel run's own per-layer judges (palpate.core.perception.layered_memory). A press goes to
10 mm or 10 N, whichever comes first, so a hard top stops it shallow and leaves the voxels below unread: the
*ceiling* is what raster reaches with every column pressed once. Per policy: presses until the post-processed
voxel map reaches 95% of the ceiling (one more than the columns when never), median and worst ratio to raster, on
tuning seeds (0, ...) and report-only seeds (100000, ...). Every policy explores the same scenes with the same memory.

Seed 001's post-processing is vertical only, so every column must be pressed to be known and no policy can do much
better than raster; --lateral also fills unexplored voxels from their layer's explored neighbours (eq. 6.15 per
layer, ``lateral_extrapolation = true``), where the accuracy objective counts those neighbours too.

Run: .venv/bin/python benchmarks/exploration_voxels.py [--scenes N] [--split tuning|report|both] [--lateral]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from exploration import make_source_for  # noqa: E402

from palpate.core.perception.layered_memory import train_layered_memory  # noqa: E402
from palpate.core.session.explore import explore_object  # noqa: E402
from palpate.core.session.progress import Progress  # noqa: E402
from palpate.core.session.training import train_memory  # noqa: E402
from palpate.core.world.scenario_file import parse_scenario  # noqa: E402

ROWS = {"raster": ("raster", None), "max_entropy": ("max_entropy", None),
        "info_gain_entropy": ("info_gain", "entropy"), "info_gain": ("info_gain", "accuracy")}
MATERIALS = [{"name": "soft", "young_kpa": 20.0, "poisson": 0.3},
             {"name": "medium", "young_kpa": 115.0, "poisson": 0.45},
             {"name": "hard", "young_kpa": 450.0, "poisson": 0.4}]
NAMES = [m["name"] for m in MATERIALS]
CELL_MM, DEPTH_MM, HEIGHT_MM, FORCE_N = 5.0, 10.0, 40.0, 40.0
OF_CEILING = 0.95


def voxel_scene(seed: int, policy: str = "raster", objective: str | None = None, lateral: bool = False) -> dict:
    """A seeded layered block as a scenario dictionary (voxel map)."""
    rng = np.random.default_rng([seed, 3])
    nx, ny = int(rng.integers(8, 13)), int(rng.integers(6, 10))
    sx, sy = nx * CELL_MM, ny * CELL_MM
    base, skin, box, col = (str(v) for v in rng.choice(NAMES, 4))
    obj = {"name": f"block{seed}", "size_mm": [sx, sy, HEIGHT_MM], "position_mm": [sx / 2, sy / 2], "material": base,
           "inclusions": []}
    t = float(rng.uniform(3.0, 8.0))
    w, h = rng.uniform(0.3, 0.7) * sx, rng.uniform(0.4, 0.9) * sy
    obj["inclusions"].append({"shape": "box", "material": skin if skin != base else NAMES[(NAMES.index(base) + 1) % 3],
                              "center_mm": [rng.uniform(w / 2, sx - w / 2), rng.uniform(h / 2, sy - h / 2),
                                            HEIGHT_MM - t / 2], "size_mm": [w, h, t]})
    d = float(rng.uniform(4.0, 8.0))
    bw, bh = rng.uniform(10, 20), rng.uniform(10, 20)
    obj["inclusions"].append({"shape": "box", "material": box, "center_mm": [rng.uniform(bw / 2, sx - bw / 2),
                              rng.uniform(bh / 2, sy - bh / 2), HEIGHT_MM - d - 5.0], "size_mm": [bw, bh, 10.0]})
    cw = float(rng.uniform(5, 12))
    obj["inclusions"].append({"shape": "column", "material": col, "center_mm": [rng.uniform(cw / 2, sx - cw / 2),
                              rng.uniform(cw / 2, sy - cw / 2)], "size_mm": [cw, rng.uniform(8, 20)]})
    ex = {"map": "voxel", "cell_mm": CELL_MM, "voxel_depth_mm": DEPTH_MM, "policy": policy, "budget": nx * ny,
          "depth_mm": DEPTH_MM, "max_force_n": FORCE_N, "variability": "human"}
    if objective is not None:
        ex["objective"] = objective
    if lateral:
        ex["lateral_extrapolation"] = True
    return {"scenario": {"name": f"voxels{seed}", "seed": seed, "fidelity": "analytic"}, "materials": MATERIALS,
            "training": {"presses_per_material": 10, "depth_mm": DEPTH_MM, "max_force_n": FORCE_N},
            "exploration": ex, "objects": [obj], "outputs": {"figures": False, "haptic_material": False}}


def presses_to(acc: list[float], level: float, cap: int) -> int:
    for k, a in enumerate(acc):
        if a is not None and a >= level - 1e-12:
            return k + 1
    return cap + 1


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", type=int, default=12, help="scenes per split (default 12)")
    parser.add_argument("--split", default="both", choices=("tuning", "report", "both"))
    parser.add_argument("--lateral", action="store_true",
                        help="post-process with lateral filling within layers (exploration.lateral_extrapolation)")
    args = parser.parse_args()
    t0 = time.perf_counter()
    base = parse_scenario(voxel_scene(0), "voxels")
    training = train_memory(base, make_source_for(base), np.arange(3) + 1000, Progress(enabled=False))
    layers = train_layered_memory(training.memory, training.presses, CELL_MM * 1e-3, int(DEPTH_MM / CELL_MM))
    splits = [("tuning", range(0, args.scenes)), ("report", range(100000, 100000 + args.scenes))]
    for name, seeds in (s for s in splits if args.split in ("both", s[0])):
        ratios: dict[str, list[float]] = {r: [] for r in ROWS if r != "raster"}
        ceilings, raster_n = [], []
        for s in seeds:
            counts = {}
            for row, (kind, objective) in ROWS.items():
                sc = parse_scenario(voxel_scene(s, kind, objective, args.lateral), f"voxels{s}")
                res = explore_object(sc, sc.objects[0], training.memory, make_source_for(sc), 9000 + s,
                                     Progress(enabled=False), layers=layers)
                acc = [st.accuracy_postprocessed for st in res.steps]
                cap = sc.exploration.budget
                if row == "raster":
                    ceiling = acc[-1]
                    ceilings.append(ceiling)
                counts[row] = presses_to(acc, OF_CEILING * ceiling, cap)
            raster_n.append(counts["raster"])
            for row in ratios:
                ratios[row].append(counts[row] / counts["raster"])
            print(f"{name} {s}: ceiling {ceiling:.3f}, presses to {OF_CEILING:.0%} of it: "
                  + ", ".join(f"{k} {v}" for k, v in counts.items()), flush=True)
        print(f"\n{name} seeds {seeds[0]}-{seeds[-1]}, voxel maps ({CELL_MM:.0f} mm, {DEPTH_MM / CELL_MM:.0f} layers"
              f"{', lateral filling' if args.lateral else ''}), "
              f"physics (analytic): ceiling median {np.median(ceilings):.3f}, raster median {np.median(raster_n):.0f} "
              "presses; ratio to raster of presses to 95% of the ceiling")
        for row, q in ratios.items():
            q = np.array(q)
            print(f"  {row:<18} median {np.median(q):.3f}  quartiles [{np.percentile(q, 25):.2f}, "
                  f"{np.percentile(q, 75):.2f}]  worst {np.max(q):.2f}")
    print(f"total {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
