"""Exploration policies compared on the same seeded heterogeneous scenes: presses to a good map.

Every policy explores the same scenes (a block of one material with inclusions reaching the surface -- boxes,
discs, columns -- and sometimes a top layer, with three reference materials; the grid's origin is offset by a
random fraction of a cell, so nothing lines up with the grid) with one haptic memory trained once. Per policy it
prints the presses needed to reach 95% accuracy of the post-processed map against ground truth, and to bring the
post-processed map's mean entropy under a threshold (median, quartiles, how many scenes got there), plus
info_gain's median ratio to raster. It writes a plot of accuracy and mean entropy against presses
(median over scenes) to --plot.

--passes sets exploration.extrapolation_passes (eq. 6.15 repeated; 1 = the seed, "all" = until every cell is
filled) for every policy alike, so the comparison stays fair.

Run: .venv/bin/python benchmarks/exploration.py [--quick] [--scenes N] [--fidelity analytic|rigid] [--passes K|all]
     [--plot PNG]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from palpate.core.explore import InfoGain, outcome_posteriors, outcome_table
from palpate.core.maps import Grid2D
from palpate.core.progress import Progress
from palpate.core.run import explore_object, train_memory
from palpate.core.scenario import parse_scenario
from palpate.core.scene import Scene
from palpate.core.sources import load_source

POLICIES = ("raster", "random", "predefined", "max_entropy", "info_gain")
ACCURACY = 0.95
CELL_MM = 10.0

MATERIALS = [
    {"name": "soft", "young_kpa": 20.0, "poisson": 0.3},
    {"name": "medium", "young_kpa": 115.0, "poisson": 0.45},
    {"name": "hard", "young_kpa": 450.0, "poisson": 0.4},
    {"name": "foam", "young_kpa": 26.0, "poisson": 0.3, "reference": False, "like": "soft"},
    {"name": "rubber", "young_kpa": 100.0, "poisson": 0.45, "reference": False, "like": "medium"},
    {"name": "lump", "young_kpa": 520.0, "poisson": 0.4, "reference": False, "like": "hard"},
]
NAMES = ["soft", "medium", "hard", "foam", "rubber", "lump"]


def scene_dict(seed: int, fidelity: str, policy: str, budget: int, passes: int | None = 1) -> dict:
    """A seeded heterogeneous scene as a scenario dictionary (the TOML schema), one object."""
    rng = np.random.default_rng(seed)
    sx, sy, sz = rng.uniform(90, 130), rng.uniform(70, 100), 40.0
    bulk = str(rng.choice(NAMES))
    obj = {"name": f"scene{seed}", "size_mm": [sx, sy, sz], "position_mm": [sx / 2, sy / 2], "material": bulk,
           "inclusions": [], "layers": []}
    if rng.random() < 0.3:
        # A top layer thicker than half the press depth: the material a press mostly feels.
        obj["layers"].append({"material": str(rng.choice(NAMES)), "thickness_mm": float(rng.uniform(3.0, 6.0))})
    for _ in range(int(rng.integers(2, 5))):
        kind = str(rng.choice(["box", "sphere", "column"]))
        mat = str(rng.choice(NAMES))
        cx, cy = rng.uniform(0.1, 0.9) * sx, rng.uniform(0.1, 0.9) * sy
        if kind == "sphere":
            r = rng.uniform(12, 25)
            # The disc it cuts at the surface has a radius between ~0.6 and 1 sphere radius.
            inc = {"shape": "sphere", "center_mm": [cx, cy, sz - rng.uniform(0, 0.8) * r], "size_mm": [r]}
        elif kind == "box":
            bx, by, bz = rng.uniform(15, 45), rng.uniform(15, 40), rng.uniform(8, 20)
            inc = {"shape": "box", "center_mm": [cx, cy, sz - bz / 2], "size_mm": [bx, by, bz]}
        else:
            inc = {"shape": "column", "center_mm": [cx, cy], "size_mm": [rng.uniform(12, 30), rng.uniform(30, 90)]}
        inc["material"] = mat
        obj["inclusions"].append(inc)
    off = rng.uniform(0.1, 0.9, 2) * CELL_MM
    cells = [int((sx - off[0]) // CELL_MM), int((sy - off[1]) // CELL_MM)]
    obj["grid_origin_mm"] = [float(off[0]), float(off[1])]
    obj["grid_cells"] = cells
    # The predefined list: a planned stride-3 pattern, as a person would lay out regions in advance.
    obj["regions"] = [[c + 1, r + 1] for r in range(1, cells[1], 3) for c in range(1, cells[0], 3)]
    ex = {"policy": policy, "budget": budget, "presses_per_region": 1, "cell_mm": CELL_MM, "depth_mm": 4.0,
          "max_force_n": 10.0, "variability": "human", "extrapolation_passes": "all" if passes is None else passes}
    return {"scenario": {"name": f"scene{seed}", "seed": seed, "fidelity": fidelity},
            "materials": MATERIALS, "training": {"presses_per_material": 10, "depth_mm": 4.0, "max_force_n": 10.0},
            "exploration": ex, "objects": [obj], "outputs": {"figures": False, "haptic_material": False}}


def make_source_for(scenario):
    factory = load_source("sim")

    def make(objects, seed, variability):
        return factory(Scene(objects, scenario.fingertip, scenario.taxels, scenario.pose),
                       fidelity=scenario.fidelity, seed=seed, variability=variability)

    return make


def first_reaching(values: list, ok) -> int | None:
    """1-based press count at which ``ok(value)`` first holds, or None."""
    for k, v in enumerate(values):
        if v is not None and ok(v):
            return k + 1
    return None


def gain_timing(memory, repeats: int = 5) -> tuple[float, int]:
    """Median time (s) of one info_gain choice among 100 x 100 cells, 3% explored; and the outcome groups used."""
    rng = np.random.default_rng(3)
    grid = Grid2D(memory.materials, (100, 100))
    q = outcome_posteriors(memory)
    for _ in range(300):
        t = int(rng.integers(len(memory.materials)))
        grid.update_cell(int(rng.integers(100)), int(rng.integers(100)), q[t, int(rng.integers(q.shape[1]))])
    post = grid.postprocessed()
    policy = InfoGain(memory)
    policy.next_target(grid, post, (50, 50))
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        policy.next_target(grid, post, (50, 50))
        times.append(time.perf_counter() - t0)
    return float(np.median(times)), outcome_table(q)[0].shape[0]


def _stats(values: list[int | None], budget_cap: list[int]) -> str:
    got = [v for v in values if v is not None]
    if not got:
        return f"{'never':>22}  0/{len(values)}"
    q1, med, q3 = np.percentile(got, [25, 50, 75]) if len(got) == len(values) else np.percentile(
        [v if v is not None else c + 1 for v, c in zip(values, budget_cap, strict=True)], [25, 50, 75])
    return f"{med:7.1f} [{q1:5.1f}, {q3:5.1f}]    {len(got):2d}/{len(values)}"


def _passes_arg(text: str) -> str:
    if text != "all" and not (text.isdigit() and int(text) >= 1):
        raise argparse.ArgumentTypeError(f'expected an integer >= 1 or "all", got {text!r}')
    return text


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="6 scenes (a short smoke run)")
    parser.add_argument("--scenes", type=int, default=None, help="number of seeded scenes (default 24)")
    parser.add_argument("--fidelity", default="analytic", choices=("analytic", "rigid"))
    parser.add_argument("--entropy", type=float, default=0.05,
                        help="mean-entropy threshold of the post-processed map, log10 units (max 0.477)")
    parser.add_argument("--passes", default="1", type=_passes_arg,
                        help='eq. 6.15 passes of the post-processing, the same for every policy: an integer or "all"')
    parser.add_argument("--plot", default="/tmp/palpate_exploration.png", help="PNG of accuracy/entropy vs presses")
    args = parser.parse_args()
    n_scenes = args.scenes or (6 if args.quick else 24)
    passes = None if args.passes == "all" else int(args.passes)

    t0 = time.perf_counter()
    base = parse_scenario(scene_dict(0, args.fidelity, "raster", 1), "bench")
    memory, crossval, _ = train_memory(base, make_source_for(base), np.arange(3) + 1000, Progress(enabled=False))
    t_gain, groups = gain_timing(memory)
    print(f"memory: {len(memory.materials)} materials, leave-one-out accuracy "
          f"{np.mean(np.diag(np.asarray(crossval.confusion))):.2f}; info_gain choice among 10,000 cells: "
          f"{t_gain * 1e3:.1f} ms ({groups} outcome groups)")

    curves: dict[str, list[tuple[np.ndarray, np.ndarray]]] = {p: [] for p in POLICIES}
    to_acc: dict[str, list[int | None]] = {p: [] for p in POLICIES}
    to_h: dict[str, list[int | None]] = {p: [] for p in POLICIES}
    caps: list[int] = []
    wall: dict[str, float] = dict.fromkeys(POLICIES, 0.0)
    for s in range(n_scenes):
        probe = parse_scenario(scene_dict(s, args.fidelity, "raster", 1), "bench")
        nx, ny = probe.objects[0].grid_shape
        budget = nx * ny
        caps.append(budget)
        for policy in POLICIES:
            sc = parse_scenario(scene_dict(s, args.fidelity, policy, budget, passes), f"scene{s}")
            t1 = time.perf_counter()
            summary, *_ = explore_object(sc, sc.objects[0], memory, make_source_for(sc), 7000 + s,
                                         Progress(enabled=False))
            wall[policy] += time.perf_counter() - t1
            acc = [r["accuracy_all_cells_postprocessed"] for r in summary["per_press"]]
            ent = [r["mean_entropy_postprocessed"] for r in summary["per_press"]]
            to_acc[policy].append(first_reaching(acc, lambda v: v >= ACCURACY))
            to_h[policy].append(first_reaching(ent, lambda v: v <= args.entropy))
            k = np.arange(1, len(acc) + 1) / budget
            curves[policy].append((k, np.array([np.nan if a is None else a for a in acc]), np.array(ent)))
        print(f"scene {s:2d}: {nx}x{ny} cells; presses to {ACCURACY:.0%}: "
              + ", ".join(f"{p} {to_acc[p][-1]}" for p in POLICIES), flush=True)

    print()
    print(f"{n_scenes} scenes, fidelity {args.fidelity}, {CELL_MM:.0f} mm cells, eq. 6.15 passes {args.passes}, "
          "budget = number of cells "
          f"(median {int(np.median(caps))}); 'never' runs count as budget + 1 in the quartiles")
    print(f"{'policy':<12} {'presses to ' + format(ACCURACY, '.0%') + ' accuracy':>30} "
          f"{'presses to mean H <= ' + format(args.entropy, 'g'):>32} {'wall s':>8}")
    print(f"{'':<12} {'median [q1, q3]   reached':>30} {'median [q1, q3]   reached':>32}")
    for p in POLICIES:
        print(f"{p:<12} {_stats(to_acc[p], caps):>30} {_stats(to_h[p], caps):>32} {wall[p]:8.1f}")
    ratios = [g / r for g, r in zip(to_acc["info_gain"], to_acc["raster"], strict=True) if g and r]
    if ratios:
        print(f"info_gain / raster presses to {ACCURACY:.0%} (scenes where both got there, n = {len(ratios)}): "
              f"median {np.median(ratios):.2f}, range [{min(ratios):.2f}, {max(ratios):.2f}]; target <= 0.33")
    print(f"total {time.perf_counter() - t0:.0f} s")
    _plot(curves, args.plot, args.entropy)
    print(f"plot: {args.plot}")


def _plot(curves, path: str, threshold: float) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    grid = np.linspace(0.0, 1.0, 101)
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4))
    for p, runs in curves.items():
        acc = np.array([np.interp(grid, k, np.nan_to_num(a), left=0.0) for k, a, _ in runs])
        ent = np.array([np.interp(grid, k, h, left=np.log10(3)) for k, _, h in runs])
        a1.plot(grid * 100, np.median(acc, axis=0), label=p)
        a2.plot(grid * 100, np.median(ent, axis=0), label=p)
    a1.axhline(ACCURACY, color="k", lw=0.5, ls="--")
    a2.axhline(threshold, color="k", lw=0.5, ls="--")
    a1.set_xlabel("presses (% of the grid's cells)")
    a2.set_xlabel("presses (% of the grid's cells)")
    a1.set_ylabel("accuracy of the post-processed map (median over scenes)")
    a2.set_ylabel("mean entropy of the post-processed map (log10)")
    a1.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    main()
