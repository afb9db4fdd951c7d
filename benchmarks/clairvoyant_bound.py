"""The fewest presses any planner needs on a scene: an exact bound for the exploration benchmark's worst-scene target.

benchmarks/clairvoyant.py's greedy planner knows every reading in advance but is greedy, so a scene it needs many
presses for may still be easy for a better planner. This bound is exact instead. With the seed's post-processing
(eq. 6.15, one pass) an unpressed cell's material is the 1/H-weighted mean of its pressed 8-neighbours, so once the
reading of every cell is fixed (one draw per cell, as the clairvoyant's), whether a cell ends up right is a linear
condition on which of its neighbours are pressed:

* a pressed cell is right iff its own reading names its true material (decided);
* an unpressed cell is right iff, for every other material m, sum_j x_j w_j (p_j[true] - p_j[m]) > 0 over its
  8-neighbours j (x_j = 1 if pressed, w_j = 1/H of the pressed cell's distribution p_j).

The smallest press set with at least 95% of the ceiling's cells right is then a small integer programme (a few
hundred binaries; scipy's HiGHS), solved exactly (a solve cut short at its time limit prints its proven lower bound
too). It knows the readings *and* the truth, so no planner with those readings does better (up to :data:`MARGIN`, a
win by less than which it does not count): if it needs more than 0.7 of raster's presses, the worst-scene target
cannot be met on that scene with this map. Every solution is replayed through the real map
(family_runs.postprocess, ``map_accuracy``) before it is reported.

The programme models the map without the calibration's wall tempering (MapCalibration.wall_reliability): the
tempering lowers a pressed cell by how much its pressed edge-neighbours disagree, so an unpressed cell's 1/H
weights would depend on pairs of presses, not on each press alone, and the condition would no longer be linear. The
tempering keeps every cell's most probable material, so it moves only unpressed cells whose neighbours nearly tie;
the replay scores what a run scores (the tempered map), and a solution whose replay misses the target says so
(its accuracy is printed below the target). Readings are one draw per cell; ``--draws``
repeats with others.

``--readings-only`` plans without the truth, as a planner that has seen every reading could: the fewest presses
whose map agrees with the every-cell-pressed map on enough cells for the replay against the truth to reach the
target (a search, not a bound; it shows what knowing the readings alone allows).

Run: .venv/bin/python benchmarks/clairvoyant_bound.py --seeds 7,30,59 [--draws 3] [--readings-only] [--json PATH]
(or --from-json a table of benchmarks/exploration_families.py: its scenes with info_gain above the target).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.optimize import Bounds, LinearConstraint, milp
from scipy.sparse import coo_matrix

sys.path.insert(0, str(Path(__file__).resolve().parent))

from clairvoyant import cell_readings  # noqa: E402
from family_runs import OF_CEILING, offline_run, postprocess  # noqa: E402
from scene_families import scene  # noqa: E402

from palpate.core.mapping.accuracy import decided_labels, map_accuracy  # noqa: E402
from palpate.core.mapping.grids import new_map  # noqa: E402
from palpate.core.mapping.neighbourhood import NEIGHBOURS_8  # noqa: E402
from palpate.core.mapping.probability import entropy_unchecked  # noqa: E402
from palpate.core.world.workspace import ground_truth_map, object_geometry  # noqa: E402

#: Margin (in units of a constraint's largest coefficient) an extrapolated cell's true material must win by: well
#: above HiGHS's feasibility tolerance (1e-6), which would otherwise let a tie count as a win; the replay checks
#: every solution.
MARGIN = 1e-4
#: Seconds HiGHS may take per scene; a solve cut short reports its proven lower bound beside its best press set.
TIME_LIMIT_S = 60.0
#: Seconds per solve of the readings-only search (several solves a scene; a good press set, not a bound).
SEARCH_LIMIT_S = 15.0


@dataclass(frozen=True)
class Bound:
    """The fewest presses to a target on one scene and one draw of readings.

    Attributes:
        presses: the smallest press set found (None: no press set reaches the target with these readings).
        lower: proven lower bound on it (equal to ``presses`` when the solve finished).
        pressed: (ny, nx) the press set.
        accuracy: the replayed map's accuracy with that set (>= the target).
        own_only: cells that can be right only if pressed themselves (no set of neighbours extrapolates them
            right) and whose own reading is right.
        never: cells that no press set gets right (their reading is wrong and no neighbour set extrapolates
            them right).
        allowed_misses: how many counted cells may be wrong at the target.
    """

    presses: int | None
    lower: int
    pressed: np.ndarray
    accuracy: float | None
    own_only: int
    never: int
    allowed_misses: int


def _pressed_map(fs, readings: np.ndarray, mask: np.ndarray):
    """The scene's map after a press at every cell of ``mask`` (ny, nx), reading ``readings[iy, ix]`` (a
    posterior, (M,)) there, and the run's calibration."""
    sc = fs.scenario("raster")
    cal = sc.exploration.calibration
    grid = new_map(object_geometry(sc, sc.objects[0]))
    iy, ix = np.nonzero(mask)
    grid.update_cells(ix, iy, np.stack([cal.evidence(r) for r in readings[iy, ix]]))
    return grid, cal


