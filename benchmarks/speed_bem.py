"""The bem rung's cost per press against real time and against analytic's press of the same object, in one run
(CPU time, one BLAS thread, median of repeats): a plain block, a soft skin, a block split by a wall under the press,
a hard lump beside the axis, and a wall of the haptic-material map in scenarios/heterogeneous.toml and the edge of
its buried lump (a press there takes its force from the point's contact law, solved once as a SimSource keeps it).

Run: .venv/bin/python benchmarks/speed_bem.py [--repeat 5]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from palpate.core.session.sources import PressTarget
from palpate.core.world.resources import scenarios_dir
from palpate.core.world.scenario_file import load_scenario
from palpate.core.world.scene import Inclusion, Layer, Material, ObjectSpec, Scene
from palpate.sim.analytic import run_analytic_press
from palpate.sim.bem.press import run_bem_press
from palpate.sim.bem.wall import load_wall_table
from palpate.sim.blas import one_blas_thread
from palpate.sim.contact.stack import object_law
from palpate.sim.controller import ROBOT, press_profile
from palpate.sim.stability import law_depth


def objects() -> dict[str, tuple[ObjectSpec, tuple[float, float]]]:
    """Each benchmark object and the point pressed on it (m)."""
    half = 0.04
    soft = Material("soft", 20e3, 0.45)
    hard = Material("hard", 115e3, 0.45)
    wall = Inclusion(hard, "column", ((0.001 + half) / 2, 0.0, 0.015), (half - 0.001, 2 * half))
    lump = Inclusion(Material("lump", 2e6, 0.45), "box", (0.007, 0.0, 0.03 - 0.0035), (0.01, 0.01, 0.005))
    size = (0.08, 0.08, 0.03)
    scenario = load_scenario(scenarios_dir() / "heterogeneous.toml")
    mapped = scenario.objects[0].spec
    return {"block": (ObjectSpec("block", "box", size, (0.0, 0.0), hard), (0.0, 0.0)),
            "skin 1 mm": (ObjectSpec("skin", "box", size, (0.0, 0.0), Material("base", 200e3, 0.45),
                                     layers=(Layer(soft, 0.001),)), (0.0, 0.0)),
            "wall 1 mm off": (ObjectSpec("wall", "box", size, (0.0, 0.0), soft, inclusions=(wall,)), (0.0, 0.0)),
            "lump 2 mm off": (ObjectSpec("lump", "box", size, (0.0, 0.0), hard, inclusions=(lump,)), (0.0, 0.0)),
            "map wall": (mapped, (0.0479, 0.05)),
            "map lump edge": (mapped, (0.0279, 0.0062))}


def cpu(fn, repeat: int, *args, **kwargs) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.process_time()
        fn(*args, **kwargs)
        times.append(time.process_time() - t0)
    return float(np.median(times))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    walls = load_wall_table()
    print(f"{'object':<16} {'mixing':<8} {'press s':>8} {'bem ms':>8} {'x real time':>12} {'analytic ms':>12} "
          f"{'bem / analytic':>15}")
    for name, (obj, (x, y)) in objects().items():
        scene = Scene(objects=(obj,))
        profile = press_profile(PressTarget(x, y, depth=0.004, speed=0.01), obj.height, radius=0.008,
                                timestep=0.002, variability=ROBOT, seed=0)
        with one_blas_thread():
            law = object_law(obj, x, y, obj.height, 0.008, law_depth(profile))

            def law_for(max_depth: float, law=law):  # the point's law, solved once, as a SimSource keeps it
                return law

            # kernel tables built once per stack, as in a run
            trace = run_bem_press(scene, obj, profile, walls=walls, law_for=law_for)
            bem = cpu(run_bem_press, args.repeat, scene, obj, profile, walls=walls, law_for=law_for)
            analytic = cpu(run_analytic_press, args.repeat, scene, obj, profile, law=law)
        print(f"{name:<16} {trace.meta['mixing']:<8} {profile.duration:8.2f} {1e3 * bem:8.1f} "
              f"{profile.duration / bem:12.1f} {1e3 * analytic:12.1f} {bem / analytic:15.1f}")


if __name__ == "__main__":
    main()
