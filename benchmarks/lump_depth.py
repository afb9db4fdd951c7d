"""How deep is a lump, from the press over a spot? Two-layer stacks against finite on-axis inclusions as templates.

For every lump of benchmarks/lump_scenes.py that a raster's stiffness spots found (summary.json's
``stiffness_anomalies``), the press nearest the spot's centroid is read: its contact intensity c_P against its
indentation c_D, divided by the mean curve of the training presses of the material the map names there (the top),
is matched by least squares in log against the same ratio for templates of the top over each other reference
material (the contact law and the pad's sensel image of the simulation, law_sensel_pressure; 40 mm on a bonded
base): ``stack``, the other material from a depth t on (0.25-8 mm); ``sphere``, an on-axis sphere of radius 5, 8, 12
or 18 mm with its top at t; ``both``, stacks, spheres and cylinders of those radii together. The reading: t, the
deep material and the template. Scored against the lump's top depth and material. Seeds below 100000 are tuning
seeds, from 100000 on report seeds.

Run: .venv/bin/python benchmarks/lump_depth.py [--first 100000] [--scenes 24] [--jobs 2]
"""

from __future__ import annotations

import warnings
from functools import cache

import numpy as np
from fine_map_families import trained_scene
from lump_scenes import lump_footprint, lump_top_mm, make_lump_scene, scene_arguments, scene_results
from scene_families import is_report_seed

from palpate.core.session.boundaries import object_fine_map, training_moduli
from palpate.core.session.explore import explore_object
from palpate.core.session.progress import Progress
from palpate.core.world.scene import FingertipSpec, Layer, Material

#: Indentations the curves are compared at, m.
DEPTHS = np.linspace(0.75e-3, 4.0e-3, 14)
#: Depths of the template's interface or inclusion top the reading chooses among, m.
TOPS = np.arange(0.25e-3, 8.01e-3, 0.25e-3)
#: Radii of the inclusion templates, m.
RADII = (5e-3, 8e-3, 12e-3, 18e-3)
#: The template sets compared: (shape or None for a stack, radius m).
KINDS = {"stack": ((None, 0.0),), "sphere": tuple(("sphere", r) for r in RADII),
         "both": ((None, 0.0),) + tuple(("sphere", r) for r in RADII) + tuple(("cylinder", r) for r in RADII)}
#: Thickness of the templates' sample, m.
THICKNESS = 0.04


@cache
def _pad_sum(top: tuple[float, float], deep: tuple[float, float] | None, t: float, shape: str | None = None,
             radius: float = 0.0) -> np.ndarray:
    """Sum of the pad's sensel pressures (Pa) at DEPTHS for ``top`` (E Pa, nu) over ``deep`` from ``t`` m (None:
    the top all the way), or with an on-axis ``shape`` of ``deep`` (radius m, a cylinder 2 radii tall) topped at
    ``t``; the default fingertip."""
    from palpate.sim.analytic import law_sensel_pressure
    from palpate.sim.contact.stack import sample_law
    from palpate.sim.fingertip import sensel_bounds
    from palpate.sim.reference.sample import AxisInclusion, AxisymmetricSample

    tip = FingertipSpec()
    top_m = Material("top", *top)
    if deep is None:
        sample = AxisymmetricSample(bulk=top_m, thickness=THICKNESS)
    elif shape is None:
        sample = AxisymmetricSample(bulk=Material("deep", *deep), thickness=THICKNESS, layers=(Layer(top_m, t),))
    else:
        height = min(2.0 * radius, THICKNESS - t - 1e-3)
        if shape == "sphere" and t + 2.0 * radius > THICKNESS - 1e-3:
            shape = "cylinder"  # a sphere that would reach the base: its upper part
        inclusion = AxisInclusion(Material("deep", *deep), shape, t, radius, height)
        sample = AxisymmetricSample(bulk=top_m, thickness=THICKNESS, inclusion=inclusion)
    law = sample_law(sample, tip.radius, 1.05 * DEPTHS[-1])
    return law_sensel_pressure(law, DEPTHS, sensel_bounds(tip)).reshape(len(DEPTHS), -1).sum(axis=1)


def mean_curve(presses) -> np.ndarray:
    """Geometric mean over presses of c_P at DEPTHS (NaN past a press's depth)."""
    rows = []
    for p in presses:
        if p.press is None:
            continue
        c_d, c_p = np.asarray(p.press.c_D), np.asarray(p.press.c_P)
        order = np.argsort(c_d, kind="stable")
        row = np.interp(DEPTHS, c_d[order], c_p[order], right=np.nan)
        rows.append(np.log(np.maximum(row, 1e-9)))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # depths no press reached stay NaN
        return np.exp(np.nanmean(np.array(rows), axis=0))


