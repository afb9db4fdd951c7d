"""Exploration scored on the fine (1 mm) material map: raster, max_entropy, info_gain and boundary side by side on
the shape-family scenes (benchmarks/scene_families.py) with physics presses (``auto``: the image rung beside walls).

Per policy and scene: the presses until the fine map labels 95% of the area right (as a share of the raster's
presses, i.e. of the cells; a run that never gets there counts as cells + 1; with raster among the policies also
until 95% or the raster's final area right less 2 points, whichever is lower: a scene a full raster maps only to
96% is then met at 94%), the area right after every cell's worth of presses, and the area the fine map gets wrong
after a tenth (and a quarter) of the raster's presses against the area the cell map gets wrong after the full
raster (the symmetric difference of the labelled and the true regions). The tables give the median, the 95th
percentile and the mean of that share: a median that falls between far-apart scenes moves with one scene, the mean
with all. Every policy explores the same scene with the same trained memory; a policy's run is as long as the
raster's.

Seeds below 100000 are tuning seeds, from 100000 on report seeds (never tuned on); the tables print them apart,
per family, and each policy against max_entropy scene by scene (fewer / more presses, a one-sided Wilcoxon
signed-rank p, and per family the median of the paired differences: with ten scenes a family, two family medians
compared apart swap on noise). --clairvoyant adds the boundary policy told where its fine map is wrong (its
expected errors are the true ones): what a planner that knew where the map is wrong would score with the same
presses and readings.
--share S ends every run after S of the raster's presses (quicker tuning runs; a run that has not reached the
target by then counts as cells + 1). --stays also scores the press after which the fine map stays at the target to
the end of the run (the first press there can be a lucky guess a later press undoes; the fine map is then rebuilt
after every press, which costs about twice the run): per policy its median and p95, and against max_entropy scene by
scene (fewer / more presses, one-sided Wilcoxon signed-rank p).

--calibration also keeps, per policy and scene, the fine map's reliability bins after 0.1, 0.25, 0.5 and all of the
raster's presses, over all points and within 5 mm of a wall, and prints the ECE pooled over a split's scenes: how
honest the map is while the presses are still sparse.

--jobs J runs J scenes at once in separate processes (rows and tables as with one; the wall time printed last).

Run: .venv/bin/python benchmarks/exploration_fine.py [--first 0] [--scenes 9] [--policies raster,boundary]
     [--clairvoyant] [--share S] [--stays] [--calibration] [--boundary FIELD=VALUE ...] [--jobs J] [--json PATH]
     [--from-json PATH ...]
"""

from __future__ import annotations

import argparse
import json
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np
from fine_map_families import trained_scene
from scene_families import is_report_seed

from palpate.api import register_policy
from palpate.core.mapping.calibration import binned_calibration, calibration_sample, reliability_table
from palpate.core.mapping.fine import fine_map
from palpate.core.mapping.grids import new_map
from palpate.core.planning.boundary_seeking import BoundarySeeking
from palpate.core.session.boundaries import NEAR_BOUNDARY, fine_truth, near_boundaries, training_moduli
from palpate.core.session.explore import MapPostprocessing, apply_press, explore_object
from palpate.core.session.progress import Progress
from palpate.core.world.workspace import object_geometry

POLICIES = ("raster", "max_entropy", "info_gain", "boundary")
CLAIRVOYANT = "clairvoyant_boundary"


class ClairvoyantBoundary(BoundarySeeking):
    """The boundary policy told the truth on the fine raster: its expected errors are the true errors."""

    truth: np.ndarray | None = None

    def expected_errors(self, fine) -> np.ndarray:
        known = self.truth >= 0
        return ((fine.labels() != self.truth) & known).astype(float)


TUNED = "boundary_set"


def register_tuned(settings: dict) -> None:
    """The boundary policy with some settings replaced, as the row TUNED."""
    register_policy(TUNED, lambda ctx: BoundarySeeking(ctx.memory, ctx.geometry, ctx.moduli, seed=ctx.seed,
                                                       **settings), replace=True)


def register_clairvoyant(truth: np.ndarray) -> None:
    def factory(ctx):
        p = ClairvoyantBoundary(ctx.memory, ctx.geometry, ctx.moduli, seed=ctx.seed)
        p.truth = truth
        return p

    register_policy(CLAIRVOYANT, factory, replace=True)
