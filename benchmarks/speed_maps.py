"""Map post-processing and batch updates against plain numpy references of the same arithmetic, timed in one run.

Run: .venv/bin/python benchmarks/speed_maps.py [--quick] [--repeats N]

1. Post-processing (seed 000 eq. 6.15) of a 1000 x 1000 x 3 map, 30% of the cells explored: ``Grid2D.postprocessed``
   against a plain row-blocked numpy version written below (materials-first planes, 64 rows per block). Both
   must give the same floats before anything is timed. Target: <= 60 ms.
2. Batch update of many cells (seed 001 eq. 2, clamped): ``Grid2D.update_cells`` against plain numpy over rows
   (``P[cells] = update(P[cells], p_meas)``, which holds only while no cell repeats), and against one
   ``update_cell`` call per measurement. Target: >= 4 M cell updates per second.
3. The voxel stages (seed 001 eq. 3 and 5, and the lateral eq. 6.15) for scale, without a reference.

The maps and measurements are random (Dirichlet), seeded; nothing here was tuned on them. The library and the
reference alternate within each repetition; medians of CPU time are reported (on a shared machine wall time
mostly measures the other processes), and the ratio of the medians.
"""

from __future__ import annotations

import argparse
import math
import statistics
import time

import numpy as np

from palpate.core.mapping.extrapolation import extrapolate_vertical, verify_continuity
from palpate.core.mapping.grids import Grid2D, VoxelGrid

POSTPROCESS_TARGET_MS = 60.0
UPDATE_TARGET_PER_S = 4e6


# ---- plain numpy references ---------------------------------------------------------------------------------------

def reference_postprocess(p: np.ndarray, explored: np.ndarray, base: float = 10.0, h_min: float = 1e-12,
                          block: int = 64) -> np.ndarray:
    """Eq. 6.15 (one pass): each unexplored cell with an explored 8-neighbour becomes the 1/H-weighted mean of its
    explored neighbours. Rows in blocks of ``block`` with one row of neighbours each side, materials-first."""
    ny, nx, m = p.shape
    out = p.copy()
    for r0 in range(0, ny, block):
        r1 = min(r0 + block, ny)
        lo, hi = max(r0 - 1, 0), min(r1 + 1, ny)
        planes = np.ascontiguousarray(np.moveaxis(p[lo:hi], -1, 0))  # (m, rows, nx)
        plogp = np.log(planes) * planes
        h = plogp[0] + plogp[1]
        for k in range(2, m):
            h += plogp[k]
        h = np.maximum(h * (-1.0 / math.log(base)), 0.0)
        w = np.where(explored[lo:hi], 1.0 / np.maximum(h, h_min), 0.0)
        # 3x3 sums with zeros off the grid: columns (centre + left + right), then rows (centre + up + down)
        padded = np.zeros((m + 1, hi - lo + 2, nx + 2))
        padded[:m, 1:-1, 1:-1] = w * planes
        padded[m, 1:-1, 1:-1] = w
        cols = padded[..., 1:-1] + padded[..., :-2] + padded[..., 2:]
        a, b = r0 - lo + 1, r1 - lo + 1
        sums = cols[:, a:b] + cols[:, a - 1:b - 1] + cols[:, a + 1:b + 1]
        fill = ~explored[r0:r1] & (sums[m] > 0)
        out[r0:r1][fill] = (sums[:m, fill] / sums[m, fill]).T
    return out


def reference_update(p: np.ndarray, cells: np.ndarray, meas: np.ndarray, p_min: float) -> None:
    """Recursive update of the rows ``cells`` (no repeats) of ``p`` (n_cells, M), in log space, clamped."""
    with np.errstate(divide="ignore"):
        logp = np.log(p[cells]) + np.log(meas)
    logp -= logp.max(axis=1, keepdims=True)
    logp -= np.log(np.exp(logp).sum(axis=1, keepdims=True))
    np.maximum(logp, math.log(p_min), out=logp)
    new = np.exp(logp)
    new /= new.sum(axis=1, keepdims=True)
    p[cells] = new


# ---- timing -----------------------------------------------------------------------------------------------------

def interleaved(fns: dict, repeats: int) -> dict[str, list[float]]:
    """CPU time of each function, s, the functions alternating within every repetition (and which goes first
    rotating, so neither always finds the other's data in the cache)."""
    out: dict[str, list[float]] = {name: [] for name in fns}
    names = list(fns)
    for k in range(repeats):
        for name in names[k % len(names):] + names[:k % len(names)]:
            t0 = time.process_time()
            fns[name]()
            out[name].append(time.process_time() - t0)
    return out


def random_map(rng: np.random.Generator, shape: tuple[int, ...], explored_fraction: float, m: int = 3):
    p = rng.dirichlet(np.full(m, 0.5), size=shape)
    explored = rng.random(shape) < explored_fraction
    p[~explored] = 1.0 / m  # unexplored cells are uniform, as on a map
    return p, explored


def grid_holding(p: np.ndarray, explored: np.ndarray) -> Grid2D:
    """A Grid2D in the given state (explored cells as given), without a million update calls."""
    ny, nx, m = p.shape
    return Grid2D([f"m{k}" for k in range(m)], (nx, ny))._with_arrays(p, explored)


