"""The fine (1 mm) material map against the cell map on a scenario with walls (default: heterogeneous.toml), a
raster of every cell (or --policy with --budget presses) with physics presses: the share of the area each labels
right on a 1 mm raster (all of it, outside the first buried inclusion's footprint, outside every buried one's), how
far their boundaries lie from the true ones, and per buried box whether a stiffness spot lies within 5 mm of it.

Run: .venv/bin/python benchmarks/fine_map.py [--scenario heterogeneous] [--seed 11] [--readings]
     [--policy boundary --budget 24]
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np

from palpate.api import load_scenario
from palpate.core.mapping.fine import boundary_error
from palpate.core.session.boundaries import (
    NEAR_BOUNDARY,
    boundary_reader,
    fine_calibration,
    object_fine_map,
    training_moduli,
)
from palpate.core.session.explore import explore_object
from palpate.core.session.progress import Progress
from palpate.core.session.sources import scenario_source_maker
from palpate.core.session.training import train_memory, training_seeds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="heterogeneous")
    parser.add_argument("--seed", type=int, default=11)
    parser.add_argument("--readings", action="store_true", help="print every press's reading")
    parser.add_argument("--policy", default="raster", help="exploration policy (default raster: every cell)")
    parser.add_argument("--budget", type=int, default=10**6, help="press budget (default: no limit)")
    args = parser.parse_args()
    t0 = time.process_time()
    sc = load_scenario(args.scenario)
    sc = dataclasses.replace(sc, exploration=dataclasses.replace(
        sc.exploration, policy=args.policy, budget=args.budget, stop_mean_entropy=None, stop_max_entropy=None,
        stop_min_gain=None))
    entry = sc.objects[0]
    reader, why = boundary_reader(sc)
    if reader is None:
        raise SystemExit(why)
    make = scenario_source_maker(sc, sc.training.source)
    training = train_memory(sc, make, training_seeds(sc), Progress(enabled=False), boundary_reader=reader)
    moduli = training_moduli(training.readings)
    res = explore_object(sc, entry, training.memory, make, args.seed, Progress(enabled=False), boundary_reader=reader,
                         moduli=moduli)
    result = object_fine_map(res, entry, sc, moduli)
    fine, summary = result.fine, result.summary
    truth = result.truth
    cells = fine.cells_on_raster(np.argmax(res.post.probabilities, axis=-1))
    pts = fine.centres()
    buried = [inc for inc in entry.spec.inclusions if inc.shape == "box"
              and inc.center[2] + inc.size[-1] / 2 < entry.spec.height]
    print(f"{args.scenario}: {len(res.steps)} presses, {summary['walls_read']} read a wall; ECE of the fine map "
          f"{summary['calibration_ece']}")
    for incs, what in (([], "all of the area"), (buried[:1], "outside the first buried inclusion"),
                       (buried, "outside every buried inclusion")):
        mask = truth >= 0
        for inc in incs:
            (cx, cy, _), size = inc.center, inc.size
            mask &= ~((np.abs(pts[..., 0] - cx) <= size[0] / 2) & (np.abs(pts[..., 1] - cy) <= size[1] / 2))
        ec, ef = (boundary_error(lab, truth, mask, fine.resolution) for lab in (cells, fine.labels()))
        ece = fine_calibration(fine, truth, mask)
        print(f"{what} ({mask.mean():.0%}): area right cell map {np.mean(cells[mask] == truth[mask]):.1%}, fine map "
              f"{np.mean(fine.labels()[mask] == truth[mask]):.1%}; boundary error median / p90 cell map "
              f"{ec[0] * 1e3:.1f} / {ec[1] * 1e3:.1f} mm, fine map {ef[0] * 1e3:.1f} / {ef[1] * 1e3:.1f} mm; fine map "
              f"ECE {ece['all']:.3f}, within {NEAR_BOUNDARY * 1e3:g} mm of a boundary {ece['near_boundary']:.3f}")
    # the buried lump reported at its true position: a stiffness spot within 5 mm of its footprint
    spots = summary.get("stiffness_anomalies") or []
    for inc in buried:
        (cx, cy, cz), size = inc.center, inc.size
        gaps = [float(np.hypot(max(abs(sp["centroid_m"][0] - cx) - size[0] / 2, 0.0),
                               max(abs(sp["centroid_m"][1] - cy) - size[1] / 2, 0.0))) for sp in spots]
        k = int(np.argmin(gaps)) if gaps else -1
        near = "no spot" if k < 0 else (f"nearest spot {gaps[k] * 1e3:.1f} mm from its footprint ({spots[k]['sign']}, "
                                        f"{spots[k]['presses']} presses)")
        print(f"buried {inc.material.name} box at ({cx * 1e3:.0f}, {cy * 1e3:.0f}) mm, top "
              f"{(entry.spec.height - cz - size[-1] / 2) * 1e3:.1f} mm down: {near}; reported within 5 mm: "
              f"{'yes' if k >= 0 and gaps[k] <= 5e-3 else 'no'}")
    if args.readings:
        for s in res.steps:
            r = s.boundary
            if r is not None:
                print(f"press at ({s.result.location[0] * 1e3:5.1f}, {s.result.location[1] * 1e3:5.1f}) mm: p_b "
                      f"{r.p_boundary:.2f} angle {np.degrees(r.angle):6.1f} offset {r.offset * 1e3:+5.1f} "
                      f"+-{r.offset_sd * 1e3:.1f} mm contrast {r.contrast:g}")
    print(f"CPU {time.process_time() - t0:.0f} s")


if __name__ == "__main__":
    main()
