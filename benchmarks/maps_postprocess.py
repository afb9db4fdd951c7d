"""Speed and memory of palpate.core.mapping.grids: post-processing large maps and single-cell updates.

Prints a table. Run: .venv/bin/python benchmarks/maps_postprocess.py [--quick] [--repeats N]
"""

from __future__ import annotations

import argparse
import tracemalloc

import numpy as np
from bench_timing import median_of

from palpate.core.mapping import grids as maps


def _median_time(fn, repeats: int) -> float:
    return median_of(fn, repeats)[0]


def _peak_bytes(fn) -> int:
    tracemalloc.start()
    tracemalloc.reset_peak()
    fn()
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return peak


def _random_map(rng: np.random.Generator, shape: tuple[int, ...], m: int, explored_fraction: float):
    p = rng.dirichlet(np.full(m, 0.5), size=shape)
    explored = rng.random(shape) < explored_fraction
    p[~explored] = 1.0 / m
    return p, explored


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smaller grids and fewer repeats (CI smoke run)")
    parser.add_argument("--repeats", type=int, default=None, help="runs per timing (median reported)")
    args = parser.parse_args()
    repeats = args.repeats or (3 if args.quick else 5)
    n2d = 300 if args.quick else 1000
    vox = (60, 60, 20) if args.quick else (200, 200, 40)
    m = 3
    rng = np.random.default_rng(20261122)
    rows: list[tuple[str, str, float, str, float]] = []

    p2, e2 = _random_map(rng, (n2d, n2d), m, 0.3)
    rows.append((
        "extrapolate_unexplored (eq. 6.15)", f"{n2d}x{n2d}x{m}, 30% explored",
        _median_time(lambda: maps.extrapolate_unexplored(p2, e2), repeats), "s",
        _peak_bytes(lambda: maps.extrapolate_unexplored(p2, e2)) / 2**20,
    ))
    grid = maps.Grid2D([f"m{i}" for i in range(m)], (n2d, n2d))
    grid._p, grid._explored = p2, e2  # benchmark only: load a prepared state without n2d^2 updates
    rows.append((
        "Grid2D.postprocessed", f"{n2d}x{n2d}x{m}",
        _median_time(grid.postprocessed, repeats), "s", _peak_bytes(grid.postprocessed) / 2**20,
    ))

    n_updates = 2000 if args.quick else 20000
    cells = rng.integers(0, n2d, size=(n_updates, 2))
    meas = rng.dirichlet(np.ones(m), size=n_updates)

    def single_updates() -> None:
        for (ix, iy), z in zip(cells, meas, strict=True):
            grid.update_cell(int(ix), int(iy), z)

    t = _median_time(single_updates, repeats)
    rows.append(("Grid2D.update_cell (one press)", f"{n_updates} calls", t / n_updates * 1e6, "us/call", 0.0))

    prior = rng.dirichlet(np.ones(m), size=(n2d, n2d))
    z = rng.dirichlet(np.ones(m), size=(n2d, n2d))
    t = _median_time(lambda: maps.update(prior, z), repeats)
    rows.append(("update, vectorised", f"{n2d}x{n2d}x{m}", t / (n2d * n2d) * 1e9, "ns/cell",
                 _peak_bytes(lambda: maps.update(prior, z)) / 2**20))

    pv, ev = _random_map(rng, vox, m, 0.5)
    label = "x".join(map(str, vox)) + f"x{m}, 50% explored"
    rows.append(("extrapolate_vertical (eq. 3)", label,
                 _median_time(lambda: maps.extrapolate_vertical(pv, ev), repeats), "s",
                 _peak_bytes(lambda: maps.extrapolate_vertical(pv, ev)) / 2**20))
    rows.append(("verify_continuity (eq. 5)", label,
                 _median_time(lambda: maps.verify_continuity(pv, ev), repeats), "s",
                 _peak_bytes(lambda: maps.verify_continuity(pv, ev)) / 2**20))
    vg = maps.VoxelGrid([f"m{i}" for i in range(m)], vox)
    vg._p, vg._explored = pv, ev
    rows.append(("VoxelGrid.postprocessed", label, _median_time(vg.postprocessed, repeats), "s",
                 _peak_bytes(vg.postprocessed) / 2**20))
    rows.append(("VoxelGrid.postprocessed(lateral)", label,
                 _median_time(lambda: vg.postprocessed(lateral=True), repeats), "s",
                 _peak_bytes(lambda: vg.postprocessed(lateral=True)) / 2**20))

    print(f"palpate maps benchmark (median of {repeats} runs; peak = tracemalloc peak of one run, MiB; "
          f"input arrays excluded)")
    head = f"{'operation':<36} {'size':<28} {'time':>12} {'unit':<8} {'peak MiB':>9}"
    print(head)
    print("-" * len(head))
    for name, size, value, unit, peak in rows:
        peak_s = f"{peak:9.1f}" if peak else f"{'-':>9}"
        print(f"{name:<36} {size:<28} {value:12.4g} {unit:<8} {peak_s}")


if __name__ == "__main__":
    main()
