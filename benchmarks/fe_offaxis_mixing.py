"""The contact law's azimuthal mixing, measured against the 3-D FE for each power mean (swapped in for this process
only).

Each ring's mean is taken relative to its depth's matrix (the material covering most of the disc): the sectors
stiffer than the matrix by one power mean (``power``), the softer ones by another (``soft_power``). Stiff lumps in a
soft bulk have only stiffer sectors, soft lumps in a stiff bulk (--soft) only softer ones, so each exponent is chosen
on its own rows.

The law first averaged the material around the press axis by the arithmetic mean of E over each ring (a Voigt-type
upper bound: sectors in parallel), which benchmarks/fe_offaxis.py showed 36-58% too stiff beside a stiff shallow
lump; it now uses the geometric mean (p = 0 below), chosen here. The family: the ring's power mean
M_p = (mean E^p)^(1/p) over the sectors inside the object, times the fraction of the ring inside (so a free edge
counts as before); p = 1 is the first mixing, p = 0 the geometric mean, p = -1 the harmonic (Reuss) mean.
On an on-axis inclusion, a layer or a cylinder's centre every ring is uniform and any p gives the same law, so the
validated cases do not move.

p (stiff lumps) is tuned on the nu 0.3 rows of the saved table and reported on the nu 0.45 rows (never tuned on);
soft_power (--soft) is tuned on the nu 0.45 soft rows and reported on the nu 0.3 ones.

Run: .venv/bin/python benchmarks/fe_offaxis.py --save /tmp/offaxis.json
     .venv/bin/python benchmarks/fe_offaxis_mixing.py /tmp/offaxis.json
     .venv/bin/python benchmarks/fe_offaxis.py --soft --save /tmp/soft.json
     .venv/bin/python benchmarks/fe_offaxis_mixing.py --soft /tmp/soft.json
"""

from __future__ import annotations

import argparse
import functools
import json
from pathlib import Path

import numpy as np

from palpate.sim.contact import axisymmetric
from palpate.sim.validity.offaxis import OffAxisCase, law_force

MAX_BYTES = 1_000_000
P_GRID = (1.0, 0.5, 0.25, 0.0, -0.25, -0.5, -1.0)


def load_rows(path: Path) -> list[dict]:
    """The rows benchmarks/fe_offaxis.py --save wrote (validated: size, keys, finite positive ratios)."""
    if path.stat().st_size > MAX_BYTES:
        raise SystemExit(f"{path}: larger than {MAX_BYTES} bytes; not a table from fe_offaxis.py --save")
    rows = json.loads(path.read_text()).get("rows")
    if not isinstance(rows, list) or not rows:
        raise SystemExit(f"{path}: no 'rows' list")
    for i, row in enumerate(rows):
        for key in ("contrast", "top", "near", "poisson", "law_ratio", "fe_ratio"):
            if key not in row:
                raise SystemExit(f"{path}: rows[{i}] lacks {key!r}")
        fe = np.asarray(row["fe_ratio"], dtype=float)
        if not (np.all(np.isfinite(fe)) and np.all(fe > 0)):
            raise SystemExit(f"{path}: rows[{i}].fe_ratio must be finite and > 0")
    return rows


def law_errors(rows: list[dict], p: float, exponent: str = "power") -> np.ndarray:
    """(rows, depths) law error against the 3-D FE ratio with mixing p for ``exponent`` ("power": the sectors
    stiffer than the matrix, "soft_power": the softer ones)."""
    original = axisymmetric.azimuthal_materials
    # the law reads the mixing from its module at call time: swap in power p for this process only
    axisymmetric.azimuthal_materials = functools.partial(original, **{exponent: p})
    try:
        plain: dict = {}
        out = []
        for row in rows:
            case = OffAxisCase(row["contrast"], row["top"], row["near"], row["poisson"])
            if case.poisson not in plain:
                plain[case.poisson] = law_force(None, case.poisson)
            out.append(law_force(case) / plain[case.poisson] / np.asarray(row["fe_ratio"]) - 1.0)
        return np.array(out)
    finally:
        axisymmetric.azimuthal_materials = original


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("rows", type=Path, help="JSON from benchmarks/fe_offaxis.py --save")
    parser.add_argument("--soft", action="store_true",
                        help="soft-lump rows (fe_offaxis.py --soft): sweep soft_power, tune on nu 0.45, report nu 0.3")
    args = parser.parse_args()
    rows = load_rows(args.rows)
    exponent = "soft_power" if args.soft else "power"
    tuned_nu = 0.45 if args.soft else 0.3
    tune = [r for r in rows if abs(r["poisson"] - tuned_nu) < 0.01]
    report = [r for r in rows if abs(r["poisson"] - tuned_nu) >= 0.01]
    print(f"{exponent}: tuning on {len(tune)} rows (nu {tuned_nu:g}), reporting on {len(report)} (the others)")
    print(f"{'p':>6} {'tune: rms %':>12} {'max |err| %':>12}")
    scores = {}
    for p in P_GRID:
        err = law_errors(tune, p, exponent)
        scores[p] = float(np.sqrt(np.mean(err**2)))
        print(f"{p:6.2f} {100 * scores[p]:12.1f} {100 * np.max(np.abs(err)):12.1f}", flush=True)
    best = min(scores, key=scores.get)
    print(f"\nbest {exponent} on the tuning rows: {best:g}; on the report rows (never tuned on):")
    for p in sorted({1.0, 0.0, best}, reverse=True):
        err = law_errors(report, p, exponent) if report else np.zeros((0, 1))
        if err.size:
            print(f"  p {p:5.2f}: rms {100 * np.sqrt(np.mean(err**2)):.1f}%, max |err| "
                  f"{100 * np.max(np.abs(err)):.1f}%, range {100 * err.min():+.1f}% to {100 * err.max():+.1f}%")
    for row, e in zip(report, law_errors(report, best, exponent) if report else [], strict=True):
        case = OffAxisCase(row["contrast"], row["top"], row["near"], row["poisson"])
        print(f"    {case.label:<38} {' '.join(f'{100 * v:+6.1f}' for v in e)}")


if __name__ == "__main__":
    main()