def read_depth(ratio: np.ndarray, top: tuple[float, float], deeps: dict[str, tuple[float, float]], kinds):
    """(deep material, t m, template, rms in log) of the template whose pad-sum ratio to the plain top fits
    ``ratio`` best (deep material None: the plain top fits best)."""
    ok = np.isfinite(ratio) & (ratio > 0)
    plain = _pad_sum(top, None, 0.0)
    best = (None, float("nan"), None, float(np.sqrt(np.mean(np.log(ratio[ok]) ** 2))))
    for name, deep in deeps.items():
        for kind in kinds:
            for t in TOPS:
                model = _pad_sum(top, deep, float(t), *kind) / plain
                rms = float(np.sqrt(np.mean((np.log(ratio[ok]) - np.log(model[ok])) ** 2)))
                if rms < best[3]:
                    best = (name, float(t), kind, rms)
    return best


def scene_rows(seed: int) -> list[dict]:
    fs = make_lump_scene(seed)
    _, sc, reader, make, training = trained_scene(seed, fs)
    res = explore_object(sc, sc.objects[0], training.memory, make, 7000 + seed, Progress(enabled=False),
                         boundary_reader=reader)
    fine = object_fine_map(res, sc.objects[0], sc, training_moduli(training.readings))
    refs = {n: (sc.materials[n].material.young, sc.materials[n].material.poisson) for n in sc.references}
    curves = {name: mean_curve(training.presses[name]) for name in refs}
    like = {name: ref for name, ref, _, _ in fs.materials}
    rows, seen = [], set()
    for spot in fine.summary["stiffness_anomalies"] or ():  # strongest first: one reading per lump
        cx, cy = (v * 1e3 for v in spot["centroid_m"])
        k = next((k for k, lu in enumerate(fs.lumps) if lump_footprint(lu, np.array(cx), np.array(cy))
                  or np.hypot(cx - lu["center_mm"][0], cy - lu["center_mm"][1]) < 10.0), None)
        if k is None or k in seen:
            continue
        seen.add(k)
        lump = fs.lumps[k]
        step = min((s for s in res.steps if s.result.press is not None),
                   key=lambda s: np.hypot(s.result.location[0] * 1e3 - cx, s.result.location[1] * 1e3 - cy))
        top = spot["material"]
        ratio = mean_curve([step.result]) / curves[top]
        deeps = {n: v for n, v in refs.items() if n != top}
        row = {"seed": seed, "top": lump_top_mm(lump), "shape": lump["shape"], "material": like[lump["material"]],
               "off": float(np.hypot(step.result.location[0] * 1e3 - lump["center_mm"][0],
                                     step.result.location[1] * 1e3 - lump["center_mm"][1]))}
        for name, kinds in KINDS.items():
            deep, t, kind, rms = read_depth(ratio, refs[top], deeps, kinds)
            row[name] = (deep, t * 1e3, kind, rms)
        rows.append(row)
    return rows


def main() -> None:
    args = scene_arguments(__doc__)
    print("seed    split  lump: top mm, shape, material, press off centre mm | per template set: material, depth mm")
    rows = []
    for found in scene_results(scene_rows, args):
        for r in found:
            rows.append(r)
            read = " | ".join(f"{n} {r[n][0] or '-'} {r[n][1]:.2f}" for n in KINDS)
            print(f"{r['seed']:7d} {'report' if is_report_seed(r['seed']) else 'tuning':6} {r['top']:4.1f} "
                  f"{r['shape']:6} {r['material']:7} {r['off']:5.1f} | {read}", flush=True)
    for name in KINDS:
        read = [r for r in rows if r[name][0] is not None]
        if not read:
            print(f"{name}: {len(rows)} spotted lumps, none read")
            continue
        err = np.array([r[name][1] - r["top"] for r in read])
        right = sum(r[name][0] == r["material"] for r in read)
        print(f"{name:6s}: {len(rows)} spotted, {len(read)} read, material right {right}; depth error (read - true) "
              f"median {np.median(err):+.2f} mm, |error| median {np.median(np.abs(err)):.2f} mm, within 1 / 2 mm "
              f"{np.mean(np.abs(err) <= 1):.0%} / {np.mean(np.abs(err) <= 2):.0%}")


if __name__ == "__main__":
    main()
