"""The `flex` correction for lumps (sim/flex/lump.py): its calibration, and flex's error on held-out lumps without
it (before) and with it (after).

    .venv/bin/python benchmarks/flex_lump.py --calibrate   # remeasure models/flex_lump_calibration.json first
    .venv/bin/python benchmarks/flex_lump.py               # the held-out lumps, before -> after

The table is measured on calibration lumps (sim/flex/lump.py: spheres of 4 / 6 mm, tops 0.7-7.5 mm down, 0.05-40x
the bulk), none of which is reported here. Every lump below is held out: the validity table's five lumps (against
the cached FE reference) and NEW_LUMPS (against the FE reference solved here, refinement 1). Each is one shipped flex
press (`validity.measure.press_case`'s, to 4.12 mm); "before" is its force times r at each depth's a / cell (the
press divides each step's force by r, and the tip's drive is fed the uncorrected force, so the motion is the same).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from palpate.sim.flex.calibrate import lump_sample, measure_lump_calibration
from palpate.sim.flex.grid import DEFAULT_RESOLUTION
from palpate.sim.flex.lump import LUMP_CALIBRATION_PATH, load_lump_calibration, lump_curve, pocket_moduli
from palpate.sim.reference.fe import fe_press
from palpate.sim.validity.cases import TIP_RADIUS, ValidityCase, case_object, validity_cases
from palpate.sim.validity.measure import loading_force, press_case
from palpate.sim.validity.reference import load_reference, reference_force

DEPTHS = np.array([0.5, 1.0, 2.0, 4.0]) * 1e-3
#: New held-out lumps, written down before the correction was first evaluated on them: (label, top m, radius m,
#: E_lump / E_bulk), in the calibration block (30 mm, 100 kPa, nu 0.45).
NEW_LUMPS = (
    ("soft 0.1x r 5.5 mm top 1.2 mm", 0.0012, 0.0055, 0.1),
    ("soft 0.3x r 4.5 mm top 0.9 mm", 0.0009, 0.0045, 0.3),
    ("hard 10x r 5 mm top 2 mm", 0.002, 0.005, 10.0),
    ("soft 0.03x r 5 mm top 3 mm", 0.003, 0.005, 0.03),
    ("hard 20x r 4.5 mm top 1 mm", 0.001, 0.0045, 20.0),
)


def before_after(case: ValidityCase, reference: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Flex's error at DEPTHS without and with the lump correction, and the press's CPU time (with its build), s."""
    models: dict = {}
    t0 = time.process_time()
    trace = press_case(case, "flex", models).trace
    cpu = time.process_time() - t0
    after = loading_force(trace.indentation, trace.force, DEPTHS)
    r = np.ones_like(DEPTHS)
    if trace.meta["lump_corrected"]:
        fm = next(iter(models.values()))[0]
        e = pocket_moduli(case_object(case), fm.grid, fm.cell_young, fm.cell_poisson, 0.0, 0.0)
        curve = lump_curve(load_lump_calibration(), e, DEFAULT_RESOLUTION / TIP_RADIUS)
        r = np.array([curve.at(float(np.sqrt(TIP_RADIUS * d)) / DEFAULT_RESOLUTION) for d in DEPTHS])
    return after * r / reference - 1.0, after / reference - 1.0, cpu


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--calibrate", action="store_true", help=f"remeasure {LUMP_CALIBRATION_PATH}")
    args = parser.parse_args()
    if args.calibrate:
        t0 = time.perf_counter()
        measure_lump_calibration(path=LUMP_CALIBRATION_PATH,
                                 progress=lambda c, r, k: print(f"  top {c * 1e3:.1f} mm r {r * 1e3:.0f} mm {k:g}x",
                                                                flush=True))
        print(f"wrote {LUMP_CALIBRATION_PATH} in {time.perf_counter() - t0:.0f} s")
        return
    reference = load_reference()
    cases = [(c.name, c, np.interp(DEPTHS, c.depths, reference_force(reference, c)))
             for c in validity_cases() if c.family == "lump"]
    for label, top, size, contrast in NEW_LUMPS:
        sample = lump_sample(top, size, contrast)
        case = ValidityCase(label, "lump", sample, (0.004,))
        cases.append((label, case, fe_press(sample, TIP_RADIUS, DEPTHS).force))
    print("flex error at 0.5 / 1 / 2 / 4 mm, % (before -> after the lump correction); CPU s per press")
    means = {"table": [], "new": []}
    for name, case, ref in cases:
        b, a, cpu = before_after(case, ref)
        means["table" if case.name.startswith("lump_") else "new"].append((np.abs(b), np.abs(a)))
        print(f"  {name:32s} " + " / ".join(f"{100 * v:+.1f}" for v in b) + " -> "
              + " / ".join(f"{100 * v:+.1f}" for v in a) + f"%  cpu {cpu:.2f} s")
    for key, rows in means.items():
        b = np.mean([r[0] for r in rows]) * 100
        a = np.mean([r[1] for r in rows]) * 100
        print(f"mean |error| over the {key} lumps: {b:.2f} -> {a:.2f}%")


if __name__ == "__main__":
    main()
