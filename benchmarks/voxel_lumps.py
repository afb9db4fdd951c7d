"""Buried lumps on the voxel map: does a raster of every column (presses to 10 mm or 40 N, 5 mm voxels two layers
deep, physics presses) report each lump where it lies, at its depth and by its material?

Seeded scenes: a block 50-70 x 40-60 mm of one of three reference materials (soft 20, medium 115, hard 450 kPa)
with 1-2 buried boxes or spheres of another (8-20 mm across, tops 0.5-8 mm down), kept 5 mm apart and 5 mm inside
the block. Per lump, from summary.json's ``material_regions`` of the post-processed voxel map: **located** when a
region of another material than the block's has its centroid within 5 mm of the lump's centre laterally and at most
twice the lump's volume within the map's depth (and two voxels); **named** when it is the lump's material;
**top right** when that region's shallowest voxel holds the lump's top. **In the lump layer** when the layer of 1 mm
cubes the run writes beside the voxel map (summary.json's ``fine_map.lump_layer``) has such a region (named: of the
lump's material; its top's error against the lump's, mm). **Spotted** when a stiffness spot of the
surface layer's fine map (a press reading harder or softer than the material the surface layer names) lies within
5 mm of the lump's footprint, **its sign right** when the spot says harder for a harder lump, softer for a softer.
Seeds below 100000 are tuning seeds, from 100000 on report seeds. The layered judges are trained once, on tuning
scene 0's references.

Run: .venv/bin/python benchmarks/voxel_lumps.py [--first 100000] [--scenes 24] [--jobs 2]
"""

from __future__ import annotations

import math
import time
from functools import cache

import numpy as np
from exploration import make_source_for
from exploration_voxels import CELL_MM, DEPTH_MM, FORCE_N, MATERIALS, NAMES
from lump_scenes import footprint_gap_mm, lump_read, lump_read_line, lump_top_mm, scene_arguments, scene_results
from scene_families import HEIGHT_MM, is_report_seed

from palpate.core.boundary.templates import Pad
from palpate.core.mapping.regions import map_region_report
from palpate.core.perception.layered_memory import train_layered_memory
from palpate.core.session.boundaries import boundary_reader, lump_evidence, object_fine_map, training_moduli
from palpate.core.session.explore import explore_object
from palpate.core.session.progress import Progress
from palpate.core.session.training import train_memory
from palpate.core.world.scenario_file import parse_scenario

#: How far a region's centroid may lie from a lump's centre laterally, mm.
NEAR_MM = 5.0
#: Depth bands of a lump's top, mm.
BANDS = ((0.0, 2.0), (2.0, 5.0), (5.0, 8.0))


def voxel_lump_scene(seed: int) -> tuple[dict, list[dict]]:
    """A seeded block with buried lumps as a raster voxel scenario dictionary, and its lumps (TOML inclusions)."""
    rng = np.random.default_rng([seed, 27])
    nx, ny = int(rng.integers(10, 15)), int(rng.integers(8, 13))
    sx, sy = nx * CELL_MM, ny * CELL_MM
    block = int(rng.integers(len(NAMES)))
    lumps: list[dict] = []
    taken: list[tuple[float, float, float, float]] = []
    for _ in range(int(rng.integers(1, 3))):
        for _try in range(50):
            if rng.random() < 0.5:
                w, h, t = (float(v) for v in rng.uniform([8.0, 8.0, 5.0], [20.0, 20.0, 15.0]))
                size, half = [round(w, 2), round(h, 2), round(t, 2)], (w / 2, h / 2, t / 2)
            else:
                r = float(rng.uniform(4.0, 10.0))
                size, half = [round(r, 2)], (r, r, r)
            if sx - 10.0 <= 2 * half[0] or sy - 10.0 <= 2 * half[1]:
                continue
            x = float(rng.uniform(5.0 + half[0], sx - 5.0 - half[0]))
            y = float(rng.uniform(5.0 + half[1], sy - 5.0 - half[1]))
            box = (x - half[0], x + half[0], y - half[1], y + half[1])
            if any(b[0] - 5 < box[1] and box[0] < b[1] + 5 and b[2] - 5 < box[3] and box[2] < b[3] + 5 for b in taken):
                continue
            top = float(rng.uniform(0.5, 8.0))
            other = [i for i in range(len(NAMES)) if i != block]
            lumps.append({"material": NAMES[int(rng.choice(other))], "shape": "sphere" if len(size) == 1 else "box",
                          "center_mm": [round(x, 3), round(y, 3), round(HEIGHT_MM - top - half[2], 3)],
                          "size_mm": size})
            taken.append(box)
            break
    obj = {"name": f"block{seed}", "size_mm": [sx, sy, HEIGHT_MM], "position_mm": [sx / 2, sy / 2],
           "material": NAMES[block], "inclusions": lumps}
    ex = {"map": "voxel", "cell_mm": CELL_MM, "voxel_depth_mm": DEPTH_MM, "policy": "raster", "budget": nx * ny,
          "depth_mm": DEPTH_MM, "max_force_n": FORCE_N, "variability": "human"}
    return ({"scenario": {"name": f"voxel_lumps{seed}", "seed": seed, "fidelity": "analytic"}, "materials": MATERIALS,
             "training": {"presses_per_material": 10, "depth_mm": DEPTH_MM, "max_force_n": FORCE_N},
             "exploration": ex, "objects": [obj], "outputs": {"figures": False, "haptic_material": False}}, lumps)