def pressed_distributions(fs, readings: np.ndarray) -> np.ndarray:
    """(ny, nx, M) each cell's distribution after one press reading ``readings[iy, ix]`` (a posterior, (M,))."""
    grid, _ = _pressed_map(fs, readings, np.ones(readings.shape[:2], bool))
    return np.array(grid.probabilities)


def _neighbour_margins(p: np.ndarray, truth: np.ndarray, base: float) -> list[tuple[int, list[int], np.ndarray]]:
    """Per counted cell: (flat index, its in-grid 8-neighbours' flat indices, margins (neighbours, M)):
    w_j (p_j[truth] - p_j[m]) of each neighbour, what it adds to the true material's lead over m."""
    ny, nx, _ = p.shape
    w = 1.0 / np.maximum(entropy_unchecked(p, base), 1e-12)
    out = []
    for iy in range(ny):
        for ix in range(nx):
            t = truth[iy, ix]
            if t < 0:
                continue
            nb = [(iy + dy, ix + dx) for dy, dx in NEIGHBOURS_8 if 0 <= iy + dy < ny and 0 <= ix + dx < nx]
            flat = [a * nx + b for a, b in nb]
            d = np.array([w[a, b] * (p[a, b, t] - p[a, b]) for a, b in nb])
            out.append((iy * nx + ix, flat, d))
    return out


def _extrapolable(d: np.ndarray, t: int) -> bool:
    """Whether some non-empty set of neighbours (rows of ``d``) gives material ``t`` a lead over every other."""
    k = d.shape[0]
    masks = (np.arange(1, 2 ** k)[:, None] >> np.arange(k)) & 1  # every non-empty subset
    lead = masks @ d  # (subsets, M)
    lead[:, t] = np.inf
    return bool((lead.min(axis=1) > MARGIN * np.abs(d).max()).any())


