"""Where each fidelity is valid: every rung's force against the converged FE reference (sim/validity).

    .venv/bin/python benchmarks/validity.py --reference   # recompute models/reference_tables.json (FE, minutes)
    .venv/bin/python benchmarks/validity.py               # measure every case, write models/validity_table.json
    .venv/bin/python benchmarks/validity.py --quick       # the CI subset, printed only

The FE reference is checked against closed forms in tests/test_fe_reference.py and its mesh convergence is printed here
(the force change of three cases at refinement 0.5 and 1 against 2). What was tuned on what: the contact law has nothing
tuned (it is exact for layers; its axisymmetric averaging of lateral variation is exact on the axis); flex's mesh
correction was measured on homogeneous 1.7/3/7/14/30/70/150 mm blocks, none of which is a case here, and a stiff skin's
on calibration plates (2-70x, 0.7-4.5 mm skins, 12-60 mm; benchmarks/flex_plate.py), none of which is a case here
either. BLAS runs on one thread (unless OMP/OPENBLAS/MKL_NUM_THREADS say otherwise): on a busy machine its threads
waited for cores and then spun beside the next press, which made the FE-backed rungs look slower (docs/results.md).
"""

from __future__ import annotations

import os

# one core, as the table's cost line claims and as `palpate bench --write-table`, the table's other writer, runs
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402

from palpate.sim.validity.cases import quick_cases, validity_cases  # noqa: E402
from palpate.sim.validity.measure import measure_table  # noqa: E402
from palpate.sim.validity.reference import (  # noqa: E402
    REFERENCE_PATH,
    compute_reference,
    convergence_rows,
    load_reference,
)
from palpate.sim.validity.report import format_table  # noqa: E402
from palpate.sim.validity.table import TABLE_PATH  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--reference", action="store_true", help=f"recompute {REFERENCE_PATH.name} first (slow)")
    ap.add_argument("--quick", action="store_true", help="the CI subset; prints, writes nothing")
    args = ap.parse_args()
    t0 = time.perf_counter()
    if args.reference:
        def say(name, fe):
            print(f"  {time.perf_counter() - t0:7.1f} s  {name}: {fe.dofs} dofs", flush=True)

        doc = compute_reference(validity_cases(), progress=say)
        REFERENCE_PATH.write_text(json.dumps(doc, indent=1) + "\n")
        print(f"wrote {REFERENCE_PATH}")
    reference = load_reference()
    print("FE reference mesh convergence (largest force change against refinement 2):")
    for r in convergence_rows(reference):
        print(f"  {r.case:22} refinement {r.refinement:4.1f}  {r.dofs:7d} dofs  {r.max_change_pct:6.3f}%")
    cases = quick_cases() if args.quick else validity_cases()

    def progress(case, errs):
        print(f"  {time.perf_counter() - t0:7.1f} s  {case.name}", flush=True)

    table = measure_table(cases, reference, progress=progress)
    print(format_table(table))
    if not args.quick:
        TABLE_PATH.write_text(json.dumps(table.to_dict(), indent=1, allow_nan=False) + "\n")
        print(f"wrote {TABLE_PATH}")


if __name__ == "__main__":
    main()