TARGET = 0.95
#: The ceiling reading's margin: with raster among the policies, a scene's target is also met at its raster's final
#: area right less this, when that is below TARGET (a scene a full raster maps to 96% is met at 94%).
CEILING_MARGIN = 0.02
TENTH = 0.1
#: Shares of raster's presses at which each row keeps the fine map's area right.
SHARES = (0.1, 0.2, 0.25, 0.3, 0.4, 0.5, 1.0)
#: Shares of raster's presses at which --calibration keeps the fine map's reliability bins.
CALIBRATION_SHARES = (0.1, 0.25, 0.5, 1.0)
BINS = 10


def reliability_bins(fine, truth: np.ndarray) -> dict:
    """Per region ("all" known points, "near": within NEAR_BOUNDARY of a true wall), the count, summed confidence
    and right count of the fine map's decided points in each of BINS equal confidence bins (pooled ECE adds them)."""
    known = truth >= 0
    near = known & near_boundaries(truth, fine.resolution)
    out = {}
    for where, mask in (("all", known), ("near", near)):
        t = reliability_table(*calibration_sample(fine.probabilities[mask], truth[mask])[:2], bins=BINS)
        out[where] = [t.count.tolist(), (t.count * t.confidence).tolist(), (t.count * t.accuracy).tolist()]
    return out


def pooled_ece(bins: list) -> float:
    """The ECE of reliability bins summed over scenes (a list of [count, confidence sum, right sum] triples)."""
    return binned_calibration(*(np.sum([np.asarray(b[i], dtype=float) for b in bins], axis=0) for i in range(3)))[2]


def fine_curve(sc, res, memory, moduli, truth, keep: set[int] = frozenset(),
               on_rebuild=None) -> tuple[np.ndarray, np.ndarray]:
    """Per press k = 1..N of an exploration, the share of the known area the fine map and the cell map label
    right, rebuilt press by press as the run's maps are: every press until the fine map first reaches
    :data:`TARGET`, then only the press counts in ``keep`` (1-based) and the last; NaN where not rebuilt (the maps
    are rebuilt from all the presses so far, so a rebuild costs as much as the press count). ``on_rebuild(k, fine)``
    is called with each rebuilt fine map."""
    ex = sc.exploration
    grid = new_map(res.geometry)
    settings = MapPostprocessing.of(ex)
    known = truth >= 0
    n = len(res.steps)
    fine_acc, cell_acc = np.full(n, np.nan), np.full(n, np.nan)
    readings, reached = [], False
    for k, s in enumerate(res.steps, start=1):
        apply_press(grid, s.result, memory, None, fallback_xy=s.target, calibration=ex.calibration)
        if s.boundary is not None:
            readings.append((s.result.location, s.boundary))
        if reached and k not in keep and k != n:
            continue
        post = settings.apply(grid, ex.calibration)
        fine = fine_map(res.geometry, post.probabilities, readings, moduli=moduli)
        if on_rebuild is not None:
            on_rebuild(k, fine)
        cells = fine.cells_on_raster(np.argmax(post.probabilities, axis=-1))
        fine_acc[k - 1] = float(np.mean(fine.labels()[known] == truth[known]))
        cell_acc[k - 1] = float(np.mean(cells[known] == truth[known]))
        reached = reached or fine_acc[k - 1] >= TARGET
    return fine_acc, cell_acc


def first_at(curve: np.ndarray, level: float) -> int | None:
    hit = np.flatnonzero(curve >= level)
    return int(hit[0]) + 1 if len(hit) else None


def stays_at(curve: np.ndarray, level: float) -> int | None:
    """The press (1-based) from which ``curve`` stays at or above ``level`` to its end; None if it ends below."""
    below = np.flatnonzero(curve < level)
    if len(below) and below[-1] == len(curve) - 1:
        return None
    return int(below[-1]) + 2 if len(below) else 1


