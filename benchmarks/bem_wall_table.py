"""Measure the ``bem`` rung's wall table on the 3-D FE (sim/bem/wall_measure.py) and print how lambda, the soft
material's share in the coupling of two surface points beside a wall, depends on contrast and Poisson ratio.

Each (Poisson ratio, contrast) is one full 3-D FE of a 30 mm block split by a wall (plus one of the soft block per
Poisson ratio), a few minutes each on one core; results are kept in --cache so an interrupted run resumes.

Run: .venv/bin/python benchmarks/bem_wall_table.py [--write] [--poisson 0.3,0.45,0.49] [--contrast 2,5.75,20]
[--h 0.0005]
(--write: replace models/bem_wall_table.json)
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from palpate.sim.bem.wall import TABLE_PATH, WallTable
from palpate.sim.bem.wall_measure import measure_share, surface_response, wall_block


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--poisson", default="0.3,0.45,0.49")
    parser.add_argument("--contrast", default="2,5.75,20")
    parser.add_argument("--h", type=float, default=0.5e-3, help="FE node spacing over the window, m")
    parser.add_argument("--cache", type=Path, default=Path.home() / ".cache" / "palpate" / "bem_wall")
    parser.add_argument("--write", action="store_true", help="replace models/bem_wall_table.json")
    args = parser.parse_args()
    poissons = [float(v) for v in args.poisson.split(",")]
    contrasts = [float(v) for v in args.contrast.split(",")]
    args.cache.mkdir(parents=True, exist_ok=True)
    shares = np.zeros((len(poissons), len(contrasts)), dtype=object)
    for p, nu in enumerate(poissons):
        soft_file = args.cache / f"soft_nu{nu:g}_h{args.h:g}.npz"
        if soft_file.exists():
            soft = dict(np.load(soft_file))
        else:
            soft = surface_response(wall_block(nu, 1.0), 9e-3, args.h)
            np.savez(soft_file, **soft)
        for c, contrast in enumerate(contrasts):
            f = args.cache / f"share_nu{nu:g}_c{contrast:g}_h{args.h:g}.npz"
            if f.exists():
                z = np.load(f)
                offsets, along, share = z["offsets"], z["along"], z["share"]
            else:
                t0 = time.perf_counter()
                offsets, along, share, _ = measure_share(nu, contrast, h=args.h, soft=soft)
                np.savez(f, offsets=offsets, along=along, share=share)
                print(f"  nu {nu:g} contrast {contrast:g}: {time.perf_counter() - t0:.0f} s", flush=True)
            shares[p, c] = share
    cube = np.stack([np.stack(list(row)) for row in shares])
    n = len(offsets) // 2
    print("lambda on the line through both points (v = 0), pairs a node apart and across the wall:")
    print(f"{'nu':>5} {'contrast':>8} {'soft 1-3 mm':>12} {'stiff 1-3 mm':>12} {'soft 1-9':>9} {'stiff 1-9':>9} "
          f"{'-3 | +3':>8} {'-9 | +9':>8}")
    for p, nu in enumerate(poissons):
        for c, contrast in enumerate(contrasts):
            s = cube[p, c, :, :, 0]
            at = {mm: n + int(round(mm * 1e-3 / args.h)) for mm in (-3, -1, 1, 3)}
            print(f"{nu:5.2f} {contrast:8g} {s[at[-1], at[-3]]:12.3f} {s[at[1], at[3]]:12.3f} {s[at[-1], 0]:9.3f} "
                  f"{s[at[1], -1]:9.3f} {s[at[-3], at[3]]:8.3f} {s[0, -1]:8.3f}")
    if args.write:
        table = WallTable(offsets=offsets, along=along, poisson=np.array(poissons), contrast=np.array(contrasts),
                          share=cube, thickness=0.03)
        import json

        TABLE_PATH.write_text(json.dumps(table.to_dict({
            "how": "benchmarks/bem_wall_table.py --write (palpate.sim.bem.wall_measure.measure_share)",
            "fe": "3-D FE, trilinear bricks, selective reduced integration, 30 x 80 x 80 mm block, bonded base",
            "h": args.h})))
        print(f"wrote {TABLE_PATH}")


if __name__ == "__main__":
    main()
