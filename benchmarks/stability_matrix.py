"""Stability at the extremes: the outcome of every cell of the matrix (palpate.sim.extremes), as a table.

Axes: fidelity, Young's modulus 1 kPa..100 MPa, Poisson 0..0.49, timestep 0.1..10 ms, speed 1..200 mm/s, depth
10%/50% of a 10 mm block, press at the centre, edge and corner; then the audit's cells (palpate.sim.extremes.
audit_cells: a press deeper than the base holds, thin skins, a 2 mm block pressed to 1.8 mm, nu to 0.49995, on every
rung and auto). Outcomes: ok (its force error against the contact law at the centre, its solver-warning steps) /
diverged / invalid (each with the message naming what to change and, for what a rung holds, its limit) / BUG (must
be none: NaN, disorder, a silent miss or a silent wrong answer).

    .venv/bin/python benchmarks/stability_matrix.py --quick   # analytic, bem, rigid, ~2 min
    .venv/bin/python benchmarks/stability_matrix.py           # adds flex (~15 min)
    .venv/bin/python benchmarks/stability_matrix.py --json out.json
"""

from __future__ import annotations

import argparse
import json
import time

from palpate.sim.extremes import audit_cells, matrix, outcome_counts, run_cell


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="analytic, bem and rigid only, fewer values")
    ap.add_argument("--json", default=None, help="also write every cell's outcome to this JSON file")
    args = ap.parse_args()
    if args.quick:
        cells = matrix(fidelities=("analytic", "bem", "rigid"), youngs=(1e3, 1e5, 1e8), poissons=(0.0, 0.49),
                       timesteps=(1e-4, 2e-3, 1e-2), speeds=(0.001, 0.01, 0.2))
    else:
        cells = matrix(fidelities=("analytic", "bem", "rigid"), youngs=(1e3, 1e4, 1e5, 1e6, 1e7, 1e8))
        cells += matrix(fidelities=("flex",), youngs=(1e3, 1e5, 1e8), poissons=(0.3, 0.49), timesteps=(1e-3, 1e-2),
                        speeds=(0.01, 0.2))
    cells += audit_cells()
    t0 = time.perf_counter()
    outcomes = [run_cell(c) for c in cells]
    print(f"{'fidelity':8} {'E Pa':>8} {'nu':>7} {'dt ms':>6} {'v mm/s':>6} {'h mm':>5} {'skin':>5} {'d/h':>4} "
          f"{'where':>7}  outcome")
    for o in outcomes:
        c = o.cell
        if o.message:
            msg = f" {o.message[:110]}"
        else:
            err = f", {o.error:+.1%} vs the law" if o.error == o.error else ""
            warned = f", {o.solver_warning_steps} warned steps" if o.solver_warning_steps else ""
            msg = f" {o.fidelity} F_max {o.peak_force:.3g} N{err}{warned}"
        print(f"{c.fidelity:8} {c.young:8.0e} {c.poisson:7.5g} {c.timestep * 1e3:6.1f} {c.speed * 1e3:6.0f} "
              f"{c.thickness * 1e3:5.1f} {c.skin * 1e3:5.2f} {c.depth_fraction:4.2f} {c.location:>7}  {o.outcome}{msg}")
    counts = outcome_counts(outcomes)
    print(f"\n{len(outcomes)} cells in {time.perf_counter() - t0:.0f} s: "
          + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())))
    if args.json:
        with open(args.json, "w") as fh:
            json.dump([o.to_dict() for o in outcomes], fh, indent=1)
    return 1 if counts.get("BUG") else 0


if __name__ == "__main__":
    raise SystemExit(main())