def postprocessing(rng, n: int, repeats: int) -> None:
    p, explored = random_map(rng, (n, n), 0.3)
    grid = grid_holding(p, explored)
    if not np.array_equal(grid.postprocessed().probabilities, reference_postprocess(p, explored)):
        raise SystemExit("post-processing: the reference and palpate differ")
    t = interleaved({"palpate": grid.postprocessed, "reference": lambda: reference_postprocess(p, explored)},
                    repeats)
    lib, ref = statistics.median(t["palpate"]) * 1e3, statistics.median(t["reference"]) * 1e3
    print(f"1. Post-processing (eq. 6.15) of {n} x {n} x 3, 30% explored; median of {repeats}, same floats")
    print(f"   Grid2D.postprocessed       {lib:8.1f} ms   (target <= {POSTPROCESS_TARGET_MS:g} ms at 1000 x 1000: "
          f"{'met' if lib <= POSTPROCESS_TARGET_MS or n != 1000 else 'NOT met'})")
    print(f"   plain numpy, row-blocked   {ref:8.1f} ms")
    print(f"   ratio palpate / reference: {lib / ref:.2f}")


def batch_updates(rng, n: int, repeats: int) -> None:
    m, p_min = 3, 1e-6
    p0, _ = random_map(rng, (n, n), 1.0)
    cells_all = n * n
    meas = rng.dirichlet(np.full(m, 0.5), cells_all)
    print(f"\n2. Batch update of a {n} x {n} x 3 map (clamped recursive update); median of {repeats}")
    print(f"   {'measurements':<34}{'palpate':>12}{'plain numpy':>14}{'ratio':>8}   M cell updates/s (palpate)")
    orders = {"every cell once, raster order": np.arange(cells_all),
              "every cell once, random order": rng.permutation(cells_all)}
    for label, flat in orders.items():
        iy, ix = np.divmod(flat, n)
        grid = grid_holding(p0.copy(), np.zeros((n, n), bool))
        ref = p0.reshape(-1, m).copy()
        grid.update_cells(ix, iy, meas)
        reference_update(ref, flat, meas, p_min)
        if not np.array_equal(grid.probabilities.reshape(-1, m), ref):
            raise SystemExit(f"batch update ({label}): the reference and palpate differ")
        t = interleaved({"palpate": lambda g=grid, ix=ix, iy=iy: g.update_cells(ix, iy, meas),
                         "reference": lambda r=ref, flat=flat: reference_update(r, flat, meas, p_min)}, repeats)
        lib, rf = statistics.median(t["palpate"]), statistics.median(t["reference"])
        print(f"   {label:<34}{lib * 1e3:9.1f} ms{rf * 1e3:11.1f} ms{lib / rf:8.2f}   {len(flat) / lib / 1e6:6.1f}  "
              f"({'met' if len(flat) / lib >= UPDATE_TARGET_PER_S else 'NOT met'}: >= 4)")
    # Random cells with repeats: plain numpy over rows cannot do this (a repeated cell must get its measurements
    # one after another), so the comparison is one update_cell per measurement, on a slice.
    flat = rng.integers(0, cells_all, cells_all)
    iy, ix = np.divmod(flat, n)
    grid = grid_holding(p0.copy(), np.zeros((n, n), bool))
    t = interleaved({"palpate": lambda: grid.update_cells(ix, iy, meas)}, repeats)
    lib = statistics.median(t["palpate"])
    k = 20_000
    one = grid_holding(p0.copy(), np.zeros((n, n), bool))
    t0 = time.process_time()
    for i in range(k):
        one.update_cell(int(ix[i]), int(iy[i]), meas[i])
    per_cell = (time.process_time() - t0) / k
    repeats_share = 1.0 - len(np.unique(flat)) / len(flat)
    print(f"   {'random cells, ' + f'{repeats_share:.0%} repeats':<34}{lib * 1e3:9.1f} ms"
          f"{'-':>14}{'-':>8}   {len(flat) / lib / 1e6:6.1f}  "
          f"({'met' if len(flat) / lib >= UPDATE_TARGET_PER_S else 'NOT met'}: >= 4)")
    print(f"   one update_cell per measurement: {per_cell * 1e6:.1f} us each ({1 / per_cell / 1e6:.3f} M/s), "
          f"so the batch is {per_cell / (lib / len(flat)):.0f}x faster; it gives the same floats (tests)")


def voxels(rng, shape: tuple[int, int, int], repeats: int) -> None:
    pv, ev = random_map(rng, shape, 0.5)
    vg = VoxelGrid(["a", "b", "c"], shape)._with_arrays(pv, ev)
    t = interleaved({"extrapolate_vertical (eq. 3)": lambda: extrapolate_vertical(pv, ev),
                     "verify_continuity (eq. 5)": lambda: verify_continuity(pv, ev),
                     "VoxelGrid.postprocessed": vg.postprocessed,
                     "VoxelGrid.postprocessed(lateral)": lambda: vg.postprocessed(lateral=True)}, repeats)
    print(f"\n3. Voxel stages, {'x'.join(map(str, shape))} x 3, 50% explored; median of {repeats}")
    for name, ts in t.items():
        print(f"   {name:<34}{statistics.median(ts) * 1e3:9.1f} ms")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="300 x 300 maps, fewer repetitions (a smoke run)")
    ap.add_argument("--repeats", type=int, default=None, help="repetitions of every timing")
    args = ap.parse_args()
    n, repeats, vox = (300, 3, (60, 60, 20)) if args.quick else (1000, 9, (200, 200, 40))
    repeats = args.repeats or repeats
    rng = np.random.default_rng(20261122)
    postprocessing(rng, n, repeats)
    batch_updates(rng, n, repeats)
    voxels(rng, vox, repeats)


if __name__ == "__main__":
    main()
