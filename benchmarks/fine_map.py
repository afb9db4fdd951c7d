"""The fine (1 mm) material map against the cell map on a scenario with walls (default: heterogeneous.toml), a
raster of every cell (or --policy with --budget presses) with physics presses: the share of the area each labels
right on a 1 mm raster (all of it, outside the first buried inclusion's footprint, outside every buried one's), how
far their boundaries lie from the true ones, and per buried box whether a stiffness spot lies within 5 mm of it and
which of the fine map's material regions (summary.json's) lies nearest its centre: a lump that feels like another
reference material than its surround is reported as a region of that material. --fe also presses each buried box's
middle with the 3-D FE (the box in a block of the material beside it, under the material above it) and prints its
force beside the contact law's there and each reference material's alone: what a press over the box feels like.

Run: .venv/bin/python benchmarks/fine_map.py [--scenario heterogeneous] [--seed 11] [--readings] [--fe]
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

#: Indentations at which --fe compares the 3-D FE with the contact law and the reference materials, m.
FE_DEPTHS = np.array([1.0, 2.0, 3.0, 4.0]) * 1e-3


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="heterogeneous")
    parser.add_argument("--seed", type=int, default=11)
    parser.add_argument("--readings", action="store_true", help="print every press's reading")
    parser.add_argument("--policy", default="raster", help="exploration policy (default raster: every cell)")
    parser.add_argument("--budget", type=int, default=10**6, help="press budget (default: no limit)")
    parser.add_argument("--fe", action="store_true", help="press each buried box's middle with the 3-D FE too")
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
        print("    " + _nearest_region(summary.get("material_regions") or [], inc, fine.labels(), pts,
                                    fine.materials))
        if args.fe:
            print("    " + _felt(sc, entry.spec, inc))
    if args.readings:
        for s in res.steps:
            r = s.boundary
            if r is not None:
                print(f"press at ({s.result.location[0] * 1e3:5.1f}, {s.result.location[1] * 1e3:5.1f}) mm: p_b "
                      f"{r.p_boundary:.2f} angle {np.degrees(r.angle):6.1f} offset {r.offset * 1e3:+5.1f} "
                      f"+-{r.offset_sd * 1e3:.1f} mm contrast {r.contrast:g}")
    print(f"CPU {time.process_time() - t0:.0f} s")


def _nearest_region(regions: list[dict], inc, labels: np.ndarray, pts: np.ndarray, materials) -> str:
    """The fine map's region whose centroid lies nearest the box's centre, against the material the map names
    around the box (a 5 mm ring outside its footprint): its distance, material and area over the footprint's."""
    (cx, cy, _), size = inc.center, inc.size
    gx, gy = np.abs(pts[..., 0] - cx) - size[0] / 2, np.abs(pts[..., 1] - cy) - size[1] / 2
    ring = (np.maximum(gx, gy) > 0) & (np.maximum(gx, gy) <= 5e-3)
    if not regions or not ring.any():
        return "no region"
    around = int(np.bincount(labels[ring]).argmax())
    d = [float(np.hypot(r["centroid_m"][0] - cx, r["centroid_m"][1] - cy)) for r in regions]
    r = regions[int(np.argmin(d))]
    return (f"nearest region: {r['material']} (p {r['probability']:.2f}), centroid {min(d) * 1e3:.1f} mm from the "
            f"box's centre, area {r['area_m2'] / (size[0] * size[1]):.2f} of its footprint; around it: "
            f"{materials[around]}")


def _felt(sc, obj, inc) -> str:
    """The 3-D FE's force pressing the box's middle (N at FE_DEPTHS), the contact law's at that point of the scene's
    object, and the FE's over each reference material's alone on a block as thick."""
    from palpate.sim.validity.offaxis import buried_box_press

    press = buried_box_press(obj, inc, sc.fingertip.radius, FE_DEPTHS,
                             {name: sc.materials[name].material for name in sc.references})
    fe, block = press.fe, press.block
    ratios = {name: float(np.mean(fe / force)) for name, force in press.plain.items()}
    nearest = min(ratios, key=lambda k: abs(np.log(ratios[k])))
    return (f"3-D FE over its middle ({inc.material.name} in {block.material.name}"
            + ("" if block.skin is None else f" under {block.skin.thickness * 1e3:g} mm of {block.skin.material.name}")
            + "): " + " / ".join(f"{f:.2f}" for f in fe)
            + f" N at {' / '.join(f'{d * 1e3:g}' for d in FE_DEPTHS)} mm, "
            + f"the law's {np.mean(press.law / fe):.2f}x that; the FE's over each reference alone: "
            + ", ".join(f"{k} {v:.2f}" for k, v in ratios.items()) + f" (feels like {nearest})")


if __name__ == "__main__":
    main()
