"""Exploration policies compared on the same seeded heterogeneous scenes: presses to a good map.

The scenes are made so that one press per cell CAN map them (otherwise the benchmark measures perception limits,
not policies): the 8 mm tip's contact at the 4 mm press is ~11 mm across and the analytic fidelity feels the
modulus averaged over that footprint and down the depth, while a cell's truth is one material under its centre.
So: 15 mm cells; a bulk block, sometimes under a skin 28-34 mm thick that is softer than the base (felt as
itself); 1-4 boxes/columns reaching the surface, each >= 32 mm (2 cells) wide, of a material class other than
what surrounds them, 30 mm apart; stiff boxes stand on the table (soft material under a stiff box would be felt in
series); six materials in three classes. The grid's origin is offset by a random fraction of a cell, and feature
walls are then kept >= 5.5 mm from every cell centre (a press on a wall straddles two materials). The column
"all cells" is raster's accuracy after pressing every cell: it must be >= 95% on every scene for the comparison
to be about policies.

Every policy explores the same scenes with one haptic memory trained once. Per policy it prints the presses
needed to reach 95% accuracy of the post-processed map against ground truth, and to bring the post-processed
map's mean entropy under a threshold (median, quartiles, how many scenes got there), plus info_gain's median
ratio to raster. It writes a plot of accuracy and mean entropy against presses (median over scenes) to --plot.

--passes sets exploration.extrapolation_passes (eq. 6.15 repeated; 1 = the seed, "all" = until every cell is
filled) for every policy alike, so the comparison stays fair.

Run: .venv/bin/python benchmarks/exploration.py [--quick] [--scenes N] [--seed0 S] [--policies a,b]
     [--fidelity analytic|rigid] [--passes K|all] [--plot PNG]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from palpate.core.mapping.grids import Grid2D
from palpate.core.planning.info_gain import InfoGain
from palpate.core.planning.outcomes import outcome_posteriors, outcome_table
from palpate.core.session.explore import explore_object
from palpate.core.session.progress import Progress
from palpate.core.session.report import object_summary
from palpate.core.session.sources import scenario_source_maker
from palpate.core.session.training import train_memory
from palpate.core.world.scenario_file import parse_scenario

#: Benchmark rows: name -> (scenario policy, info_gain objective). "info_gain" is the default (accuracy) objective.
ROWS = {"raster": ("raster", None), "random": ("random", None), "predefined": ("predefined", None),
        "max_entropy": ("max_entropy", None), "info_gain_entropy": ("info_gain", "entropy"),
        "info_gain": ("info_gain", "accuracy")}
POLICIES = tuple(ROWS)
ACCURACY = 0.95
CELL_MM = 15.0

MATERIALS = [
    {"name": "soft", "young_kpa": 20.0, "poisson": 0.3},
    {"name": "medium", "young_kpa": 115.0, "poisson": 0.45},
    {"name": "hard", "young_kpa": 450.0, "poisson": 0.4},
    {"name": "foam", "young_kpa": 26.0, "poisson": 0.3, "reference": False, "like": "soft"},
    {"name": "rubber", "young_kpa": 100.0, "poisson": 0.45, "reference": False, "like": "medium"},
    {"name": "lump", "young_kpa": 520.0, "poisson": 0.4, "reference": False, "like": "hard"},
]
NAMES = ["soft", "medium", "hard", "foam", "rubber", "lump"]


RANK = {"soft": 0, "medium": 1, "hard": 2}
CLASS = {"soft": "soft", "foam": "soft", "medium": "medium", "rubber": "medium", "hard": "hard", "lump": "hard"}
#: Features a press resolves: the 8 mm tip's contact at 4 mm is ~11 mm across, so every inclusion is at least
#: MIN_FEATURE_MM wide and features keep GAP_MM of the surrounding material between them and from the edges.
MIN_FEATURE_MM = 32.0
GAP_MM = 30.0
EDGE_CLEAR_MM = 5.5


def _clear_of_centres(edges: tuple[float, float], origin: float) -> tuple[float, float]:
    """Move each edge coordinate (mm) to at least EDGE_CLEAR_MM from the nearest cell centre of a grid starting
    at ``origin`` (mm): into the band around the cell boundary nearest to it."""
    out = []
    for e in edges:
        b = origin + round((e - origin) / CELL_MM) * CELL_MM
        slack = CELL_MM / 2 - EDGE_CLEAR_MM
        out.append(b + float(np.clip(e - b, -slack, slack)))
    return out[0], out[1]


def _place(rng, sx: float, sy: float, w: float, h: float, taken: list) -> tuple[float, float] | None:
    """Centre of a w x h footprint inside the block, GAP_MM clear of the edges and of ``taken`` rectangles."""
    for _ in range(60):
        cx = rng.uniform(GAP_MM / 2 + w / 2, sx - GAP_MM / 2 - w / 2) if sx > w + GAP_MM else sx / 2
        cy = rng.uniform(GAP_MM / 2 + h / 2, sy - GAP_MM / 2 - h / 2) if sy > h + GAP_MM else sy / 2
        if all(abs(cx - x) >= (w + tw) / 2 + GAP_MM or abs(cy - y) >= (h + th) / 2 + GAP_MM
               for x, y, tw, th in taken):
            return cx, cy
    return None


def scene_dict(seed: int, fidelity: str, policy: str, budget: int, passes: int | None = 1,
               objective: str | None = None) -> dict:
    """A seeded heterogeneous scene as a scenario dictionary (the TOML schema), one object.

    Made to be resolvable by one press per cell (see the module docstring): a bulk block, sometimes under a top
    layer 10-16 mm thick (far thicker than the 4 mm press), and 2-4 inclusions reaching the surface -- boxes,
    columns and near-surface spheres -- each at least MIN_FEATURE_MM wide, of a material class other than what
    surrounds it, GAP_MM apart; the grid's origin is offset by a random fraction of a cell.
    """
    rng = np.random.default_rng(seed)
    sx, sy, sz = rng.uniform(150, 200), rng.uniform(120, 160), 40.0
    bulk = str(rng.choice(NAMES))
    obj = {"name": f"scene{seed}", "size_mm": [sx, sy, sz], "position_mm": [sx / 2, sy / 2], "material": bulk,
           "inclusions": [], "layers": []}
    surround = bulk
    off = rng.uniform(0.1, 0.9, 2) * CELL_MM
    softer = [n for n in NAMES if RANK[CLASS[n]] < RANK[CLASS[bulk]]]
    if softer and rng.random() < 0.4:
        # A skin softer than the base: a press feels a stiffer base below a soft skin only a little (compliances
        # in series), so the skin is what a press reads; a stiff skin over a soft base would read as neither.
        surround = str(rng.choice(softer))
        obj["layers"].append({"material": surround, "thickness_mm": float(rng.uniform(28.0, 34.0))})
    taken: list[tuple[float, float, float, float]] = []
    for _ in range(int(rng.integers(2, 5))):
        kind = str(rng.choice(["box", "column"]))
        mat = str(rng.choice([n for n in NAMES if CLASS[n] != CLASS[surround]]))
        w, h = rng.uniform(MIN_FEATURE_MM, 60), rng.uniform(MIN_FEATURE_MM, 55)
        spot = _place(rng, sx, sy, w, h, taken)
        if spot is None:
            continue
        # No cell centre within EDGE_CLEAR_MM of a wall: a press there straddles two materials and reads as
        # neither (the stiff side dominates in parallel), while the truth is the one under the centre.
        (x0, x1), (y0, y1) = (_clear_of_centres(v, off[i]) for i, v in
                              enumerate(((spot[0] - w / 2, spot[0] + w / 2), (spot[1] - h / 2, spot[1] + h / 2))))
        cx, cy, w, h = (x0 + x1) / 2, (y0 + y1) / 2, x1 - x0, y1 - y0
        taken.append((cx, cy, w, h))
        if kind == "box":
            # A stiff box stands on the table (soft material under it would be felt in series); a soft one is a
            # pocket over whatever is below (the soft part dominates the series).
            bz = sz if RANK[CLASS[mat]] > RANK[CLASS[surround]] else rng.uniform(15, 30)
            inc = {"shape": "box", "center_mm": [cx, cy, sz - bz / 2], "size_mm": [w, h, bz]}
        else:
            inc = {"shape": "column", "center_mm": [cx, cy], "size_mm": [w, h]}
        inc["material"] = mat
        obj["inclusions"].append(inc)
    cells = [int((sx - off[0]) // CELL_MM), int((sy - off[1]) // CELL_MM)]
    obj["grid_origin_mm"] = [float(off[0]), float(off[1])]
    obj["grid_cells"] = cells
    # The predefined list: a planned stride-3 pattern, as a person would lay out regions in advance.
    obj["regions"] = [[c + 1, r + 1] for r in range(1, cells[1], 3) for c in range(1, cells[0], 3)]
    ex = {"policy": policy, "budget": budget, "presses_per_region": 1, "cell_mm": CELL_MM, "depth_mm": 4.0,
          "max_force_n": 10.0, "variability": "human", "extrapolation_passes": "all" if passes is None else passes}
    if objective is not None:
        ex["objective"] = objective
    return {"scenario": {"name": f"scene{seed}", "seed": seed, "fidelity": fidelity},
            "materials": MATERIALS, "training": {"presses_per_material": 10, "depth_mm": 4.0, "max_force_n": 10.0},
            "exploration": ex, "objects": [obj], "outputs": {"figures": False, "haptic_material": False}}


def chosen_rows(text: str, parser: argparse.ArgumentParser) -> list[str]:
    """The benchmark rows named in a comma-separated ``--policies`` value, in table order, raster always
    included (the ratios are to it); an unknown name is a usage error naming the known ones."""
    chosen = [p.strip() for p in text.split(",") if p.strip()]
    unknown = sorted(set(chosen) - set(ROWS))
    if unknown:
        parser.error(f"unknown policies {unknown}; known: {', '.join(ROWS)}")
    return [p for p in ROWS if p in chosen or p == "raster"]


def make_source_for(scenario):
    """``make(objects, seed, variability)``: the run's own source maker
    (:func:`~palpate.core.session.sources.scenario_source_maker`), whose sources share one dict of contact laws:
    policies explored with one maker solve a press point's law once."""
    return scenario_source_maker(scenario)


