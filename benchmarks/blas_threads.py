"""The FE-backed contact laws with BLAS on one thread against BLAS's own thread count, in one run.

An analytic press at a new point (the law is solved, not cached) on a block with a hard sphere just under its top,
so the law comes from the axisymmetric FE (sim/contact/axisymmetric.py); each round presses once with
``palpate.sim.blas.one_blas_thread`` (shipped) and once with it replaced by a no-op (BLAS's default threads, the
plain reference), interleaved so the machine's load hits both alike. Prints the median wall and CPU time of each
and their ratio. On a machine whose cores are busy, BLAS's threads wait for a core and then spin: the ratio is
largest there (docs/results.md, "Lumps' cost").

Run: .venv/bin/python benchmarks/blas_threads.py [--rounds 4]
"""

from __future__ import annotations

import argparse
import contextlib
import time

import numpy as np

from palpate.core.session.sources import PressTarget
from palpate.core.world.scene import FingertipSpec, Inclusion, Material, ObjectSpec, Scene
from palpate.sim import source

RADIUS = 0.008


def lump_scene() -> Scene:
    """A 100 kPa block 30 mm thick with a 2 MPa sphere of 5 mm radius 1 mm under its top."""
    obj = ObjectSpec("lump", "box", (0.08, 0.08, 0.03), (0.0, 0.0), Material("foam", 1e5, 0.45),
                     inclusions=(Inclusion(Material("hard", 2e6, 0.4), "sphere", (0.0, 0.0, 0.024), (0.005,)),))
    return Scene(objects=(obj,), fingertip=FingertipSpec(radius=RADIUS))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=4, help="interleaved presses of each kind (default 4)")
    args = ap.parse_args()
    if args.rounds < 1:
        ap.error("--rounds must be >= 1")
    scene, shipped = lump_scene(), source.one_blas_thread
    times = {"one thread": [], "default threads": []}
    try:
        for k in range(args.rounds):
            for name in times:
                source.one_blas_thread = shipped if name == "one thread" else contextlib.nullcontext
                wall, cpu = time.perf_counter(), time.process_time()
                # a new point each press, so each solves its law (points 0.1 mm apart would share one)
                target = PressTarget(0.001 * k + (0.0005 if name == "default threads" else 0.0), 0.0, depth=0.002,
                                     speed=0.01)
                source.SimSource(scene, fidelity="analytic", seed=k).press(target)
                times[name].append((time.perf_counter() - wall, time.process_time() - cpu))
    finally:
        source.one_blas_thread = shipped
    med = {name: np.median(np.array(v), axis=0) for name, v in times.items()}
    for name, (wall, cpu) in med.items():
        print(f"{name:16s} wall {wall:.3f} s  cpu {cpu:.3f} s  (median of {args.rounds})")
    print(f"default / one thread: wall {med['default threads'][0] / med['one thread'][0]:.2f}x, "
          f"cpu {med['default threads'][1] / med['one thread'][1]:.2f}x")


if __name__ == "__main__":
    main()
