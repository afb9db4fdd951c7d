"""Choosing the map's wall and press reliability: calibration of raster's physics maps under each candidate pair.

MapCalibration.wall_reliability (core/mapping/calibration.py, wall_tempered) lowers a pressed cell's certainty
where a pressed edge-neighbour reads otherwise, at post-processing time. Raster's presses do not depend on the map,
so one simulated run per scene (analytic fidelity, every cell pressed once, as benchmarks/exploration_families.py
--physics) serves every candidate: its maps are rebuilt at 20/35/50/100% of the cells pressed and post-processed
with each (the presses' posteriors fused again with each press reliability), and the ECE of the most probable
material, its accuracy and mean confidence are printed, overall and for the cells with a wall within a press's
reach (a neighbour sharing an edge holds another true material) and the others. The pooled ECE can hide a wall
cell that is sure and wrong behind a clear cell that is right and unsure in the same bin; the "grouped" ECE, the
two groups' ECEs weighted by their cells, cannot, and is what the setting is chosen on.

Choose on tuning seeds (--split tuning), report on the report seeds once chosen.

Run: .venv/bin/python benchmarks/exploration_wall_sweep.py [--split tuning|report] [--physics K]
     [--wall 1,0.8,0.6] [--press 0.94,0.98] [--first N]
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from family_runs import CALIBRATION_AT, checkpoint_maps, physics_explore, postprocess  # noqa: E402
from scene_families import REPORT_SEEDS, TUNING_SEEDS, scene  # noqa: E402

from palpate.core.mapping.accuracy import decided_labels  # noqa: E402
from palpate.core.mapping.calibration import reliability_table  # noqa: E402
from palpate.core.mapping.neighbourhood import shift_slices  # noqa: E402


def near_wall(truth: np.ndarray) -> np.ndarray:
    """(ny, nx) cells with an edge-neighbour of another true material."""
    ny, nx = truth.shape
    out = np.zeros(truth.shape, dtype=bool)
    for dy, dx in ((0, 1), (1, 0)):
        a, b = shift_slices(dy, dx, ny, nx)
        differ = (truth[a] != truth[b]) & (truth[a] >= 0) & (truth[b] >= 0)
        out[a] |= differ
        out[b] |= differ
    return out


def scene_samples(fs, pairs: list[tuple[float, float]]) -> dict:
    """Per (press, wall) reliability: (confidence, right, near a wall) of the decided cells with a truth at every
    checkpoint."""
    res, cal = physics_explore(fs, "raster")
    truth = np.asarray(res.truth)
    wall = near_wall(truth)
    checkpoints = {max(1, int(round(f * truth.size))) for f in CALIBRATION_AT}
    out: dict = {pair: [] for pair in pairs}
    for press in sorted({p for p, _ in pairs}):
        fused = dataclasses.replace(cal, press_reliability=press)
        for _, grid in checkpoint_maps(res, fused, checkpoints):
            for pair in (q for q in pairs if q[0] == press):
                p = np.asarray(postprocess(grid, dataclasses.replace(fused, wall_reliability=pair[1])).probabilities)
                label, decided = decided_labels(p)
                keep = decided & (truth >= 0)
                out[pair].append((p.max(axis=-1)[keep], (label == truth)[keep], wall[keep]))
    return out


def numbers(parser: argparse.ArgumentParser, text: str, flag: str) -> list[float]:
    """Comma-separated numbers in (0, 1]; anything else is a usage error."""
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        parser.error(f"{flag} takes numbers, got {text!r}")
    if not all(0 < v <= 1 for v in values):
        parser.error(f"{flag} values must lie in (0, 1]")
    return values


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--split", default="tuning", choices=("tuning", "report"))
    parser.add_argument("--physics", type=int, default=12, help="scenes (default 12)")
    parser.add_argument("--first", type=int, default=None, help="first seed (default: the split's first)")
    parser.add_argument("--wall", default="1,0.9,0.8,0.7,0.6,0.5",
                        help="wall reliabilities to compare, comma-separated, each in (0, 1]")
    parser.add_argument("--press", default="0.94",
                        help="press reliabilities to compare, comma-separated, each in (0, 1]")
    args = parser.parse_args()
    pairs = [(p, w) for p in numbers(parser, args.press, "--press") for w in numbers(parser, args.wall, "--wall")]
    seeds = TUNING_SEEDS if args.split == "tuning" else REPORT_SEEDS
    first = seeds[0] if args.first is None else args.first
    if first not in seeds:
        parser.error(f"--first {first} is not a {args.split} seed")
    t0 = time.perf_counter()
    pooled: dict = {pair: [] for pair in pairs}
    for s in range(first, first + args.physics):
        for pair, parts in scene_samples(scene(s), pairs).items():
            pooled[pair] += parts
        print(f"seed {s} done ({time.perf_counter() - t0:.0f} s)", flush=True)
    print(f"\n{args.split} seeds {first}-{first + args.physics - 1}, raster, physics (analytic), checkpoints "
          f"{CALIBRATION_AT}: grouped ECE; ECE / accuracy / mean confidence (cells) of all cells, of those with a "
          "wall at an edge, of the others")
    best = None
    for pair in pairs:
        conf = np.concatenate([c for c, _, _ in pooled[pair]])
        right = np.concatenate([r for _, r, _ in pooled[pair]])
        wall = np.concatenate([w for _, _, w in pooled[pair]])
        line = ""
        grouped = 0.0
        for name, sel in (("all", np.ones(conf.size, bool)), ("wall", wall), ("clear", ~wall)):
            t = reliability_table(conf[sel], right[sel])
            grouped += 0.0 if name == "all" else t.ece * t.cells / max(conf.size, 1)
            line += (f"  {name} {t.ece:.4f} / {np.mean(right[sel]):.3f} / {np.mean(conf[sel]):.3f}"
                     f" ({t.cells})")
        print(f"press {pair[0]:<5g} wall {pair[1]:<5g} grouped {grouped:.4f} " + line)
        best = min(best or (grouped, pair), (grouped, pair))
    print(f"lowest grouped ECE {best[0]:.4f}: press_reliability {best[1][0]:g}, wall_reliability {best[1][1]:g}")
    print(f"\ntotal {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
