"""Speed and accuracy of the `flex` fidelity over resolution and window; regenerates its mesh correction table.

Each row is one robot press-and-release (3.2 mm deep, 10 mm/s) at the centre of a wide homogeneous block bonded
to the table (200 kPa) under an 8 mm tip, on one core: cells (nx, ny, nz), degrees of freedom, wall time, the
real-time factor (simulated seconds per wall second, measured in the same run), and the force against the
reference (the layered contact law of the same block, which agrees with the FE reference within ~1%) at 0.5, 1, 2
and 3 mm. The mesh correction was measured on 1.7/3/7/14/30/70/150 mm blocks (tuning); the 10, 20 and 40 mm blocks
report.

    .venv/bin/python benchmarks/flex_resolution.py             # default resolution and window, 3 thicknesses
    .venv/bin/python benchmarks/flex_resolution.py --full      # also other resolutions/windows (uncalibrated ones
                                                               # marked *: their correction is extrapolated)
    .venv/bin/python benchmarks/flex_resolution.py --calibrate # remeasure models/flex_calibration.json first
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from palpate.core.errors import PalpateError
from palpate.core.world.scene import Material
from palpate.sim.contact.law import solve_contact_law
from palpate.sim.flex.calibrate import loading_ratio, measure_calibration
from palpate.sim.flex.calibration import CAL_YOUNG, CALIBRATION_PATH
from palpate.sim.flex.grid import DEFAULT_RESOLUTION, DEFAULT_WINDOW
from palpate.sim.flex.press import reference_press
from palpate.sim.reference.sample import AxisymmetricSample

RADIUS = 0.008
DEPTHS = np.array([0.5, 1.0, 2.0, 3.0]) * 1e-3


def press_row(resolution: float, window: float, height: float, poisson: float) -> dict:
    """One press and its errors against the reference."""
    t0 = time.perf_counter()
    try:
        tr = reference_press(young=CAL_YOUNG, poisson=poisson, radius=RADIUS, resolution=resolution, window=window,
                             height=height, depth=0.0032)
    except PalpateError as exc:
        return {"error": str(exc)[:90]}
    wall = time.perf_counter() - t0
    law = solve_contact_law(AxisymmetricSample(Material("m", CAL_YOUNG, poisson), height), RADIUS, 0.0035)
    ratio = loading_ratio(tr.indentation, tr.force, law, DEPTHS)
    return {"cells": tr.meta["cells"], "dofs": tr.meta["dofs"], "wall": wall, "rtf": (tr.t[-1] - tr.t[0]) / wall,
            "errors": ratio - 1.0, "extrapolated": tr.meta["calibration_extrapolated"]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--full", action="store_true", help="also other resolutions and windows")
    ap.add_argument("--calibrate", action="store_true", help=f"remeasure {CALIBRATION_PATH.name} first")
    args = ap.parse_args()
    if args.calibrate:
        table = measure_calibration(DEFAULT_RESOLUTION, radius=RADIUS, window=DEFAULT_WINDOW, path=CALIBRATION_PATH,
                                    progress=lambda sides, nu, h: print(f"  measured {sides} nu {nu} H {h * 1e3:g} mm",
                                                                        flush=True))
        print(f"wrote {CALIBRATION_PATH}")
        for t in table.tables:
            print(f"{t.sides} sides, a/cell " + " ".join(f"{v:5.2f}" for v in t.contact_over_cell[::4]))
            for nu, rows in zip(t.poisson, t.factor, strict=True):
                for h, row in zip(t.thickness, rows, strict=True):
                    print(f"nu {nu:4.2f} {h * 1e3:3.0f}mm " + " ".join(f"{v:5.3f}" for v in row[::4]))
    settings = [(DEFAULT_RESOLUTION, DEFAULT_WINDOW)]
    if args.full:
        settings += [(0.0075, 0.03), (0.005, 0.02), (0.005, 0.04), (0.0033, 0.03)]
    print(f"flex fidelity, {CAL_YOUNG / 1e3:.0f} kPa, tip R {RADIUS * 1e3:.0f} mm, press 3.2 mm at 10 mm/s, one core")
    print(f"{'res mm':>6} {'win mm':>6} {'H mm':>5} {'nu':>5} {'cells':>9} {'dofs':>5} {'wall s':>7} {'x RT':>6}  "
          "F err % at 0.5/1/2/3 mm")
    for res, win in settings:
        for height in (0.01, 0.02, 0.04):
            for nu in (0.3, 0.45, 0.49):
                r = press_row(res, win, height, nu)
                head = f"{res * 1e3:6.1f} {win * 1e3:6.0f} {height * 1e3:5.0f} {nu:5.2f}"
                if "error" in r:
                    print(f"{head}  failed: {r['error']}")
                    continue
                cells = "x".join(str(c) for c in r["cells"])
                flag = " *" if r["extrapolated"] else ""
                errs = " ".join(f"{100 * e:+6.1f}" for e in r["errors"])
                print(f"{head} {cells:>9} {r['dofs']:5d} {r['wall']:7.2f} {r['rtf']:6.2f}  {errs}{flag}")
    print("x RT: simulated time / wall time in this run; * = mesh correction extrapolated (another cell size)")


if __name__ == "__main__":
    main()