def scene_rows(seed: int, policies: tuple[str, ...], share: float = 1.0, stays: bool = False,
               calibration: bool = False) -> list[dict]:
    fs, base, reader, make, training = trained_scene(seed)
    moduli = training_moduli(training.readings)
    rows = []
    cells = int(np.prod(fs.grid_cells))
    geometry = object_geometry(base, base.objects[0])
    truth = fine_truth(base.objects[0], base, fine_map(geometry, new_map(geometry).probabilities, []))
    register_clairvoyant(truth)
    ceiling = None
    # raster first: its final area right sets the ceiling reading's level for the others
    for policy in sorted(policies, key=lambda p: p != "raster"):
        sc = fs.scenario(policy, budget=max(1, int(np.ceil(share * cells))), fidelity="auto")
        t0 = time.process_time()
        res = explore_object(sc, sc.objects[0], training.memory, make, 7000 + seed, Progress(enabled=False),
                             boundary_reader=reader, moduli=moduli)
        n = cells
        tenth = max(1, int(round(TENTH * n)))
        keep = {min(tenth, len(res.steps))} | {max(1, int(round(q * n))) for q in SHARES}
        if stays:
            keep = set(range(1, len(res.steps) + 1))
        at_share = {max(1, int(round(q * n))): f"{q:g}" for q in CALIBRATION_SHARES} if calibration else {}
        keep |= {k for k in at_share if k <= len(res.steps)}
        bins = {}

        def keep_bins(k, fine, at_share=at_share, bins=bins):
            if k in at_share:
                bins[at_share[k]] = reliability_bins(fine, truth)

        fine, cell = fine_curve(sc, res, training.memory, moduli, truth, keep, keep_bins)
        if policy == "raster" and len(res.steps) == cells:
            ceiling = float(fine[-1])
        # every press is rebuilt until the map first reaches TARGET, so a lower level's first press is in the curve
        level = None if ceiling is None else min(TARGET, ceiling - CEILING_MARGIN)
        rows.append({"seed": seed, "family": fs.family, "split": "report" if is_report_seed(seed) else "tuning",
                     "policy": policy, "cells": n, "presses": len(res.steps), "to_target": first_at(fine, TARGET),
                     "fine_final": float(fine[-1]), "cell_final": float(cell[-1]),
                     "fine_tenth": float(fine[min(tenth, len(fine)) - 1]),
                     "fine_at": {f"{q:g}": float(fine[k - 1]) for q in SHARES
                                 if (k := max(1, int(round(q * n)))) <= len(fine)},
                     "off_centre": sum(1 for s in res.steps if s.target != tuple(
                         res.geometry.cell_centres()[s.cell[1], s.cell[0]])),
                     "cpu_s": time.process_time() - t0} | ({"stays": stays_at(fine, TARGET)} if stays else {})
                    | ({"calibration": bins} if calibration else {})
                    | ({"to_ceiling": first_at(fine, level), "ceiling": ceiling} if level is not None else {}))
    return sorted(rows, key=lambda r: policies.index(r["policy"]))


def ratio(r: dict, key: str = "to_target") -> float:
    return (r[key] if r[key] is not None else r["cells"] + 1) / r["cells"]


def paired(part: list[dict], policy: str, key: str = "to_target") -> tuple[np.ndarray, list[str]]:
    """Per scene of ``part`` run by both, ``policy``'s ratio less max_entropy's, and the scenes' families."""
    mine = {r["seed"]: r for r in part if r["policy"] == policy}
    base = {r["seed"]: r for r in part if r["policy"] == "max_entropy"}
    seeds = sorted(set(mine) & set(base))
    return (np.array([ratio(mine[s], key) - ratio(base[s], key) for s in seeds]),
            [mine[s]["family"] for s in seeds])


def paired_text(d: np.ndarray) -> str:
    """'fewer / more, p': scenes with fewer and more presses than max_entropy, one-sided Wilcoxon signed-rank p."""
    from scipy.stats import wilcoxon

    pval = wilcoxon(d, alternative="less").pvalue if np.any(d != 0) else 1.0
    return f"{int(np.sum(d < 0))} / {int(np.sum(d > 0))}, p {pval:.3f}"