def fewest_presses(p: np.ndarray, truth: np.ndarray, need: int, base: float,
                   time_limit: float = TIME_LIMIT_S) -> tuple:
    """Solve the integer programme (module docstring): the smallest press set with ``need`` counted cells right.
    Returns (press mask (ny, nx) or None, proven lower bound, own_only, never); a solve cut short at
    ``time_limit`` s returns its best press set so far."""
    ny, nx, m = p.shape
    n = nx * ny
    label, decided = decided_labels(p)
    right_pressed = ((label == truth) & decided & (truth >= 0)).reshape(-1)
    cells = _neighbour_margins(p, truth, base)
    # variables: x (n presses), a (n: cell right), z (n: cell right by extrapolation)
    rows, cols, vals, lo, hi = [], [], [], [], []

    def add(entries, lower, upper):
        r = len(lo)
        for c, v in entries:
            rows.append(r)
            cols.append(c)
            vals.append(v)
        lo.append(lower)
        hi.append(upper)

    own_only = never = 0
    z_free = np.zeros(n, dtype=bool)
    for c, nb, d in cells:
        t = int(truth.reshape(-1)[c])
        can_z = _extrapolable(d, t)
        z_free[c] = can_z
        own_only += int(right_pressed[c] and not can_z)
        never += int(not right_pressed[c] and not can_z)
        # a_c <= r_c x_c + z_c
        add([(n + c, 1.0)] + ([(c, -1.0)] if right_pressed[c] else []) + ([(2 * n + c, -1.0)] if can_z else []),
            -np.inf, 0.0)
        if not can_z:
            continue
        add([(2 * n + c, 1.0), (c, 1.0)], -np.inf, 1.0)  # z_c only when c is not pressed
        for mm in range(m):
            if mm == t:
                continue
            col = d[:, mm] / np.abs(d).max()
            floor = float(np.minimum(col, 0.0).sum())
            # z_c = 1 => sum_j x_j col_j >= MARGIN; z_c = 0 => the sum's own lower bound
            add([(j, float(v)) for j, v in zip(nb, col, strict=True)] + [(2 * n + c, -(MARGIN - floor))],
                floor, np.inf)
    add([(n + c, 1.0) for c, _, _ in cells], need, np.inf)
    a = coo_matrix((vals, (rows, cols)), shape=(len(lo), 3 * n)).tocsr()
    upper = np.ones(3 * n)
    upper[2 * n:][~z_free] = 0.0
    cost = np.concatenate([np.ones(n), np.zeros(2 * n)])
    res = milp(cost, constraints=LinearConstraint(a, lo, hi), integrality=np.ones(3 * n),
               bounds=Bounds(np.zeros(3 * n), upper), options={"time_limit": time_limit})
    if res.x is None:
        return None, n + 1, own_only, never
    dual = getattr(res, "mip_dual_bound", None)
    lower = int(math.ceil(dual - 1e-6)) if dual is not None and np.isfinite(dual) else 0
    return np.round(res.x[:n]).astype(bool).reshape(ny, nx), lower, own_only, never


def scene_bound(fs, target: float, draw_seed: int, know_truth: bool = True) -> Bound:
    """The bound on scene ``fs`` for accuracy ``target`` (a fraction of its counted cells), the readings drawn
    with ``draw_seed`` (fs.seed + 7000 draws the greedy clairvoyant's), replayed through the real map.

    ``know_truth`` False plans on the readings alone, as a planner that has seen every reading but not the truth
    could: the smallest press set whose map agrees with the every-cell-pressed map on all but k cells, k
    bisected for the largest k whose replay against the truth still reaches ``target`` (a stronger planner than
    the greedy clairvoyant of the same knowledge, not a bound)."""
    sc = fs.scenario("raster")
    entry = sc.objects[0]
    geom = object_geometry(sc, entry)
    truth = ground_truth_map(entry, sc, geom)
    readings = cell_readings(fs, draw_seed)
    p = pressed_distributions(fs, readings)
    counted = int((truth >= 0).sum())
    need = int(math.ceil(target * counted - 1e-9))
    misses = counted - need
    base = new_map(geom).base
    if know_truth:
        return _replayed(fs, readings, truth, target, fewest_presses(p, truth, need, base), misses)
    label, decided = decided_labels(p)
    plan_on = np.where(decided & (truth >= 0), label, -1)
    # the fewest presses that agree with the every-cell map on `k` cells, for the smallest k (bisected) whose
    # replay against the truth reaches the target; a miss at the largest k is reported as it is
    lo, hi = 0, int((plan_on >= 0).sum())
    best = _replayed(fs, readings, truth, target, fewest_presses(p, plan_on, hi, base, SEARCH_LIMIT_S), misses)
    if best.accuracy is None or best.accuracy < target - 1e-12:
        return best
    while hi - lo > 1:
        mid = (lo + hi) // 2
        got = _replayed(fs, readings, truth, target, fewest_presses(p, plan_on, mid, base, SEARCH_LIMIT_S), misses)
        if got.accuracy is not None and got.accuracy >= target - 1e-12:
            hi, best = mid, got
        else:
            lo = mid
    return best


