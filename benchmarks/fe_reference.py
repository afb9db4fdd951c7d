"""The FE reference (sim/reference): its mesh convergence, and how far the closed-form Hertz law is from it on
blocks of finite thickness.

Part 1 refines the mesh (surface spacing = smallest contact radius / 12 / refinement) on a 20 mm block (E = 100 kPa,
nu = 0.45, bonded base) and on a 60 mm block (200 kPa, nu 0.3), printing each level's force and its change against
the finest, and, for the 60 mm block, Sneddon's sphere times Dimitriadis et al.'s (2002) bonded-layer factor.

Part 2 measures how far the cheap rungs are off with thickness: the `analytic` and `rigid` rungs return Hertz's
force for a homogeneous block whatever its thickness; the table gives Hertz's error against the reference at 5-60 mm
(E = 200 kPa, nu 0.3, tip radius 8 mm).

Run: .venv/bin/python benchmarks/fe_reference.py [--quick]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from palpate.core.world.scene import Material
from palpate.sim.hertz import hertz_force, sneddon_sphere_force_at_depth
from palpate.sim.reference.bonded_layer import dimitriadis_factor
from palpate.sim.reference.fe import fe_press
from palpate.sim.reference.sample import AxisymmetricSample

R = 0.008


def convergence(sample: AxisymmetricSample, depths: np.ndarray, levels: list[float], closed=None) -> None:
    print(f"\n{sample.describe()}; depths {', '.join(f'{1e3 * d:g}' for d in depths)} mm")
    runs = []
    for k in levels:
        t0 = time.perf_counter()
        fe = fe_press(sample, R, depths, refinement=k)
        runs.append((k, fe, time.perf_counter() - t0))
    finest = runs[-1][1].force
    print(f"{'refinement':>10} {'dofs':>8} {'h0 mm':>7} {'s':>6}  force N (change vs finest)")
    for k, fe, s in runs:
        cells = "  ".join(f"{f:8.4f} ({100 * (f / g - 1):+.2f}%)" for f, g in zip(fe.force, finest, strict=True))
        print(f"{k:>10g} {fe.dofs:>8d} {1e3 * fe.h0:>7.3f} {s:>6.1f}  {cells}")
    if closed is not None:
        cells = "  ".join(f"{f:8.4f} ({100 * (f / g - 1):+.2f}%)" for f, g in zip(closed, finest, strict=True))
        print(f"{'closed form':>33}  {cells}")


def hertz_error(depths: np.ndarray, thicknesses: list[float], refinement: float) -> None:
    m = Material("block", 2e5, 0.3)
    print(f"\nHertz (what analytic/rigid return for a homogeneous block) against the reference, E = 200 kPa, "
          f"nu 0.3, bonded base, refinement {refinement:g}")
    print(f"{'thickness mm':>12}  " + "  ".join(f"{1e3 * d:>6g} mm" for d in depths))
    for h in thicknesses:
        fe = fe_press(AxisymmetricSample(m, h), R, depths, refinement=refinement)
        err = hertz_force(m.effective_modulus, R, depths) / fe.force - 1
        print(f"{1e3 * h:>12g}  " + "  ".join(f"{100 * e:>+8.1f}%" for e in err))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="coarser levels and fewer thicknesses")
    args = ap.parse_args()
    levels = [0.5, 1.0] if args.quick else [0.5, 1.0, 2.0]
    d = np.array([0.5, 1.0, 2.0]) * 1e-3
    convergence(AxisymmetricSample(Material("b", 1e5, 0.45), 0.02), d, levels)
    thick = AxisymmetricSample(Material("m", 2e5, 0.3), 0.06)
    closed = sneddon_sphere_force_at_depth(thick.bulk.effective_modulus, R, d) * dimitriadis_factor(
        np.sqrt(R * d) / thick.thickness, thick.bulk.poisson)
    convergence(thick, d, levels, closed)
    hertz_error(np.array([1.0, 2.0, 3.0]) * 1e-3, [0.005, 0.01, 0.02, 0.06] if not args.quick else [0.01, 0.06],
                1.0)


if __name__ == "__main__":
    main()