def report_stays(part: list[dict], policies: tuple[str, ...]) -> None:
    """The --stays reading of one split: per policy, and each policy against max_entropy scene by scene."""
    by = {p: [ratio(r, "stays") for r in part if r["policy"] == p] for p in policies}
    print(f"presses after which the fine map stays at {TARGET:.0%} / raster's: policy, median, p95, against "
          "max_entropy (fewer / more presses, one-sided Wilcoxon p)")
    for p in policies:
        line = f"  {p:12} {np.median(by[p]):7.2f} {np.percentile(by[p], 95):6.2f}"
        if p != "max_entropy" and by.get("max_entropy"):
            line += "   " + paired_text(paired(part, p, "stays")[0])
        print(line)


def report_paired(part: list[dict], policies: tuple[str, ...]) -> None:
    """Each policy against max_entropy scene by scene: over the split, and per family the median of the paired
    differences with its scenes fewer / more (a family's two medians compared apart mislead on a few scenes)."""
    others = [p for p in policies if p != "max_entropy"]
    if "max_entropy" not in policies or not others:
        return
    print("against max_entropy, scene by scene (ratio difference; fewer / more presses, one-sided Wilcoxon p):")
    for p in others:
        d, fams = paired(part, p)
        print(f"  {p:12} median {np.median(d):+.3f}   {paired_text(d)}")
        for f in sorted(set(fams)):
            df = d[[k for k, g in enumerate(fams) if g == f]]
            print(f"  {'':12} {f:10} {np.median(df):+.3f}   {int(np.sum(df < 0))} / {int(np.sum(df > 0))}")
    near = [r for r in part if r["policy"] == "max_entropy"]
    print(f"scenes whose fine map ends below 96% of the area right with max_entropy's presses (the target then "
          f"falls near the run's end): {sum(r['fine_final'] < 0.96 for r in near)} of {len(near)}")


def report_calibration(part: list[dict], policies: tuple[str, ...]) -> None:
    """The --calibration reading of one split: per policy and share of raster's presses, the fine map's ECE
    pooled over the scenes, over all points / within 5 mm of a wall."""
    shares = [f"{q:g}" for q in CALIBRATION_SHARES]
    print("fine map's ECE pooled over the scenes after a share of raster's presses, all points / within "
          f"{NEAR_BOUNDARY * 1e3:g} mm of a wall:")
    print(f"  {'policy':12} " + " ".join(f"{q:>13}" for q in shares))
    for p in policies:
        mine = [r["calibration"] for r in part if r["policy"] == p]
        cells = []
        for q in shares:
            got = [c[q] for c in mine if q in c]
            cells.append(f"{pooled_ece([g['all'] for g in got]):.3f} / {pooled_ece([g['near'] for g in got]):.3f}"
                         if got else "-")
        print(f"  {p:12} " + " ".join(f"{c:>13}" for c in cells))


