"""Speed and accuracy of the `flex` fidelity over resolution and timestep; regenerates its calibration table.

Each row is one robot press-and-release (3 mm deep, 10 mm/s, ~1 s) at the centre of a thick homogeneous block
(40 x 40 x 20 mm, 200 kPa, nu 0.3) under an 8 mm tip, run on one core. Columns: cells (nx, ny, nz), wall time per
press, real-time factor, force error against Hertz (least-squares ratio - 1 over 0.3-1.5 mm indentation, with the
calibrated modulus) and the fitted force-indentation exponent over the same range (Hertz: 1.5).

Validity: the flex level is a trilinear FE block with cells coarser than the contact radius; its exponent stays
near 1.4, so after calibration the force is right on average over 0.3-1.5 mm but ~10% high at the low end and
~10% low at the high end. Use `analytic` where Hertz holds; flex is for finite thickness, layers, inclusions.

    .venv/bin/python benchmarks/flex_resolution.py            # full table (a few minutes)
    .venv/bin/python benchmarks/flex_resolution.py --quick    # default resolution, two timesteps
    .venv/bin/python benchmarks/flex_resolution.py --calibrate  # remeasure models/flex_calibration.json first
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from palpate.core.errors import SimulationDiverged
from palpate.sim.flex import DEFAULT_RESOLUTION, reference_press
from palpate.sim.flex_calibrate import hertz_ratio, measure_calibration
from palpate.sim.flex_calibration import CAL_POISSON, CAL_RANGE, CAL_YOUNG, CALIBRATION_PATH

RADIUS = 0.008
CALIBRATION_CELLS = [10.0 / 8.0, 6.67 / 8.0, 5.0 / 8.0]  # cell / tip radius: 4, 6, 8 cells over 40 mm


def press_row(resolution: float, timestep: float) -> dict:
    """Run one calibrated reference press and measure it."""
    t0 = time.perf_counter()
    try:
        tr = reference_press(young=CAL_YOUNG, poisson=CAL_POISSON, radius=RADIUS, resolution=resolution,
                             timestep=timestep, depth=0.003)
    except SimulationDiverged as exc:
        return {"resolution": resolution, "timestep": timestep, "error": str(exc)[:60]}
    wall = time.perf_counter() - t0
    press = tr.t <= tr.meta["press_end"]
    d, f = tr.indentation[press], tr.force[press]
    sel = (d >= CAL_RANGE[0]) & (d <= CAL_RANGE[1]) & (f > 0)
    exponent = float(np.polyfit(np.log(d[sel]), np.log(f[sel]), 1)[0])
    return {
        "resolution": resolution, "timestep": timestep, "cells": tr.meta["cells"], "wall": wall,
        "rtf": (tr.t[-1] - tr.t[0]) / wall, "error": hertz_ratio(d, f, CAL_YOUNG, CAL_POISSON, RADIUS) - 1.0,
        "exponent": exponent, "factor": tr.meta["calibration_factor"],
        "extrapolated": tr.meta["calibration_extrapolated"],
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="default resolution only, timesteps 2 and 5 ms")
    ap.add_argument("--calibrate", action="store_true", help=f"remeasure {CALIBRATION_PATH.name} first")
    args = ap.parse_args()
    if args.calibrate:
        table = measure_calibration(CALIBRATION_CELLS, radius=RADIUS, path=CALIBRATION_PATH)
        print(f"wrote {CALIBRATION_PATH}")
        for p in table["points"]:
            print(f"  cell/R {p['cell_over_radius']:.3f}  cell {p['cell'] * 1e3:.2f} mm  factor {p['factor']:.3f}")
    resolutions = [DEFAULT_RESOLUTION] if args.quick else [0.010, DEFAULT_RESOLUTION, 0.005]
    timesteps = [0.002, 0.005] if args.quick else [0.001, 0.002, 0.005]
    print(f"flex fidelity, thick block {CAL_YOUNG / 1e3:.0f} kPa, tip R {RADIUS * 1e3:.0f} mm, press 3 mm at 10 mm/s")
    print(f"{'res mm':>7} {'dt ms':>6} {'cells':>10} {'wall s':>7} {'x RT':>6} {'F err %':>8} {'exp':>5} {'factor':>6}")
    for res in resolutions:
        for dt in timesteps:
            r = press_row(res, dt)
            if "wall" not in r:
                print(f"{res * 1e3:7.2f} {dt * 1e3:6.1f}  diverged: {r['error']}")
                continue
            cells = "x".join(str(c) for c in r["cells"])
            flag = "*" if r["extrapolated"] else ""
            print(f"{res * 1e3:7.2f} {dt * 1e3:6.1f} {cells:>10} {r['wall']:7.2f} {r['rtf']:6.2f} "
                  f"{100 * r['error']:8.1f} {r['exponent']:5.2f} {r['factor']:6.3f}{flag}")
    print("F err: calibrated force vs Hertz, least squares over "
          f"{CAL_RANGE[0] * 1e3:.1f}-{CAL_RANGE[1] * 1e3:.1f} mm; * = calibration extrapolated")


if __name__ == "__main__":
    main()
