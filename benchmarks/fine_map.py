"""The fine (1 mm) material map against the cell map on a scenario with walls (default: heterogeneous.toml), a
raster of every cell with physics presses: the share of the object's area each labels right on a 1 mm raster, and
how the presses' boundary readings did against the truth.

Run: .venv/bin/python benchmarks/fine_map.py [--scenario heterogeneous] [--seed 11] [--figure FILE]
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import time

import numpy as np
from scipy.ndimage import distance_transform_edt

from palpate.api import load_scenario
from palpate.core.boundary.moduli import material_moduli
from palpate.core.boundary.press import noise_of, read_press
from palpate.core.boundary.templates import read_templates
from palpate.core.mapping.fine import fine_map
from palpate.core.perception.press import perceive_press
from palpate.core.session.explore import explore_object
from palpate.core.session.progress import Progress
from palpate.core.session.sources import PressTarget, load_source
from palpate.core.session.training import TRAINING_BLOCK, train_memory, training_seeds
from palpate.core.world.scene import ObjectSpec, Scene
from palpate.core.world.workspace import ground_truth_cells


def make_source_for(scenario):
    factory = load_source("sim")

    def make(objects, seed, variability):
        return factory(Scene(objects, scenario.fingertip, scenario.taxels, scenario.pose), fidelity=scenario.fidelity,
                       seed=seed, variability=variability)

    return make


def _edges(labels: np.ndarray) -> np.ndarray:
    e = np.zeros(labels.shape, dtype=bool)
    e[:, 1:] |= labels[:, 1:] != labels[:, :-1]
    e[1:, :] |= labels[1:, :] != labels[:-1, :]
    return e


def boundary_error(labels: np.ndarray, truth: np.ndarray, mask: np.ndarray, resolution: float) -> tuple[float, float]:
    """Median and 90th percentile distance, mm, from each true boundary point in ``mask`` to the nearest boundary
    point of ``labels`` (infinite when ``labels`` has none)."""
    mine, true = _edges(labels), _edges(truth) & mask
    if not mine.any() or not true.any():
        return float("inf"), float("inf")
    dist = distance_transform_edt(~mine) * resolution * 1e3
    return float(np.median(dist[true])), float(np.percentile(dist[true], 90))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="heterogeneous")
    parser.add_argument("--seed", type=int, default=11)
    parser.add_argument("--figure")
    parser.add_argument("--moduli", action="store_true", help="name each side of a wall by its read modulus")
    parser.add_argument("--readings", action="store_true", help="print every press's reading")
    args = parser.parse_args()
    sc = load_scenario(args.scenario)
    t0 = time.process_time()
    entry = sc.objects[0]
    nx, ny = (int(round(v / sc.exploration.cell_size)) for v in entry.spec.size[:2])
    ex = dataclasses.replace(sc.exploration, policy="raster", budget=10**6, stop_mean_entropy=None,
                             stop_max_entropy=None, stop_min_gain=None)
    sc = dataclasses.replace(sc, exploration=ex)
    make = make_source_for(sc)
    memory = train_memory(sc, make, training_seeds(sc), Progress(enabled=False)).memory
    reader = functools.partial(read_press, templates=read_templates(), noise=noise_of(sc.taxels))
    res = explore_object(sc, entry, memory, make, args.seed, Progress(enabled=False),
                         boundary_reader=lambda rec, r: reader(rec, r))
    readings = [(s.result.location, s.boundary) for s in res.steps if s.boundary is not None]
    moduli = None
    if args.moduli:  # the references read on training blocks, as the memory was trained
        by_material = {}
        for m, name in enumerate(sc.references):
            block = ObjectSpec(f"sample_{name}", "box", TRAINING_BLOCK, (0.0, 0.0), sc.materials[name].material)
            source = make((block,), 500 + m, sc.training.variability)
            recs = [source.press(PressTarget(0.0, 0.0, depth=sc.training.depth)) for _ in range(4)]
            by_material[name] = [reader(rec, perceive_press(rec)) for rec in recs]
        moduli = material_moduli(by_material)
        print("reference log moduli:", dict(zip(moduli.materials, np.round(moduli.log_mean, 2), strict=True)))
    fine = fine_map(res.geometry, res.post.probabilities, readings, moduli=moduli)
    pts = fine.centres()
    top = entry.spec.height
    truth = ground_truth_cells(entry, sc, pts.reshape(-1, 2), np.full(pts.shape[0] * pts.shape[1],
                                                                       top - sc.exploration.depth / 2))
    truth = truth.reshape(pts.shape[:2])
    names = res.geometry.materials
    known = truth >= 0
    cells = np.argmax(res.post.probabilities, axis=-1)
    n = pts.shape[0] // cells.shape[0]
    cell_labels = np.kron(cells, np.ones((n, n), dtype=int))
    cell_acc = float(np.mean(cell_labels[known] == truth[known]))
    fine_acc = float(np.mean(fine.labels()[known] == truth[known]))
    walls = sum(1 for _, r in readings if r.p_boundary > 0.5)
    # outside the footprints of box inclusions buried under the surface (a press there feels a layer): the first
    # (heterogeneous.toml: the lump), then all (and the layered patch)
    buried = [inc for inc in entry.spec.inclusions if inc.shape == "box" and inc.center[2] + inc.size[-1] / 2 < top]
    masks = []
    for incs in (buried[:1], buried):
        outside = known.copy()
        for inc in incs:
            (cx, cy, _), size = inc.center, inc.size
            outside &= ~((np.abs(pts[..., 0] - cx) <= size[0] / 2) & (np.abs(pts[..., 1] - cy) <= size[1] / 2))
        masks.append(outside)
    print(f"{args.scenario}: {len(res.steps)} presses ({nx} x {ny} cells), {walls} read a wall; materials {names}")
    print(f"area right on a {fine.resolution * 1e3:g} mm raster: cell map {cell_acc:.1%}, fine map {fine_acc:.1%}")
    for outside, what in zip(masks, ("the first buried inclusion's footprint", "every buried inclusion's"),
                             strict=True):
        print(f"outside {what} ({outside.mean():.0%} of the area): cell map "
              f"{np.mean(cell_labels[outside] == truth[outside]):.1%}, fine map "
              f"{np.mean(fine.labels()[outside] == truth[outside]):.1%}; boundary error median / p90 (mm): cell "
              "map {:.2f} / {:.2f}, fine map {:.2f} / {:.2f}".format(
                  *boundary_error(cell_labels, truth, outside, fine.resolution),
                  *boundary_error(fine.labels(), truth, outside, fine.resolution)))
    print(f"CPU {time.process_time() - t0:.0f} s")
    if args.readings:
        for s in res.steps:
            r = s.boundary
            if r is not None:
                print(f"press at ({s.result.location[0] * 1e3:5.1f}, {s.result.location[1] * 1e3:5.1f}) mm: p_b "
                      f"{r.p_boundary:.2f} angle {np.degrees(r.angle):6.1f} offset {r.offset * 1e3:+5.1f} "
                      f"+-{r.offset_sd * 1e3:.1f} mm contrast {r.contrast:g}")
    if args.figure:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, ax = plt.subplots(1, 3, figsize=(13, 3.6), constrained_layout=True)
        ext = [fine.origin[0] * 1e3, (fine.origin[0] + pts.shape[1] * fine.resolution) * 1e3, fine.origin[1] * 1e3,
               (fine.origin[1] + pts.shape[0] * fine.resolution) * 1e3]
        for a, img, title in ((ax[0], truth, "truth"), (ax[1], cell_labels, f"cell map {cell_acc:.1%}"),
                              (ax[2], fine.labels(), f"fine map {fine_acc:.1%}")):
            a.imshow(img, origin="lower", extent=ext, vmin=-1, vmax=len(names) - 1, cmap="viridis")
            a.set_title(title)
            a.set_xlabel("x (mm)")
            a.set_ylabel("y (mm)")
        for (x, y), r in readings:
            if r.p_boundary > 0.5:
                f = (np.array([x, y]) + r.foot) * 1e3
                t = np.array([-r.normal[1], r.normal[0]]) * 4
                ax[2].plot([f[0] - t[0], f[0] + t[0]], [f[1] - t[1], f[1] + t[1]], "w-", lw=1)
        fig.savefig(args.figure, dpi=120)
        print(f"figure: {args.figure}")


if __name__ == "__main__":
    main()
