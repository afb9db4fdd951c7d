"""Stability at the extremes: the outcome of every cell of the matrix (palpate.sim.extremes), as a table.

Axes: fidelity, Young's modulus 1 kPa..100 MPa, Poisson 0..0.49, timestep 0.1..10 ms, speed 1..200 mm/s, depth
10%/80% of a 10 mm block, press at the centre, edge and corner. Outcomes: ok / diverged / invalid (each with the
message naming what to change) / BUG (must be none).

    .venv/bin/python benchmarks/stability_matrix.py --quick   # analytic + rigid, ~1 min
    .venv/bin/python benchmarks/stability_matrix.py           # adds flex (~15 min)
    .venv/bin/python benchmarks/stability_matrix.py --json out.json
"""

from __future__ import annotations

import argparse
import json
import time

from palpate.sim.extremes import matrix, outcome_counts, run_cell


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="analytic and rigid only, fewer values")
    ap.add_argument("--json", default=None, help="also write every cell's outcome to this JSON file")
    args = ap.parse_args()
    if args.quick:
        cells = matrix(fidelities=("analytic", "rigid"), youngs=(1e3, 1e5, 1e8), poissons=(0.0, 0.49),
                       timesteps=(1e-4, 2e-3, 1e-2), speeds=(0.001, 0.01, 0.2))
    else:
        cells = matrix(fidelities=("analytic", "rigid"), youngs=(1e3, 1e4, 1e5, 1e6, 1e7, 1e8))
        cells += matrix(fidelities=("flex",), youngs=(1e3, 1e5, 1e8), poissons=(0.3, 0.49), timesteps=(1e-3, 1e-2),
                        speeds=(0.01, 0.2))
    t0 = time.perf_counter()
    outcomes = [run_cell(c) for c in cells]
    print(f"{'fidelity':8} {'E Pa':>8} {'nu':>5} {'dt ms':>6} {'v mm/s':>6} {'d/h':>4} {'where':>7}  outcome")
    for o in outcomes:
        c = o.cell
        msg = f" {o.message[:90]}" if o.message else f" F_max {o.peak_force:.3g} N"
        print(f"{c.fidelity:8} {c.young:8.0e} {c.poisson:5.2f} {c.timestep * 1e3:6.1f} {c.speed * 1e3:6.0f} "
              f"{c.depth_fraction:4.1f} {c.location:>7}  {o.outcome}{msg}")
    counts = outcome_counts(outcomes)
    print(f"\n{len(outcomes)} cells in {time.perf_counter() - t0:.0f} s: "
          + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())))
    if args.json:
        with open(args.json, "w") as fh:
            json.dump([o.to_dict() for o in outcomes], fh, indent=1)
    return 1 if counts.get("BUG") else 0


if __name__ == "__main__":
    raise SystemExit(main())
