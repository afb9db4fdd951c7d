"""The lump layer with a fringe: presses beside a spot (within its link distance) that read to its side by
``fringe_z`` spreads or more, added to the spot's footprint. Per threshold, over voxel_lumps.py's scenes: lumps
located in the layer (voxel_lumps.py's rule) and the shares of cubes labelled right.

    .venv/bin/python benchmarks/lump_layer_fringe.py [--first 0] [--scenes 24] [--jobs 2]
"""

from __future__ import annotations

import numpy as np
import voxel_lumps as V
from lump_scenes import scene_arguments, scene_results

from palpate.core.boundary.lump_depth import read_lump_depth
from palpate.core.mapping.anomalies import stiffness_anomalies
from palpate.core.mapping.geometry import plane_probabilities
from palpate.core.session.boundaries import lump_layer_accuracy, plane_fine_map, voxel_lump_layer, with_curves
from palpate.core.session.explore import explore_object
from palpate.core.session.progress import Progress
from palpate.core.world.scenario_file import parse_scenario
from palpate.core.world.workspace import contact_radius, ground_truth_cells

ZS = (float("inf"), 2.5, 2.0, 1.5, 1.0)


def scene_row(seed: int) -> dict:
    memory, layers, reader, moduli, ev = V._judges()
    raw, lumps = V.voxel_lump_scene(seed)
    sc = parse_scenario(raw, f"voxel_lumps{seed}")
    res = explore_object(sc, sc.objects[0], memory, V.make_source_for(sc), 9000 + seed, Progress(enabled=False),
                         layers=layers, boundary_reader=reader)
    steps = [s for s in res.steps if s.boundary is not None]
    readings = [(s.result.location, s.boundary) for s in steps]
    curves = with_curves(ev, [s.result for s in steps])
    g, reach = res.geometry, contact_radius(sc)
    fine, _ = plane_fine_map(g, res.post.probabilities, readings, moduli, reach, curves)
    out = {}
    for zf in ZS:
        spots = []
        for a in stiffness_anomalies(g.plane(), plane_probabilities(res.post.probabilities), readings, moduli,
                                     edge_reach=reach, fringe_z=zf):
            lump = read_lump_depth(curves.curves[a.press], a.material, curves, moduli, a.sign)
            spots.append(a.to_dict() | {"lump": None if lump is None else lump.to_dict()})
        layer, summary = voxel_lump_layer(g, fine, {"stiffness_anomalies": spots})
        c = layer.centres()
        truth = ground_truth_cells(sc.objects[0], sc, c[..., :2].reshape(-1, 2), c[..., 2].ravel())
        acc = lump_layer_accuracy(g, res.post.probabilities, layer, truth.reshape(layer.probabilities.shape[:3]))
        regions = [r for r in summary["material_regions"] if r["material"] != raw["objects"][0]["material"]]
        located = 0
        for lump in lumps:
            centre = np.array(lump["center_mm"][:2])
            limit = 2 * V._volume_in_map_mm3(lump) + 2 * V.CELL_MM**3
            located += any(np.hypot(*(np.array(r["centroid_m"][:2]) * 1e3 - centre)) <= V.NEAR_MM
                           and r["volume_m3"] * 1e9 <= limit for r in regions)
        out[zf] = {"acc": acc, "located": located, "fringe": sum(len(s["fringe_locations_m"]) for s in spots)}
    return out


def main() -> None:
    rows = list(scene_results(scene_row, scene_arguments(__doc__)))
    for zf in ZS:
        every = np.mean([r[zf]["acc"]["volume_accuracy"]["lump_layer"] for r in rows])
        below = [r[zf]["acc"]["below_surface_accuracy"]["lump_layer"] for r in rows
                 if "below_surface_accuracy" in r[zf]["acc"]]
        print(f"fringe z {zf}: located {sum(r[zf]['located'] for r in rows)}, every cube right {every:.4f}, "
              f"cubes not of the surface's material right {np.mean(below):.4f} ({len(below)} scenes), "
              f"fringe presses {sum(r[zf]['fringe'] for r in rows)}")
    print(f"voxel map: every cube right {np.mean([r[ZS[0]]['acc']['volume_accuracy']['voxel_map'] for r in rows]):.4f}")


if __name__ == "__main__":
    main()
