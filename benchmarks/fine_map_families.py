"""The fine (1 mm) material map against the cell map on the shape-family scenes (benchmarks/scene_families.py),
a raster of every cell with physics presses (``auto``: the image rung beside walls), one scene per family.

Per scene: the share of the area each map labels right on the fine raster, the median distance of their
boundaries from the true ones and the fine map's calibration error; then medians, and the calibration error of
every scene's points pooled. Seeds from 100000 on are report seeds (never tuned on).

Run: .venv/bin/python benchmarks/fine_map_families.py [--first 100000] [--scenes 9]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from exploration import make_source_for
from scene_families import FAMILIES, is_report_seed, make_scene

from palpate.core.mapping.calibration import calibration_sample, reliability_table
from palpate.core.session.boundaries import boundary_reader, near_boundaries, object_fine_map, training_moduli
from palpate.core.session.explore import explore_object
from palpate.core.session.progress import Progress
from palpate.core.session.training import train_memory


def trained_scene(seed: int, fs=None):
    """A family scene (``fs``, default the shape family scene of ``seed``) with physics presses (``auto``) as a
    raster scenario, its boundary reader, source maker and memory trained on its references (readings kept):
    (scene, scenario, reader, make, training)."""
    fs = make_scene(seed) if fs is None else fs
    sc = fs.scenario("raster", fidelity="auto")
    reader, why = boundary_reader(sc)
    if reader is None:
        raise SystemExit(f"scene {seed}: {why}")
    make = make_source_for(sc)
    training = train_memory(sc, make, np.arange(len(sc.references)) + 1000 + seed, Progress(enabled=False),
                            boundary_reader=reader)
    return fs, sc, reader, make, training


def scene_row(seed: int) -> dict:
    fs, sc, reader, make, training = trained_scene(seed)
    res = explore_object(sc, sc.objects[0], training.memory, make, 7000 + seed, Progress(enabled=False),
                         boundary_reader=reader)
    fine = object_fine_map(res, sc.objects[0], sc, training_moduli(training.readings))
    s = fine.summary
    known = fine.truth >= 0
    near = known & near_boundaries(fine.truth, fine.fine.resolution)
    samples = {where: calibration_sample(fine.fine.probabilities[m], fine.truth[m])[:2]
               for where, m in (("all", known), ("near", near))}
    return {"samples": samples, "seed": seed, "family": fs.family, "cells": len(res.steps), "walls": s["walls_read"],
            "cell": s["area_accuracy"]["cell_map"], "fine": s["area_accuracy"]["fine_map"],
            "err_cell": s["boundary_error_m"]["cell_map"]["median"],
            "err_fine": s["boundary_error_m"]["fine_map"]["median"], "ece": s["calibration_ece"].get("all"),
            "spots": len(s["stiffness_anomalies"] or ()),
            "ece_near": s["calibration_ece"].get("near_boundary")}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--first", type=int, default=100000)
    parser.add_argument("--scenes", type=int, default=len(FAMILIES))
    args = parser.parse_args()
    print(f"{'seed':>7} {'split':6} {'family':10} {'cells':>5} {'walls':>5} {'cell map':>8} {'fine map':>8} "
          f"{'err cell':>8} {'err fine':>8} {'ECE':>5} {'near':>5} {'spots':>5}")
    print("(area right; median boundary error, mm; the fine map's ECE, all and within 5 mm of a boundary; stiffness "
          "anomalies, on scenes without lumps all stray)")
    rows = []
    for seed in range(args.first, args.first + args.scenes):
        t0 = time.process_time()
        r = scene_row(seed)
        rows.append(r)
        mm = lambda v: f"{v * 1e3:8.2f}" if v is not None else "       -"  # noqa: E731
        print(f"{seed:7d} {'report' if is_report_seed(seed) else 'tuning':6} {r['family']:10} {r['cells']:5d} "
              f"{r['walls']:5d} {r['cell']:8.1%} {r['fine']:8.1%} {mm(r['err_cell'])} {mm(r['err_fine'])} "
              f"{r['ece']:5.3f} {r['ece_near']:5.3f} {r['spots']:5d}  "
              f"({time.process_time() - t0:.0f} s CPU)", flush=True)
    cell, fine = np.array([r["cell"] for r in rows]), np.array([r["fine"] for r in rows])
    print(f"median over {len(rows)} scenes: cell map {np.median(cell):.1%}, fine map {np.median(fine):.1%}; fine map "
          f"better on {int(np.sum(fine > cell))}, worse on {int(np.sum(fine < cell))}; median ECE "
          f"{np.median([r['ece'] for r in rows]):.3f} (near boundaries "
          f"{np.median([r['ece_near'] for r in rows]):.3f}); stiffness anomalies {sum(r['spots'] for r in rows)}")
    pooled = {where: reliability_table(*(np.concatenate([r["samples"][where][k] for r in rows]) for k in (0, 1))).ece
              for where in ("all", "near")}
    print(f"ECE over every scene's points pooled: {pooled['all']:.3f} (near boundaries {pooled['near']:.3f})")


if __name__ == "__main__":
    main()