def report(rows: list[dict], policies: tuple[str, ...]) -> None:
    for split in ("tuning", "report"):
        part = [r for r in rows if r["split"] == split]
        if not part:
            continue
        raster_err = {r["seed"]: 1 - r["cell_final"] for r in part if r["policy"] == "raster"
                      and r["presses"] == r["cells"]}
        print(f"\n{split} seeds ({len({r['seed'] for r in part})} scenes): presses to {TARGET:.0%} of the area right "
              "on the fine map / raster's presses")
        print(f"{'policy':12} {'median':>7} {'p95':>6} {'mean':>6} {'worst':>6} {'reached':>8} {'fine@all':>9} "
              f"{'err@1/10, @1/4 <= raster cell err':>34}")
        for p in policies:
            mine = [r for r in part if r["policy"] == p]
            rs = np.array([ratio(r) for r in mine])
            ok = (f"{sum(1 - r['fine_tenth'] <= raster_err[r['seed']] for r in mine):14d}/{len(mine)}"
                  f"{sum(1 - r['fine_at'].get('0.25', 0.0) <= raster_err[r['seed']] for r in mine):10d}/{len(mine)}"
                  if all(r["seed"] in raster_err for r in mine) else f"{'- (needs a full raster)':>20}")
            print(f"{p:12} {np.median(rs):7.2f} {np.percentile(rs, 95):6.2f} {rs.mean():6.3f} {rs.max():6.2f} "
                  f"{sum(r['to_target'] is not None for r in mine):4d}/{len(mine):<3d} "
                  f"{np.median([r['fine_final'] for r in mine]):9.1%} {ok}")
        if all("to_ceiling" in r for r in part):
            print(f"presses until the area right is {TARGET:.0%} or raster's final less {CEILING_MARGIN:g} if lower "
                  f"/ raster's (scenes whose raster ends below {TARGET + CEILING_MARGIN:.0%}: "
                  f"{len({r['seed'] for r in part if r['ceiling'] < TARGET + CEILING_MARGIN})}): median, p95")
            for p in policies:
                rs = [ratio(r, "to_ceiling") for r in part if r["policy"] == p]
                print(f"  {p:12} {np.median(rs):7.2f} {np.percentile(rs, 95):6.2f}")
        report_paired(part, policies)
        if all("stays" in r for r in part):
            report_stays(part, policies)
        if all("calibration" in r for r in part):
            report_calibration(part, policies)
        fams = sorted({r["family"] for r in part})
        print(f"per family, median ratio: {'family':10} " + " ".join(f"{p:>11}" for p in policies))
        for f in fams:
            cells = [np.median([ratio(r) for r in part if r["family"] == f and r["policy"] == p]) for p in policies]
            print(f"{'':26}{f:10} " + " ".join(f"{c:11.2f}" for c in cells))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--first", type=int, default=0)
    parser.add_argument("--scenes", type=int, default=9)
    parser.add_argument("--policies", default=",".join(POLICIES))
    parser.add_argument("--clairvoyant", action="store_true", help=f"add {CLAIRVOYANT}")
    parser.add_argument("--boundary", action="append", default=[], metavar="FIELD=VALUE",
                        help=f"add the row {TUNED}: the boundary policy with FIELD set (repeatable)")
    parser.add_argument("--share", type=float, default=1.0, help="end runs after this share of raster's presses")
    parser.add_argument("--stays", action="store_true", help="also score the press from which the fine map stays "
                        "at the target (rebuilds the fine map after every press)")
    parser.add_argument("--calibration", action="store_true", help="also keep the fine map's reliability bins "
                        "after 0.1, 0.25, 0.5 and all of raster's presses and print its pooled ECE")
    parser.add_argument("--jobs", type=int, default=1, help="scenes run at once, one process each (default 1)")
    parser.add_argument("--json", default=None, help="write every row to this JSON file")
    parser.add_argument("--from-json", nargs="+", default=None, metavar="PATH",
                        help="print the tables of rows written by earlier runs (--json) instead of running")
    args = parser.parse_args()
    if args.from_json:
        rows = [r for path in args.from_json for r in json.load(open(path))]
        report(rows, tuple(dict.fromkeys(r["policy"] for r in rows)))
        return
    policies = tuple(p.strip() for p in args.policies.split(",") if p.strip()) + (
        (CLAIRVOYANT,) if args.clairvoyant else ()) + ((TUNED,) if args.boundary else ())
    settings = {k: float(v) for k, v in (kv.split("=", 1) for kv in args.boundary)}
    register_tuned(settings)
    seeds = range(args.first, args.first + args.scenes)
    rows, wall = [], time.perf_counter()
    pool = ProcessPoolExecutor(args.jobs, initializer=register_tuned, initargs=(settings,)) if args.jobs > 1 else None
    try:
        scenes = pool.map(scene_rows, seeds, [policies] * len(seeds), [args.share] * len(seeds),
                          [args.stays] * len(seeds), [args.calibration] * len(seeds)) if pool else (
            scene_rows(seed, policies, args.share, args.stays, args.calibration) for seed in seeds)
        for got in scenes:  # in seed order either way
            rows.extend(got)
            print(f"scene {got[0]['seed']} ({got[0]['family']}, {got[0]['cells']} cells): " + ", ".join(
                f"{r['policy']} {ratio(r):.2f} (fine {r['fine_final']:.1%}, {r['off_centre']} off-centre, "
                f"{r['cpu_s']:.0f} s)" for r in got), flush=True)
            if args.json:
                with open(args.json, "w") as fh:
                    json.dump(rows, fh, indent=1)
    finally:
        if pool:
            pool.shutdown(cancel_futures=True)
    report(rows, policies)
    print(f"\n{len(seeds)} scenes x {len(policies)} policies in {time.perf_counter() - wall:.0f} s wall "
          f"({args.jobs} job(s)); exploration CPU {sum(r['cpu_s'] for r in rows):.0f} s")


if __name__ == "__main__":
    main()
