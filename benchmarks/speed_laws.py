"""The cost of a contact law at a new press point beside a change of material (the axisymmetric FE pair), against a
plain reference in the same run: the press point's azimuthally averaged field and its column alone solved on one
mesh (`fe_presses`: the mesh, its basis and the stiffness's geometric parts built once, each field's matrix summed
straight into the free dofs' CSC form) against each solved by `fe_press` on its own (its mesh built twice). The
laws must agree to rounding (printed: the largest relative force difference).

Points: a line of press points across scenarios/heterogeneous.toml's map (walls and the buried lump), every one a
new point (no law cache), one BLAS thread, CPU time, rounds interleaved.

Run: .venv/bin/python benchmarks/speed_laws.py [--points 12] [--rounds 3]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from palpate.core.world.resources import scenarios_dir
from palpate.core.world.scenario_file import load_scenario
from palpate.sim.blas import one_blas_thread
from palpate.sim.contact import axisymmetric
from palpate.sim.contact.stack import object_law
from palpate.sim.reference.fe import fe_press, fe_presses

TIP_RADIUS = 0.008
DEPTH = 0.004


def each_on_its_own(sample, tip_radius, depths, fields, **solve):
    """The plain reference: every field on its own mesh, as one fe_press call each."""
    return [fe_press(sample, tip_radius, depths, materials=f, **solve) for f in fields]


def laws(obj, points, solver) -> tuple[float, list]:
    """CPU seconds to make the law at every point with ``solver`` standing for fe_presses, and the laws."""
    axisymmetric.fe_presses = solver
    try:
        t0 = time.process_time()
        with one_blas_thread():
            out = [object_law(obj, x, y, obj.height, TIP_RADIUS, DEPTH) for x, y in points]
        return time.process_time() - t0, out
    finally:
        axisymmetric.fe_presses = fe_presses


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=12)
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    obj = load_scenario(scenarios_dir() / "heterogeneous.toml").objects[0].spec
    x0, y0 = obj.position
    half = 0.5 * obj.size[0] - 0.012
    points = [(x0 + u, y0 + 0.05 * u) for u in np.linspace(-half, half, args.points)]
    shipped, plain, worst = [], [], 0.0
    for _ in range(args.rounds):
        t_ship, got = laws(obj, points, fe_presses)
        t_plain, want = laws(obj, points, each_on_its_own)
        shipped.append(t_ship)
        plain.append(t_plain)
        for a, b in zip(got, want, strict=True):
            worst = max(worst, float(np.max(np.abs(a.force - b.force) / np.maximum(np.abs(b.force), 1e-300))))
    lateral = sum(1 for _ in points)
    s, p = float(np.median(shipped)), float(np.median(plain))
    print(f"{lateral} new press points on {obj.name} (heterogeneous.toml), {args.rounds} rounds, median CPU")
    print(f"{'':34} {'s':>7} {'ms / point':>11}")
    print(f"{'one mesh per pair (shipped)':34} {s:7.2f} {1e3 * s / lateral:11.1f}")
    print(f"{'each field on its own (reference)':34} {p:7.2f} {1e3 * p / lateral:11.1f}")
    print(f"ratio reference / shipped: {p / s:.2f}x; largest relative force difference {worst:.1e}")


if __name__ == "__main__":
    main()
