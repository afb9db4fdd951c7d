"""Cost of the depth-weighted effective modulus, and what it adds to an analytic and a rigid press.

Run: .venv/bin/python benchmarks/effective_modulus.py [--quick]
One core (BLAS threads pinned to 1). Objects: a homogeneous 20 kPa block, a 1.5 mm 20 kPa skin over a 200 kPa
base, and the same block with a 200 kPa lump 1 mm down. "table" is one per-press E*_eff table (24 contact radii,
48 depth cells x 24 lateral columns each); "analytic"/"rigid" time a whole 5 mm press at 10 mm/s (robot motion),
on the homogeneous block the same code path as before (one material: no table is made). "map block" is the
haptic-material-mapped block of scenarios/heterogeneous.toml pressed at its lump (x, y = 25, 15 mm).
Also prints E*_eff / E*_surface at the deepest point of each press.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402

import numpy as np  # noqa: E402
from bench_timing import median_of  # noqa: E402

from palpate.core.session.sources import PressTarget
from palpate.core.world.scene import FingertipSpec, Inclusion, Layer, Material, ObjectSpec, Scene
from palpate.sim.analytic import run_analytic_press  # noqa: E402
from palpate.sim.controller import press_profile  # noqa: E402
from palpate.sim.effective_modulus import effective_modulus_table  # noqa: E402

R = 0.008
H = 0.03
SOFT = Material("soft", 2e4)
HARD = Material("hard", 2e5)


def _objects() -> dict[str, tuple[ObjectSpec, float, float]]:
    from pathlib import Path

    from palpate.core.world.scenario_file import load_scenario

    size = (0.1, 0.1, H)
    het = load_scenario(Path(__file__).resolve().parents[1] / "scenarios" / "heterogeneous.toml").objects[0].spec
    objs = {
        "homogeneous": ObjectSpec("block", "box", size, (0, 0), SOFT),
        "skin 1.5 mm": ObjectSpec("block", "box", size, (0, 0), HARD, layers=(Layer(SOFT, 0.0015),)),
        "lump 1 mm down": ObjectSpec("block", "box", size, (0, 0), SOFT,
                                     inclusions=(Inclusion(HARD, "box", (0.0, 0.0, H - 0.011), (0.02, 0.02, 0.02)),)),
    }
    out = {name: (obj, 0.0, 0.0) for name, obj in objs.items()}
    out["map block"] = (het, 0.025, 0.015)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer repeats, no rigid press")
    args = parser.parse_args()
    repeats = 3 if args.quick else 10
    radii = np.linspace(0.0, np.sqrt(R * 0.005), 24)
    print(f"{'object':<16} {'table ms':>9} {'analytic ms':>12} {'rigid ms':>9} {'E*eff/E*surf':>13}")
    for name, (obj, x, y) in _objects().items():
        scene = Scene(objects=(obj,), fingertip=FingertipSpec(radius=R))
        t_tab, _ = median_of(lambda obj=obj, x=x, y=y: effective_modulus_table(obj, x, y, H, radii), repeats)
        profile = press_profile(PressTarget(x, y, depth=0.005, speed=0.01), H, radius=R, timestep=0.002)
        t_an, tr = median_of(lambda scene=scene, obj=obj, profile=profile: run_analytic_press(scene, obj, profile),
                           repeats)
        ratio = tr.meta["young_eff"] / tr.meta["young_eff_surface"]
        t_rig = float("nan")
        if not args.quick:
            from palpate.sim.rigid import run_rigid_press

            t_rig, _ = median_of(lambda scene=scene, obj=obj, profile=profile: run_rigid_press(scene, obj, profile),
                               max(repeats // 3, 1))
        print(f"{name:<16} {t_tab * 1e3:9.2f} {t_an * 1e3:12.2f} {t_rig * 1e3:9.1f} {ratio:13.2f}")


if __name__ == "__main__":
    main()
