"""The per-press boundary reading against the 3-D FE image reference: every wall and block case's FE image as 8-bit
counts (default taxel model, seeded noise), read with the shipped boundary templates, and scored per split and
depth: the harder side named, the wall's position and angle, the offset's calibration, p_boundary.

Run: .venv/bin/python benchmarks/boundary_reading.py [--seeds 8] [--templates FILE] [--model-error 0.25]
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from palpate.core.boundary.templates import read_templates
from palpate.core.session.boundaries import noise_of, shipped_templates
from palpate.core.world.scene import TaxelSensorSpec
from palpate.sim.validity.boundary_reading import check_readings
from palpate.sim.validity.image_reference import load_image_reference


def table(rows, title: str) -> None:
    print(f"\n{title}")
    print(f"{'split':7} {'depth':>5} {'walls':>5} {'side':>6} {'pos med':>7} {'pos p90':>7} {'ang med':>7} "
          f"{'|z|<1':>6} {'|z|<2':>6} {'p_b wall':>8} {'p_b far':>7} {'p_b block':>9}")
    for split in ("tuning", "report"):
        for depth in sorted({r.depth for r in rows}):
            sel = [r for r in rows if r.split == split and r.depth == depth]
            walls = [r for r in sel if r.family == "wall" and abs(r.offset) <= 0.005]
            far = [r for r in sel if r.family == "wall" and abs(r.offset) > 0.005]
            blocks = [r for r in sel if r.family == "block"]
            if not walls:
                continue
            pos = np.array([r.position_error for r in walls]) * 1e3
            z = np.array([(r.read_offset - r.offset) / max(r.offset_sd, 1e-9) for r in walls if r.side_right])
            ang = np.degrees([r.angle_error for r in walls])
            pb = lambda rs: f"{np.mean([r.p_boundary for r in rs]):.2f}" if rs else "-"  # noqa: E731
            print(f"{split:7} {depth * 1e3:5.1f} {len(walls):5d} {np.mean([r.side_right for r in walls]):6.0%} "
                  f"{np.median(pos):7.2f} {np.percentile(pos, 90):7.2f} {np.median(ang):7.1f} "
                  f"{np.mean(np.abs(z) < 1):6.0%} {np.mean(np.abs(z) < 2):6.0%} {pb(walls):>8} {pb(far):>7} "
                  f"{pb(blocks):>9}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=8)
    parser.add_argument("--templates", type=Path)
    parser.add_argument("--model-error", type=float)
    parser.add_argument("--cases", action="store_true", help="also print each wall case at 4 mm")
    args = parser.parse_args()
    templates = read_templates(args.templates) if args.templates else shipped_templates()
    spec = TaxelSensorSpec()
    noise = noise_of(spec) if args.model_error is None else noise_of(spec, model_error=args.model_error)
    rows = check_readings(load_image_reference(), templates, seeds=range(args.seeds), spec=spec, noise=noise)
    print(f"noise {noise.noise:.2f} counts, floor {noise.floor:g}, model error {noise.model_error:g}; "
          f"{args.seeds} noise seeds; walls within 5 mm of the axis (pos: mm, ang: deg)")
    table(rows, "boundary reading against the 3-D FE")
    if args.cases:
        for r in rows:
            if r.depth == 0.004 and r.seed == 0:
                print(f"{r.case:42} {r.split:6} side {'ok ' if r.side_right else 'BAD'} pos "
                      f"{r.position_error * 1e3:6.2f} mm  offset {r.read_offset * 1e3:+5.2f}+-{r.offset_sd * 1e3:.2f} "
                      f"ang {math.degrees(r.angle_error):5.1f} p_b {r.p_boundary:.2f} c {r.read_contrast:g}")


if __name__ == "__main__":
    main()