def first_reaching(values: list, ok) -> int | None:
    """1-based press count at which ``ok(value)`` first holds, or None."""
    for k, v in enumerate(values):
        if v is not None and ok(v):
            return k + 1
    return None


def gain_timing(memory, repeats: int = 5) -> tuple[float, int]:
    """Median time (s) of one info_gain choice among 100 x 100 cells, 3% explored, scoring every cell (choices after
    a press rescore only around it: benchmarks/planning_scale.py); and the outcome groups used."""
    rng = np.random.default_rng(3)
    grid = Grid2D(memory.materials, (100, 100))
    q = outcome_posteriors(memory)
    for _ in range(300):
        t = int(rng.integers(len(memory.materials)))
        grid.update_cell(int(rng.integers(100)), int(rng.integers(100)), q[t, int(rng.integers(q.shape[1]))])
    post = grid.postprocessed()
    policy = InfoGain(memory, incremental=False)
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
    parser.add_argument("--entropy", type=float, default=0.1,
                        help="mean-entropy threshold of the post-processed map, log10 units (max 0.477; a cell "
                             "pressed once keeps ~0.085 with the default map calibration)")
    parser.add_argument("--passes", default="1", type=_passes_arg,
                        help='eq. 6.15 passes of the post-processing, the same for every policy: an integer or "all"')
    parser.add_argument("--plot", default="/tmp/palpate_exploration.png", help="PNG of accuracy/entropy vs presses")
    parser.add_argument("--seed0", type=int, default=0,
                        help="first scene seed (default 0; e.g. 100 for scenes the policies were not tuned on)")
    parser.add_argument("--policies", default=",".join(POLICIES),
                        help=f"comma-separated rows to run (default all: {','.join(POLICIES)}); raster is always run")
    args = parser.parse_args()
    n_scenes = args.scenes or (6 if args.quick else 24)
    policies = chosen_rows(args.policies, parser)
    passes = None if args.passes == "all" else int(args.passes)

    t0 = time.perf_counter()
    base = parse_scenario(scene_dict(0, args.fidelity, "raster", 1), "bench")
    training = train_memory(base, make_source_for(base), np.arange(3) + 1000, Progress(enabled=False))
    memory, crossval = training.memory, training.crossval
    t_gain, groups = gain_timing(memory)
    print(f"memory: {len(memory.materials)} materials, leave-one-out accuracy "
          f"{np.mean(np.diag(np.asarray(crossval.confusion))):.2f}; info_gain scoring all of 10,000 cells: "
          f"{t_gain * 1e3:.1f} ms ({groups} outcome groups)")

    curves: dict[str, list[tuple[np.ndarray, np.ndarray]]] = {p: [] for p in policies}
    to_acc: dict[str, list[int | None]] = {p: [] for p in policies}
    to_h: dict[str, list[int | None]] = {p: [] for p in policies}
    caps: list[int] = []
    full_acc: list[float] = []
    wall: dict[str, float] = dict.fromkeys(policies, 0.0)
    for s in range(args.seed0, args.seed0 + n_scenes):
        probe = parse_scenario(scene_dict(s, args.fidelity, "raster", 1), "bench")
        nx, ny = probe.objects[0].grid_shape
        budget = nx * ny
        caps.append(budget)
        for policy in policies:
            kind, objective = ROWS[policy]
            sc = parse_scenario(scene_dict(s, args.fidelity, kind, budget, passes, objective), f"scene{s}")
            t1 = time.perf_counter()
            summary = object_summary(explore_object(sc, sc.objects[0], memory, make_source_for(sc), 7000 + s,
                                                    Progress(enabled=False)))
            wall[policy] += time.perf_counter() - t1
            acc = [r["accuracy_all_cells_postprocessed"] for r in summary["per_press"]]
            ent = [r["mean_entropy_postprocessed"] for r in summary["per_press"]]
            if policy == "raster":
                full_acc.append(acc[-1])
            to_acc[policy].append(first_reaching(acc, lambda v: v >= ACCURACY))
            to_h[policy].append(first_reaching(ent, lambda v: v <= args.entropy))
            k = np.arange(1, len(acc) + 1) / budget
            curves[policy].append((k, np.array([np.nan if a is None else a for a in acc]), np.array(ent)))
        print(f"scene {s:2d}: {nx}x{ny} cells; all cells {full_acc[-1]:.1%}; presses to {ACCURACY:.0%}: "
              + ", ".join(f"{p} {to_acc[p][-1]}" for p in policies), flush=True)

    print()
    print(f"{n_scenes} scenes (seeds {args.seed0}-{args.seed0 + n_scenes - 1}), fidelity {args.fidelity}, "
          f"{CELL_MM:.0f} mm cells, eq. 6.15 passes {args.passes}, "
          "budget = number of cells "
          f"(median {int(np.median(caps))}); 'never' runs count as budget + 1 in the quartiles")
    print(f"accuracy with every cell pressed (raster's last press): min {min(full_acc):.1%}, median "
          f"{np.median(full_acc):.1%}; scenes under {ACCURACY:.0%}: {sum(a < ACCURACY for a in full_acc)}")
    print(f"{'policy':<18} {'presses to ' + format(ACCURACY, '.0%') + ' accuracy':>30} "
          f"{'presses to mean H <= ' + format(args.entropy, 'g'):>32} {'wall s':>8}")
    print(f"{'':<18} {'median [q1, q3]   reached':>30} {'median [q1, q3]   reached':>32}")
    for p in policies:
        print(f"{p:<18} {_stats(to_acc[p], caps):>30} {_stats(to_h[p], caps):>32} {wall[p]:8.1f}")
    for p in ("info_gain", "info_gain_entropy"):
        if p not in to_acc:
            continue
        # a scene info_gain never mapped counts as budget + 1 presses, so a failure cannot flatter the median
        ratios = [(g if g else c + 1) / r for g, r, c in zip(to_acc[p], to_acc["raster"], caps, strict=True) if r]
        if ratios:
            print(f"{p} / raster presses to {ACCURACY:.0%} (n = {len(ratios)}): median {np.median(ratios):.2f}, "
                  f"quartiles [{np.percentile(ratios, 25):.2f}, {np.percentile(ratios, 75):.2f}], range "
                  f"[{min(ratios):.2f}, {max(ratios):.2f}]; target <= 0.33")
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