def _replayed(fs, readings: np.ndarray, truth: np.ndarray, target: float, solved: tuple, misses: int) -> Bound:
    """A Bound of an integer programme's press set, its accuracy replayed through the real map."""
    mask, lower, own_only, never = solved
    if mask is None:
        return Bound(None, lower, np.zeros(truth.shape, bool), None, own_only, never, misses)
    grid, cal = _pressed_map(fs, readings, mask)
    acc = map_accuracy(postprocess(grid, cal).probabilities, truth)
    return Bound(int(mask.sum()), max(lower, 0), mask, acc, own_only, never, misses)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default="", help="comma-separated scene seeds")
    parser.add_argument("--from-json", default=None,
                        help="a --json table of exploration_families.py: bound its scenes with an info_gain ratio "
                             "above --above")
    parser.add_argument("--above", type=float, default=0.7)
    parser.add_argument("--draws", type=int, default=1, help="reading draws per scene (the first is the greedy "
                                                             "clairvoyant's)")
    parser.add_argument("--readings-only", action="store_true",
                        help="plan on the readings alone (agreement with the every-cell-pressed map), not the truth")
    parser.add_argument("--json", default=None)
    args = parser.parse_args()
    seeds = [int(s) for s in args.seeds.split(",") if s.strip()]
    known: dict[int, dict] = {}
    if args.from_json:
        doc = json.loads(Path(args.from_json).read_text())
        for key, part in doc.items():
            if not key.endswith("_offline"):
                continue
            for r in part["scenes"]:
                tc = r["to_ceiling"]
                ratios = {k: v / max(tc["raster"], 1) for k, v in tc.items() if k != "raster"}
                known[r["seed"]] = ratios
                if ratios.get("info_gain", 0) > args.above:
                    seeds.append(r["seed"])
    seeds = sorted(set(seeds))
    out = []
    print(f"{'seed':>7} {'family':<10} {'cells':>5} {'raster':>6} {'ceil':>6}  {'info_gain':>9} {'greedy':>6}  "
          f"bound per draw (presses/raster) [own-only, never, misses allowed]")
    for s in seeds:
        fs = scene(s)
        raster = offline_run(fs, "raster")
        ceiling = float(raster.accuracy[-1])
        target = OF_CEILING * ceiling
        base = raster.presses_to(target)
        cells = raster.accuracy.size - 1
        got = []
        for k in range(args.draws):
            b = scene_bound(fs, target, fs.seed + 7000 + k, know_truth=not args.readings_only)
            if b.presses is not None and b.accuracy < target - 1e-12 and not args.readings_only:
                raise RuntimeError(f"seed {s}: the bound's press set replays to {b.accuracy} < {target}")
            got.append(b)
        r = known.get(s, {})
        line = (f"{s:>7} {fs.family:<10} {cells:>5} {base:>6} {ceiling:6.3f}  {r.get('info_gain', float('nan')):9.2f} "
                f"{r.get('clairvoyant', float('nan')):6.2f}  ")
        line += "; ".join((f"{b.presses / base:.2f}" if b.presses is not None else "none")
                          + ("" if b.accuracy is None or b.accuracy >= target - 1e-12 else " (misses the target)")
                          + ("" if b.presses is None or b.lower >= b.presses or args.readings_only
                             else f" (>= {b.lower / base:.2f})")
                          + f" [{b.own_only}, {b.never}, {b.allowed_misses}]" for b in got)
        print(line, flush=True)
        out.append({"seed": s, "family": fs.family, "cells": cells, "raster": base, "ceiling": ceiling, **r,
                    "bound": [{"presses": b.presses, "lower": b.lower, "accuracy": b.accuracy,
                               "own_only": b.own_only, "never": b.never, "allowed_misses": b.allowed_misses,
                               "pressed": b.pressed.astype(int).tolist()} for b in got]})
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
