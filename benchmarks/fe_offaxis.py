"""The contact law beside a box lump (off the press axis) against an independent 3-D FE (sim/reference/fe3d.py).

Part 1 validates the 3-D FE on homogeneous blocks: a 20 mm block (80 x 80 mm, 25 kPa, nu 0.3 and 0.45) against the
axisymmetric FE reference (sim/reference/fe.py) at refinement 1, and a 60 mm block (120 x 120 mm, nu 0.3) against
Sneddon's sphere times Dimitriadis et al.'s bonded-layer factor (cells growing 1.5x away, not 1.3x, to stay
small); the error printed is the 3-D mesh's own.

Part 2 prints, per case of sim/validity/offaxis.py (lump 4x / 20x stiffer, top 1 / 5 mm down, near face 0-15 mm
from the press axis or the press over its middle, nu 0.3 / 0.45, depths 1 / 3 / 5 mm), the force ratio with/without
the lump of the contact law as scenes use it and of the 3-D FE (same grid, so its discretisation error cancels),
and the law's error. The law's ring mixing was chosen on the nu 0.3 stiff-lump rows (benchmarks/fe_offaxis_mixing.py);
the nu 0.45 rows and the soft lumps (--soft: 4x and 20x softer, top 1 mm down, nu 0.45) are report-only.

Run: .venv/bin/python benchmarks/fe_offaxis.py [--quick] [--soft] [--save rows.json]
(--quick: part 1 at nu 0.3 only, part 2 two cases; --soft: part 2 on the soft lumps only, ~5 min;
--save: the rows for benchmarks/fe_offaxis_mixing.py)
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from palpate.core.world.scene import Material
from palpate.sim.hertz import sneddon_sphere_force_at_depth
from palpate.sim.reference.bonded_layer import dimitriadis_factor
from palpate.sim.reference.fe import fe_press
from palpate.sim.reference.fe3d import BoxBlock
from palpate.sim.reference.fe3d_solve import fe3d_press
from palpate.sim.reference.sample import AxisymmetricSample
from palpate.sim.validity.offaxis import BULK_E, DEPTHS, HALF, THICKNESS, TIP, H, compare, offaxis_cases, soft_cases


def _pct(values) -> str:
    return " ".join(f"{100 * v:+6.1f}" for v in np.atleast_1d(values))


def validate(quick: bool) -> None:
    print(f"Part 1: 3-D FE (h {1e3 * H:g} mm) on homogeneous blocks; error % at depths "
          f"{', '.join(f'{1e3 * d:g}' for d in DEPTHS)} mm")
    for nu in (0.3,) if quick else (0.3, 0.45):
        m = Material("bulk", BULK_E, nu)
        t0 = time.perf_counter()
        fe3 = fe3d_press(BoxBlock(m, THICKNESS, HALF, HALF), TIP, DEPTHS, h=H)
        ref = fe_press(AxisymmetricSample(m, THICKNESS), TIP, DEPTHS, refinement=1.0).force
        print(f"  20 mm block, nu {nu:g} ({fe3.dofs} dofs, {time.perf_counter() - t0:.0f} s): vs axisymmetric FE "
              f"{_pct(fe3.force / ref - 1)}")
    if not quick:
        m = Material("bulk", BULK_E, 0.3)
        fe3 = fe3d_press(BoxBlock(m, 0.06, 0.06, 0.06), TIP, DEPTHS, h=H, growth=1.5)  # coarser far field: 21k dofs
        exact = sneddon_sphere_force_at_depth(m.effective_modulus, TIP, DEPTHS) * dimitriadis_factor(
            np.sqrt(TIP * DEPTHS) / 0.06, m.poisson)
        print(f"  60 mm block, nu 0.3 ({fe3.dofs} dofs): vs Sneddon x bonded-layer factor "
              f"{_pct(fe3.force / exact - 1)}")


def table(cases) -> list:
    print("\nPart 2: force ratio with / without the lump (law: sim/contact object_law; FE: 3-D, same grid)")
    print(f"{'case':<38} {'law ratio':>21} {'3-D FE ratio':>21} {'law error %':>21}")
    cache: dict = {}
    rows = []
    for case in cases:
        row = compare(case, cache=cache)
        rows.append(row)
        print(f"{case.label:<38} {' '.join(f'{v:6.3f}' for v in row.law_ratio):>21} "
              f"{' '.join(f'{v:6.3f}' for v in row.fe_ratio):>21} {_pct(row.error):>21}", flush=True)
    err = np.array([r.error for r in rows])
    print(f"\nlaw error over {len(rows)} cases x {len(DEPTHS)} depths: median {100 * np.median(err):+.1f}%, "
          f"range {100 * err.min():+.1f}% to {100 * err.max():+.1f}%")
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a subset (under ~2 min)")
    parser.add_argument("--soft", action="store_true", help="part 2 on the report-only soft lumps only")
    parser.add_argument("--save", type=Path, help="write the rows as JSON (for benchmarks/fe_offaxis_mixing.py)")
    args = parser.parse_args()
    if args.soft:
        rows = table(soft_cases())
    else:
        validate(args.quick)
        rows = table(offaxis_cases(args.quick))
    if args.save:
        doc = [dict(contrast=r.case.contrast, top=r.case.top, near=r.case.near, poisson=r.case.poisson,
                    depth=r.depth.tolist(), law_ratio=r.law_ratio.tolist(), fe_ratio=r.fe_ratio.tolist())
               for r in rows]
        args.save.write_text(json.dumps({"rows": doc}, indent=1))


if __name__ == "__main__":
    main()
