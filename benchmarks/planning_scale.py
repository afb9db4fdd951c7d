"""Planning at scale: one info_gain choice among 10^4 to 10^6 cells, rescoring only what a press changed.

Per map size: a scene of blobs of three materials, its stride-3 lattice pressed (info_gain's start) plus 1% of the
cells at random, then PRESSES more presses chosen by info_gain, each followed by the map update and the run's
post-processing. Timed per choice (median, and the worst after the first): info_gain rescoring only around each
press (the default), info_gain scoring every cell (the full computation), and a raster choice on the same map as
the plain reference (it checks every column's entropy). Both info_gain variants see the same maps, and the table
says whether every choice was the same. Goals: <= 20 ms among 10^4 cells, <= 0.5 s among 10^6.

Run: .venv/bin/python benchmarks/planning_scale.py [--sizes 100,316,1000] [--presses 12] [--full-up-to 316]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from palpate.core.mapping.grids import Grid2D
from palpate.core.perception.memory import HapticMemory
from palpate.core.planning.info_gain import InfoGain
from palpate.core.planning.outcomes import outcome_posteriors
from palpate.core.planning.policies import Raster

MATERIALS = ["soft", "medium", "hard"]


def synthetic_memory() -> HapticMemory:
    """A memory over three materials whose presses overlap a little (no physics needed to time planning)."""
    rng = np.random.default_rng(11)
    mus = np.array([[100.0, 1.0, 20.0, 0.5], [160.0, 1.4, 26.0, 0.7], [900.0, 3.0, 60.0, 1.5]])
    x = np.vstack([mu * (1 + 0.15 * rng.standard_normal((12, 4))) for mu in mus])
    return HapticMemory(MATERIALS).fit(x, [m for m in MATERIALS for _ in range(12)])


def scene_truth(n: int, seed: int = 5) -> np.ndarray:
    """(n, n) material per cell: soft background, blobs of the other two of 3-30 cells across."""
    rng = np.random.default_rng(seed)
    iy, ix = np.mgrid[0:n, 0:n]
    truth = np.zeros((n, n), dtype=int)
    for _ in range(max(3, n * n // 400)):
        cx, cy, r = rng.uniform(0, n), rng.uniform(0, n), rng.uniform(1.5, 15)
        truth[(ix - cx) ** 2 + (iy - cy) ** 2 <= r * r] = int(rng.integers(1, 3))
    return truth


def start_map(truth: np.ndarray, answers: np.ndarray, rng) -> Grid2D:
    n = truth.shape[0]
    grid = Grid2D(MATERIALS, (n, n), cell_size=0.01)
    lat = np.zeros_like(truth, dtype=bool)
    lat[(n - 1) % 3 // 2::3, (n - 1) % 3 // 2::3] = True
    lat |= rng.random(truth.shape) < 0.01
    for iy, ix in np.argwhere(lat):
        grid.update_cell(int(ix), int(iy), answers[truth[iy, ix], rng.integers(answers.shape[1])])
    return grid


def timed(fn):
    t0 = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t0


def run_size(n: int, presses: int, memory, answers, full: bool) -> dict:
    rng = np.random.default_rng(n)
    truth = scene_truth(n)
    grid = start_map(truth, answers, rng)
    fast = InfoGain(memory)
    slow = InfoGain(memory, incremental=False) if full else None
    post, t_post0 = timed(grid.postprocessed)
    _, t_first = timed(lambda: fast.next_target(grid, post))  # builds the kept scores: a full scoring
    t_fast, t_slow, t_raster, t_post, same = [], [], [], [t_post0], True
    for _ in range(presses):
        target, dt = timed(lambda p=post: fast.next_target(grid, p))
        t_fast.append(dt)
        if slow is not None:
            other, dt = timed(lambda p=post: slow.next_target(grid, p))
            t_slow.append(dt)
            same &= (other.ix, other.iy) == (target.ix, target.iy)
        _, dt = timed(lambda p=post: Raster().next_target(grid, p))
        t_raster.append(dt)
        grid.update_cell(target.ix, target.iy, answers[truth[target.iy, target.ix], rng.integers(answers.shape[1])])
        post, dt = timed(grid.postprocessed)
        t_post.append(dt)
    return {"cells": n * n, "first_s": t_first, "fast_s": float(np.median(t_fast)), "fast_max_s": float(max(t_fast)),
            "full_s": float(np.median(t_slow)) if t_slow else None, "raster_s": float(np.median(t_raster)),
            "post_s": float(np.median(t_post)), "same": same if slow is not None else None,
            "rescored": fast._cache.rescored_cells if fast._cache else 0}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="100,316,1000", help="map sides in cells (comma-separated)")
    parser.add_argument("--presses", type=int, default=12, help="timed choices per size")
    parser.add_argument("--full-up-to", type=int, default=316,
                        help="also time the full computation (and compare choices) up to this side")
    args = parser.parse_args()
    memory = synthetic_memory()
    answers = outcome_posteriors(memory, 40, seed=3)
    print(f"{'cells':>9} {'info_gain ms':>13} {'worst ms':>9} {'full ms':>9} {'raster ms':>10} {'ratio':>7} "
          f"{'full/raster':>12} {'post ms':>8} {'first ms':>9} {'same choices':>13}")
    for side in (int(v) for v in args.sizes.split(",")):
        r = run_size(side, args.presses, memory, answers, side <= args.full_up_to)
        full = "-" if r["full_s"] is None else f"{r['full_s'] * 1e3:9.1f}"
        full_ratio = "-" if r["full_s"] is None else f"{r['full_s'] / r['raster_s']:12.1f}"
        print(f"{r['cells']:>9} {r['fast_s'] * 1e3:13.2f} {r['fast_max_s'] * 1e3:9.1f} {full:>9} "
              f"{r['raster_s'] * 1e3:10.2f} {r['fast_s'] / r['raster_s']:7.1f} {full_ratio:>12} "
              f"{r['post_s'] * 1e3:8.1f} {r['first_s'] * 1e3:9.0f} {str(r['same']):>13}", flush=True)
    print("info_gain ms: median time of one choice after a press (rescoring around it); worst: the slowest of them;"
          " full: scoring every cell; ratio: info_gain / raster choice on the same map; post: the run's"
          " post-processing of the map per press (not part of a choice); first: the first choice (scores every"
          " cell once). Goals: <= 20 ms at 10^4 cells, <= 500 ms at 10^6.")


if __name__ == "__main__":
    main()
