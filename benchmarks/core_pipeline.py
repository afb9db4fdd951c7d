"""Time per press through the whole perception stack, and post-processing of a 1000 x 1000 map.

Run: .venv/bin/python benchmarks/core_pipeline.py [--quick]

The press streams come from the analytic simulation (human-like presses on three materials) and are made before
timing; what is timed is what a live run does per press: sync + contact features + segmentation, the two
3/2-power fits, the haptic-memory posterior, and the map update (2-D cell, and a voxel column via per-layer
evidence). The last table times the entropy-weighted extrapolation of a 1000 x 1000 x 3 grid (30% explored).
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from bench_timing import median_of

from palpate.core.mapping.extrapolation import extrapolate_unexplored
from palpate.core.mapping.grids import Grid2D, VoxelGrid
from palpate.core.perception.fit import fit_press
from palpate.core.perception.layered_memory import layer_fits
from palpate.core.perception.memory import HapticMemory
from palpate.core.perception.pipeline import presses_from_recording
from palpate.core.session.sources import PressTarget
from palpate.core.world.scene import Material, ObjectSpec, Scene
from palpate.sim.source import SimSource

MATERIALS = {"soft": 20e3, "medium": 115e3, "hard": 450e3}


def _recordings(n_per: int) -> dict[str, list]:
    out = {}
    for i, (name, young) in enumerate(MATERIALS.items()):
        block = ObjectSpec(name, "box", (0.08, 0.08, 0.04), (0.0, 0.0), Material(name, young, 0.4))
        src = SimSource(Scene((block,)), fidelity="analytic", seed=i, variability="human")
        out[name] = [src.press(PressTarget(0.0, 0.0, depth=0.005, force=10.0)) for _ in range(n_per)]
    return out


def _median_time(fn, items, repeats: int) -> float:
    """Median over ``repeats`` passes of the mean time per item, s."""
    return median_of(lambda: [fn(it) for it in items], repeats)[0] / len(items)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer presses and repeats")
    args = ap.parse_args()
    n_per, repeats = (8, 3) if args.quick else (30, 5)
    recs = _recordings(n_per)
    flat = [r for rs in recs.values() for r in rs]
    presses = [presses_from_recording(r).presses[0] for r in flat]
    fits = [fit_press(p) for p in presses]
    params = np.vstack([f.params for f in fits])
    labels = [name for name, rs in recs.items() for _ in rs]
    memory = HapticMemory(materials=list(MATERIALS)).fit(params, labels)
    grid = Grid2D(list(MATERIALS), (100, 100), cell_size=0.01)
    voxels = VoxelGrid(list(MATERIALS), (100, 100, 6), cell_size=0.0025)
    rng = np.random.default_rng(0)
    cells = rng.integers(0, 100, size=(len(flat), 2))

    stages = [
        ("sync + features + segmentation", lambda r: presses_from_recording(r), flat),
        ("two 3/2-power fits (N and A)", fit_press, presses),
        ("haptic-memory posterior", lambda p: memory.predict_proba(p[None, :]), list(params)),
        ("2-D map update (one cell)", lambda c: grid.update_cell(int(c[0]), int(c[1]), np.full(3, 1 / 3)),
         list(cells)),
        ("voxel evidence + column update",
         lambda p: [voxels.update_voxel(1, 1, iz, memory.predict_proba(f[None, :])[0])
                    for iz, f in enumerate(layer_fits(p.t, p.c_P, p.c_A, p.c_D, 0.0025, 6)) if f is not None],
         presses),
    ]
    print(f"Per press ({len(flat)} simulated presses, median of {repeats} passes, one process)")
    print(f"{'stage':<34}{'ms per press':>14}")
    total = 0.0
    for name, fn, items in stages:
        t = _median_time(fn, items, repeats) * 1e3
        total += t if not name.startswith("voxel") else 0.0
        print(f"{name:<34}{t:14.3f}")
    print(f"{'total (2-D map path)':<34}{total:14.3f}")

    p = rng.dirichlet(np.ones(3), size=(1000, 1000))
    explored = rng.random((1000, 1000)) < 0.3
    t = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        extrapolate_unexplored(p, explored, base=10.0)
        t.append(time.perf_counter() - t0)
    print()
    print("Post-processing (entropy-weighted extrapolation, eq. 6.15)")
    print(f"{'grid':<34}{'s (median)':>14}")
    print(f"{'1000 x 1000 x 3, 30% explored':<34}{np.median(t):14.3f}")


if __name__ == "__main__":
    main()