def _volume_in_map_mm3(lump: dict) -> float:
    """The lump's volume within the map's depth (DEPTH_MM under the surface), mm^3."""
    top = lump_top_mm(lump)
    if lump["shape"] == "box":
        sx, sy, sz = lump["size_mm"]
        return sx * sy * max(0.0, min(top + sz, DEPTH_MM) - top)
    r = lump["size_mm"][0]
    lo, hi = top, min(top + 2 * r, DEPTH_MM)  # depths through the sphere: a cap between them
    if hi <= lo:
        return 0.0
    cap = lambda h: math.pi * h * h * (3 * r - h) / 3  # noqa: E731  (a cap of height h)
    return cap(hi - lo + 0.0) if lo == top else cap(hi - top) - cap(lo - top)


@cache
def _judges():
    base = parse_scenario(voxel_lump_scene(0)[0], "voxel_lumps")
    reader, why = boundary_reader(base)
    if reader is None:
        raise SystemExit(f"no boundary readings: {why}")
    training = train_memory(base, make_source_for(base), np.arange(3) + 1000, Progress(enabled=False),
                            boundary_reader=reader)
    return (training.memory, train_layered_memory(training.memory, training.presses, CELL_MM * 1e-3,
                                                  int(DEPTH_MM / CELL_MM)), reader, training_moduli(training.readings),
            lump_evidence(training.presses, Pad.of(base.fingertip)))


def _lateral_mm(region: dict, centre: np.ndarray) -> float:
    """How far a region's centroid (summary.json's ``material_regions`` entry) lies from ``centre`` (x, y mm)
    laterally, mm."""
    return float(np.hypot(*(np.array(region["centroid_m"][:2]) * 1e3 - centre)))


def _locating(regions: list[dict], lump: dict) -> list[dict]:
    """The regions that locate ``lump``: centroid within NEAR_MM of its centre laterally, volume at most twice the
    lump's within the map's depth (and two voxels)."""
    centre, limit = np.array(lump["center_mm"][:2]), 2 * _volume_in_map_mm3(lump) + 2 * CELL_MM**3
    return [r for r in regions if _lateral_mm(r, centre) <= NEAR_MM and r["volume_m3"] * 1e9 <= limit]


def _near(lump: dict, spot: dict) -> bool:
    """Whether ``spot`` (summary.json's stiffness_anomalies entry) lies within NEAR_MM of the lump's footprint."""
    return footprint_gap_mm(lump, *(np.array(spot["centroid_m"]) * 1e3)) <= NEAR_MM


