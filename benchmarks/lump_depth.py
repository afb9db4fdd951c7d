"""How deep is a lump, from the presses over it? A measurement for a per-press depth reading (no map uses one yet).

For every lump of benchmarks/lump_scenes.py that a raster's stiffness spots found (summary.json's
``stiffness_anomalies``), the spot's strongest press is read: its contact intensity c_P against its indentation
c_D, divided by the mean curve of the training presses of the material the map names there (the top), is matched
against the same ratio for two-layer stacks (the top over each other reference material from a depth t, 0.25-10 mm;
the contact law and the pad's sensel image of the simulation, law_sensel_pressure) by least squares in log. The
reading: t and the deep material. Scored against the lump's top depth and material; a lump is finite, the stack
is not, so the reading is biased deep where the lump is narrower than the contact. Seeds from 100000 on are
report seeds.

Run: .venv/bin/python benchmarks/lump_depth.py [--first 100000] [--scenes 24] [--jobs 2]
"""

from __future__ import annotations

import argparse
import warnings
from concurrent.futures import ProcessPoolExecutor
from functools import cache

import numpy as np
from fine_map_families import trained_scene
from lump_scenes import lump_footprint, lump_top_mm, make_lump_scene
from scene_families import is_report_seed

from palpate.core.session.boundaries import object_fine_map, training_moduli
from palpate.core.session.explore import explore_object
from palpate.core.session.progress import Progress
from palpate.core.world.scene import FingertipSpec, Layer, Material

#: Indentations the curves are compared at, m.
DEPTHS = np.linspace(0.75e-3, 4.0e-3, 14)
#: Depths of the stack's interface the reading chooses among, m.
TOPS = np.arange(0.25e-3, 10.01e-3, 0.25e-3)


@cache
def _pad_sum(top: tuple[float, float], deep: tuple[float, float] | None, t: float) -> np.ndarray:
    """Sum of the pad's sensel pressures (Pa) at DEPTHS for ``top`` (E Pa, nu) over ``deep`` from ``t`` m (None:
    the top all the way), 40 mm to a bonded base, the default fingertip."""
    from palpate.sim.analytic import law_sensel_pressure
    from palpate.sim.contact.law import solve_contact_law
    from palpate.sim.fingertip import sensel_bounds
    from palpate.sim.reference.sample import AxisymmetricSample

    tip = FingertipSpec()
    top_m = Material("top", *top)
    if deep is None:
        stack = AxisymmetricSample(bulk=top_m, thickness=0.04)
    else:
        stack = AxisymmetricSample(bulk=Material("deep", *deep), thickness=0.04, layers=(Layer(top_m, t),))
    law = solve_contact_law(stack, tip.radius, 1.05 * DEPTHS[-1])
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


def read_depth(ratio: np.ndarray, top: tuple[float, float], deeps: dict[str, tuple[float, float]]):
    """(deep material, t m, rms in log) of the stack whose pad-sum ratio to the plain top fits ``ratio`` best."""
    ok = np.isfinite(ratio) & (ratio > 0)
    plain = _pad_sum(top, None, 0.0)
    best = (None, float("nan"), float(np.sqrt(np.mean(np.log(ratio[ok]) ** 2))))
    for name, deep in deeps.items():
        for t in TOPS:
            model = _pad_sum(top, deep, float(t)) / plain
            rms = float(np.sqrt(np.mean((np.log(ratio[ok]) - np.log(model[ok])) ** 2)))
            if rms < best[2]:
                best = (name, float(t), rms)
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
        lump = next((k for k, lu in enumerate(fs.lumps) if lump_footprint(lu, np.array(cx), np.array(cy))
                     or np.hypot(cx - lu["center_mm"][0], cy - lu["center_mm"][1]) < 10.0), None)
        if lump is None or lump in seen:
            continue
        seen.add(lump)
        lump = fs.lumps[lump]
        step = min((s for s in res.steps if s.result.press is not None),
                   key=lambda s: np.hypot(s.result.location[0] * 1e3 - cx, s.result.location[1] * 1e3 - cy))
        top = spot["material"]
        observed = mean_curve([step.result])
        deep, t, rms = read_depth(observed / curves[top], refs[top], {n: v for n, v in refs.items() if n != top})
        rows.append({"seed": seed, "top": lump_top_mm(lump), "shape": lump["shape"], "material": like[lump["material"]],
                     "read": deep, "t": t * 1e3, "rms": rms})
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--first", type=int, default=100000)
    parser.add_argument("--scenes", type=int, default=24)
    parser.add_argument("--jobs", type=int, default=1)
    args = parser.parse_args()
    print("seed    split  lump: top mm, shape, material | read: depth mm, material, rms (log)")
    rows = []
    with ProcessPoolExecutor(args.jobs) as pool:
        for found in pool.map(scene_rows, range(args.first, args.first + args.scenes)):
            for r in found:
                rows.append(r)
                print(f"{r['seed']:7d} {'report' if is_report_seed(r['seed']) else 'tuning':6} {r['top']:4.1f} "
                      f"{r['shape']:6} {r['material']:7} | {r['t']:5.2f} {r['read'] or '(one material)':15} "
                      f"{r['rms']:.3f}", flush=True)
    read = [r for r in rows if r["read"] is not None]
    if not read:
        print(f"\n{len(rows)} spotted lumps, none read as a stack")
        return
    err = np.array([r["t"] - r["top"] for r in read])
    right = sum(r["read"] == r["material"] for r in read)
    print(f"\n{len(rows)} spotted lumps read; {len(read)} read as a stack, deep material right on {right}; depth "
          f"error (read - true) median {np.median(err):+.2f} mm, |error| median {np.median(np.abs(err)):.2f} mm, "
          f"within 1 / 2 mm {np.mean(np.abs(err) <= 1):.0%} / {np.mean(np.abs(err) <= 2):.0%}")

if __name__ == "__main__":
    main()
