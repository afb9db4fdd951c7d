"""Buried lumps on the fine (1 mm) map: does a raster of every cell with physics presses (``auto``) report each lump
of benchmarks/lump_scenes.py where it lies, and by its material?

Per lump, on the cell map and on the fine map: **located** when a region of the map (summary.json's
``material_regions``) of a material other than the block's has its centroid within 5 mm of the lump's centre and
at most twice the lump's widest footprint; **named** when that region's material is the lump's reference; the
distance from the lump's centre to the nearest region of another material, of any size. Per scene: the fine map's
regions of another material than the block's that lie on no lump (centroid more than 5 mm outside every footprint:
spurious), the stiffness anomalies (summary.json's ``stiffness_anomalies``) on no lump (stray spots) and the area
right away from the lumps (more than 5 mm outside every footprint). A lump is **spotted** when an anomaly lies
within 5 mm of its footprint. Lumps are grouped by the depth of their top. Seeds from 100000 on are report seeds
(never tuned on).

Run: .venv/bin/python benchmarks/fine_map_lumps.py [--first 100000] [--scenes 24] [--jobs 2]
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np
from fine_map_families import trained_scene
from lump_scenes import (
    footprint_area_mm2,
    lump_footprint,
    lump_read,
    lump_read_line,
    lump_top_mm,
    make_lump_scene,
    scene_arguments,
    scene_results,
)
from scene_families import REFERENCES, is_report_seed
from scipy.ndimage import distance_transform_edt

from palpate.core.boundary.templates import Pad
from palpate.core.mapping.regions import map_region_report
from palpate.core.session.boundaries import lump_evidence, object_fine_map, training_moduli
from palpate.core.session.explore import explore_object
from palpate.core.session.progress import Progress

#: How far a region's centroid may lie from a lump's centre, mm.
NEAR_MM = 5.0
#: Depth bands of a lump's top, mm.
BANDS = ((0.0, 2.0), (2.0, 4.0), (4.0, 6.0))


def judge(regions: list[dict], lump: dict, block: str, ref: str) -> dict:
    """One lump against a map's regions of other materials than the block's ``block``: located, named (as ``ref``)
    and the distance to the nearest one (mm, None without any)."""
    centre = np.array(lump["center_mm"][:2])
    other = [r for r in regions if r["material"] != block]
    dist = [float(np.hypot(*(np.array(r["centroid_m"]) * 1e3 - centre))) for r in other]
    fits = [r for r, d in zip(other, dist, strict=True)
            if d <= NEAR_MM and r["area_m2"] * 1e6 <= 2.0 * footprint_area_mm2(lump)]
    return {"located": bool(fits), "named": any(r["material"] == ref for r in fits),
            "error": min(dist) if dist else None}


def force_change(sc, lump: dict, locations: np.ndarray, cache: dict) -> tuple[float, bool]:
    """The largest change of force the lump makes at the planned depth among the presses at ``locations`` (m,
    (n, 2)), as |log(F / F_plain)| (F_plain: the block without its lumps, each press's contact law), and whether
    it is felt: some press's force lies nearer (in log) a block of the lump's material than the block's own, so a
    press judged on its force alone would name the lump."""
    from palpate.sim.contact.stack import object_law

    spec = sc.objects[0].spec
    top, depth, tip = spec.height, sc.exploration.depth, sc.fingertip.radius
    inc = next(i for i in spec.inclusions if np.allclose(np.array(i.center[:2]) * 1e3, lump["center_mm"][:2]))
    star = lambda m: m.young / (1 - m.poisson**2)  # noqa: E731
    half = 0.5 * abs(np.log(star(inc.material) / star(spec.material)))
    reach = (np.sqrt(footprint_area_mm2(lump) / np.pi) + 10.0) * 1e-3
    near = locations[np.hypot(*(locations - np.array(inc.center[:2])).T) <= reach]
    plain = replace(spec, inclusions=())
    change = 0.0
    for x, y in near:
        f = object_law(spec, float(x), float(y), top, tip, depth, cache=cache).force_at(depth)
        f0 = object_law(plain, float(x), float(y), top, tip, depth, cache=cache).force_at(depth)
        change = max(change, abs(float(np.log(float(f) / float(f0)))))
    return change, change >= half


def scene_row(seed: int) -> dict:
    t0 = time.process_time()
    fs = make_lump_scene(seed)
    _, sc, reader, make, training = trained_scene(seed, fs)
    res = explore_object(sc, sc.objects[0], training.memory, make, 7000 + seed, Progress(enabled=False),
                         boundary_reader=reader)
    fine = object_fine_map(res, sc.objects[0], sc, training_moduli(training.readings),
                           lump_evidence(training.presses, Pad.of(sc.fingertip)))
    g = res.geometry
    maps = {"cell": map_region_report(g, res.post.probabilities),
            "fine": fine.summary["material_regions"]}
    block = fs.materials[0][1]
    like = {name: ref for name, ref, _, _ in fs.materials}
    pts = fine.fine.centres() * 1e3
    x, y = pts[..., 0], pts[..., 1]
    near_any = np.zeros(x.shape, dtype=bool)
    locations = np.array([s.result.location[:2] for s in res.steps])
    laws: dict = {}
    found = fine.summary["stiffness_anomalies"] or []
    spots = [np.unravel_index(np.argmin(np.hypot(x - a["centroid_m"][0] * 1e3, y - a["centroid_m"][1] * 1e3)),
                              x.shape) for a in found]
    lumps = []
    for lump in fs.lumps:
        ref = like[lump["material"]]
        change, sensed = force_change(sc, lump, locations, laws)
        near = distance_transform_edt(~lump_footprint(lump, x, y)) * fine.fine.resolution * 1e3 <= NEAR_MM
        # the lump the strongest spot on it reads (spots come strongest first)
        read = next((a["lump"] for a, i in zip(found, spots, strict=True) if near[i] and a.get("lump")), None)
        lumps.append({"top": lump_top_mm(lump), "shape": lump["shape"], "harder": _harder(ref, block),
                      "change": change, "felt": sensed, "spotted": any(near[i] for i in spots), "material": ref,
                      "read": lump_read(read)}
                     | {m: judge(regions, lump, block, ref) for m, regions in maps.items()})
        near_any |= near
    spurious = 0
    for r in maps["fine"]:
        if r["material"] == block:
            continue
        cx, cy = np.array(r["centroid_m"]) * 1e3
        i = np.unravel_index(np.argmin(np.hypot(x - cx, y - cy)), x.shape)
        spurious += int(not near_any[i])
    truth = fine.truth
    away = (truth >= 0) & ~near_any
    labels = fine.fine.labels()
    return {"seed": seed, "presses": len(res.steps), "lumps": lumps, "spurious": spurious,
            "stray_spots": sum(not near_any[i] for i in spots),
            "away": float(np.mean(labels[away] == truth[away])) if away.any() else None,
            "cpu": time.process_time() - t0}


def _harder(ref: str, block: str) -> bool:
    order = [name for name, _, _ in REFERENCES]  # softest first
    return order.index(ref) > order.index(block)


def main() -> None:
    args = scene_arguments(__doc__)
    print(f"{'seed':>7} {'split':6} {'presses':>7} lumps (top mm, shape, harder|softer, felt: located L / named N and "
          "error mm, cell map | fine map)")
    rows = []
    for r in scene_results(scene_row, args):
        rows.append(r)
        desc = "; ".join(f"{lu['top']:.1f} {lu['shape']} {'harder' if lu['harder'] else 'softer'}"
                         f"{' felt' if lu['felt'] else ''}{' spotted' if lu['spotted'] else ''}"
                         f"{'' if lu['read'] is None else ' read {} {:.1f} +- {:.1f} mm'.format(*lu['read'])}: "
                         + " | ".join(_mark(lu[m]) for m in ("cell", "fine")) for lu in r["lumps"])
        away = "-" if r["away"] is None else f"{r['away']:.1%}"
        print(f"{r['seed']:7d} {'report' if is_report_seed(r['seed']) else 'tuning':6} {r['presses']:7d} {desc}"
              f"; spurious {r['spurious']}, stray spots {r['stray_spots']}, area right away from lumps {away} "
              f"({r['cpu']:.0f} s CPU)", flush=True)
    lumps = [lu for r in rows for lu in r["lumps"]]
    print(f"\n{len(lumps)} lumps in {len(rows)} scenes. Per band of the top's depth: lumps | the median over lumps "
          "of the largest force change a press saw | felt by a press | located / named / median error mm, cell map "
          "| the same, fine map | of those felt, located by the fine map | harder and softer located by the fine map "
          "| in a stiffness anomaly (a spot within 5 mm of its footprint), located or spotted")
    for lo, hi in BANDS:
        band = [lu for lu in lumps if lo <= lu["top"] < hi]
        if not band:
            continue
        cols = []
        for m in ("cell", "fine"):
            err = [lu[m]["error"] for lu in band if lu[m]["error"] is not None]
            cols.append(f"{sum(lu[m]['located'] for lu in band)} / {sum(lu[m]['named'] for lu in band)} / "
                        f"{np.median(err) if err else float('nan'):.1f}")
        hard = [lu["fine"]["located"] for lu in band if lu["harder"]]
        soft = [lu["fine"]["located"] for lu in band if not lu["harder"]]
        sensed = [lu["fine"]["located"] for lu in band if lu["felt"]]
        spotted = sum(lu["spotted"] for lu in band)
        either = sum(lu["spotted"] or lu["fine"]["located"] for lu in band)
        change = np.median([np.expm1(lu["change"]) for lu in band])
        print(f"{lo:.0f}-{hi:.0f} mm | {len(band)} | {change:.0%} | {len(sensed)} | {cols[0]} | {cols[1]} | "
              f"{sum(sensed)}/{len(sensed)} | harder {sum(hard)}/{len(hard)}, softer {sum(soft)}/{len(soft)} | "
              f"spotted {spotted}, located or spotted {either}")
    if (line := lump_read_line(lumps)) is not None:
        print(line)
    away = [r["away"] for r in rows if r["away"] is not None]
    print(f"stray stiffness spots (on no lump) {sum(r['stray_spots'] for r in rows)} in {len(rows)} scenes")
    print(f"spurious regions on the fine map {sum(r['spurious'] for r in rows)} in {len(rows)} scenes; area right "
          f"away from lumps median {np.median(away):.1%}, worst {min(away):.1%}")


def _mark(j: dict) -> str:
    return f"{'L' if j['located'] else '-'}{'N' if j['named'] else '-'} " + \
        ("-" if j["error"] is None else f"{j['error']:.1f}")


if __name__ == "__main__":
    main()