def scene_row(seed: int) -> dict:
    t0 = time.process_time()
    memory, layers, reader, moduli, evidence = _judges()
    raw, lumps = voxel_lump_scene(seed)
    sc = parse_scenario(raw, f"voxel_lumps{seed}")
    res = explore_object(sc, sc.objects[0], memory, make_source_for(sc), 9000 + seed, Progress(enabled=False),
                         layers=layers, boundary_reader=reader)
    fine = object_fine_map(res, sc.objects[0], sc, moduli, evidence).summary
    spots = fine["stiffness_anomalies"] or []
    layer = fine.get("lump_layer") or {}
    block = raw["objects"][0]["material"]
    layered = [r for r in layer.get("material_regions", []) if r["material"] != block]
    young = {m["name"]: m["young_kpa"] for m in MATERIALS}
    regions = [r for r in map_region_report(res.geometry, res.post.probabilities) if r["material"] != block]
    rows = []
    for lump in lumps:
        centre = np.array(lump["center_mm"][:2])
        dist = [_lateral_mm(r, centre) for r in regions]
        fits, in_layer = _locating(regions, lump), _locating(layered, lump)
        top = lump_top_mm(lump)
        sign = "harder" if young[lump["material"]] > young[block] else "softer"
        near = [a for a in spots if _near(lump, a)]
        read = next((a["lump"] for a in near if a.get("lump")), None)  # the strongest spot's that reads a lump
        rows.append({"top": top, "shape": lump["shape"], "located": bool(fits), "spotted": bool(near),
                     "layer": bool(in_layer), "layer_named": any(r["material"] == lump["material"] for r in in_layer),
                     "layer_top": min((abs(r["top_depth_m"] * 1e3 - top) for r in in_layer), default=None),
                     "sign": any(a["sign"] == sign for a in near),
                     "named": any(r["material"] == lump["material"] for r in fits),
                     "top_right": any(int(r["top_depth_m"] * 1e3 / CELL_MM + 0.5) == int(top // CELL_MM)
                                      for r in fits),
                     "error": min(dist) if dist else None, "material": lump["material"],
                     "read": lump_read(read)})
    stray = sum(not any(_near(lump, a) for lump in lumps) for a in spots)
    return {"seed": seed, "presses": len(res.steps), "lumps": rows, "cpu": time.process_time() - t0,
            "volume": layer.get("volume_accuracy"), "below": layer.get("below_surface_accuracy"),
            "ece": layer.get("calibration_ece"),
            "accuracy": res.steps[-1].accuracy_postprocessed, "stray": stray}


def _median_or_nan(values) -> float:
    kept = [v for v in values if v is not None]
    return float(np.median(kept)) if kept else float("nan")


def main() -> None:
    args = scene_arguments(__doc__)
    print(f"{'seed':>7} {'split':6} {'presses':>7} {'voxels right':>12}  lumps (top mm, shape: located L, "
          "in the lump layer F (n: named), named N, top's layer right T, spotted S (s: with the wrong sign); "
          "distance to the nearest region of another material, mm)")
    rows = []
    for r in scene_results(scene_row, args):
        rows.append(r)
        desc = "; ".join(f"{lu['top']:.1f} {lu['shape']}: {'L' if lu['located'] else '-'}"
                         f"{'F' if lu['layer'] else '-'}{'n' if lu['layer_named'] else '-'}"
                         f"{'N' if lu['named'] else '-'}{'T' if lu['top_right'] else '-'}"
                         f"{('S' if lu['sign'] else 's') if lu['spotted'] else '-'} "
                         f"{'-' if lu['error'] is None else format(lu['error'], '.1f')}"
                         + ("" if lu["read"] is None else " read {} {:.1f} +- {:.1f} mm".format(*lu["read"]))
                         for lu in r["lumps"])
        print(f"{r['seed']:7d} {'report' if is_report_seed(r['seed']) else 'tuning':6} {r['presses']:7d} "
              f"{r['accuracy']:12.1%}  {desc}; stray spots {r['stray']} ({r['cpu']:.0f} s CPU)", flush=True)
    lumps = [lu for r in rows for lu in r["lumps"]]
    print(f"\n{len(lumps)} lumps in {len(rows)} scenes ({sum(r['stray'] for r in rows)} stray spots); per band of the "
          "top's depth: lumps, located, named, top's layer right, median distance mm, spotted, spotted with its sign; "
          "in the lump layer: located, named, median error of the top mm")
    for lo, hi in BANDS:
        band = [lu for lu in lumps if lo <= lu["top"] < hi]
        if band:
            err = [lu["error"] for lu in band if lu["error"] is not None]
            print(f"{lo:.0f}-{hi:.0f} mm | {len(band)} | {sum(lu['located'] for lu in band)} | "
                  f"{sum(lu['named'] for lu in band)} | {sum(lu['top_right'] for lu in band)} | "
                  f"{np.median(err) if err else float('nan'):.1f} | {sum(lu['spotted'] for lu in band)} | "
                  f"{sum(lu['sign'] for lu in band)} | {sum(lu['layer'] for lu in band)} | "
                  f"{sum(lu['layer_named'] for lu in band)} | {_median_or_nan([lu['layer_top'] for lu in band]):.1f}")
    for key, what in (("volume", "every cube"), ("below", "cubes whose material is not the surface's")):
        acc = [r[key] for r in rows if r[key]]
        if acc:
            voxel, layer = (np.mean([a[k] for a in acc]) for k in ("voxel_map", "lump_layer"))
            print(f"share of {what} labelled right (1 mm cubes), mean over {len(acc)} scenes: voxel map "
                  f"{voxel:.3f}, lump layer {layer:.3f}")
    for where in ("all", "under_spots"):
        ece = [r["ece"][where] for r in rows if r["ece"] and where in r["ece"]]
        if ece:
            print(f"lump layer's calibration error ({where.replace('_', ' ')} cubes), median over {len(ece)} scenes: "
                  f"{np.median(ece):.3f}")
    if (line := lump_read_line(lumps)) is not None:
        print(f"\n{line}")


if __name__ == "__main__":
    main()
