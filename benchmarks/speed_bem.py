"""The bem rung's cost per press against real time and against analytic's press of the same object, in one run
(CPU time, one BLAS thread, median of repeats): a plain block and a block split by a wall under the press.

Run: .venv/bin/python benchmarks/speed_bem.py [--repeat 5]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from palpate.core.session.sources import PressTarget
from palpate.core.world.scene import Inclusion, Material, ObjectSpec, Scene
from palpate.sim.analytic import run_analytic_press
from palpate.sim.bem.press import run_bem_press
from palpate.sim.bem.wall import load_wall_table
from palpate.sim.blas import one_blas_thread
from palpate.sim.contact.stack import object_law
from palpate.sim.controller import ROBOT, press_profile


def objects() -> dict[str, ObjectSpec]:
    half = 0.04
    soft = Material("soft", 20e3, 0.45)
    hard = Inclusion(Material("hard", 115e3, 0.45), "column", ((0.001 + half) / 2, 0.0, 0.015),
                     (half - 0.001, 2 * half))
    return {"block": ObjectSpec("block", "box", (0.08, 0.08, 0.03), (0.0, 0.0), soft),
            "wall 1 mm off": ObjectSpec("wall", "box", (0.08, 0.08, 0.03), (0.0, 0.0), soft, inclusions=(hard,))}


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
    print(f"{'object':<16} {'press s':>8} {'bem ms':>8} {'x real time':>12} {'analytic ms':>12} {'bem / analytic':>15}")
    for name, obj in objects().items():
        scene = Scene(objects=(obj,))
        profile = press_profile(PressTarget(0.0, 0.0, depth=0.004, speed=0.01), obj.height, radius=0.008,
                                timestep=0.002, variability=ROBOT, seed=0)
        with one_blas_thread():
            run_bem_press(scene, obj, profile, walls=walls)  # kernel tables built once per stack, as in a run
            bem = cpu(run_bem_press, args.repeat, scene, obj, profile, walls=walls)
            law = object_law(obj, 0.0, 0.0, obj.height, 0.008, 0.0042)
            analytic = cpu(run_analytic_press, args.repeat, scene, obj, profile, law=law)
        print(f"{name:<16} {profile.duration:8.2f} {1e3 * bem:8.1f} {profile.duration / bem:12.1f} "
              f"{1e3 * analytic:12.1f} {bem / analytic:15.1f}")


if __name__ == "__main__":
    main()
