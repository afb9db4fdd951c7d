"""What a fine map can reach after a share of raster's presses, with perfect readings and a clairvoyant planner: a
reference for the target "the fine map's boundary error after a tenth of raster's presses no larger than the cell
grid's after a full raster".

On each shape-family scene (benchmarks/scene_families.py) the oracle knows the truth. Each press reads perfectly
within ``--reach`` of its axis (every point there labelled right, as a perfect boundary reading would); a point out
of every press's reach takes the true material at its nearest press (what an ideal extrapolation from the presses
could say without seeing it). The presses are the better of two sets: greedy on the truth (one at a time where it
adds the most area right, anywhere on a lattice of a third of a cell) and an even lattice of as many presses (greedy
alone can stall: a press inside a ring takes the ring's surroundings with it). Against it, the cell grid after a
full raster at its best: every cell labelled with the true material at its centre (a raster's press lands there).
Both are scored as the share of the map's area labelled wrong (the symmetric difference of the label maps with the
truth), on a raster of ``--res`` mm.

Greedy is not optimal, so "oracle" is a strong reference, not a bound; real readings are not perfect within reach
(one press locates a wall to 0.2-1 mm) and the map's own extrapolation is the seed's eq. 6.15, not the nearest press.

Run: .venv/bin/python benchmarks/fine_budget_bound.py [--first 100000] [--scenes 24] [--shares 0.1,0.25]
"""

from __future__ import annotations

import argparse
import math

import numpy as np
from scene_families import PX_MM, REFERENCES, is_report_seed, make_scene

#: A perfect reading's reach, mm (a wall farther than this from the axis is not read: docs/boundaries.md).
REACH_MM = 5.5


def truth_raster(fs, res_mm: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(xs, ys, truth): the map's raster of ``res_mm`` points over its cells and the reference index at each (-1 off
    the block)."""
    (ox, oy), (nx, ny), c = fs.grid_origin_mm, fs.grid_cells, fs.cell_mm
    xs = ox + (np.arange(int(round(nx * c / res_mm))) + 0.5) * res_mm
    ys = oy + (np.arange(int(round(ny * c / res_mm))) + 0.5) * res_mm
    return xs, ys, label_at(fs, *np.meshgrid(xs, ys))


def label_at(fs, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Reference index (in REFERENCES order) of the scene's material at points (mm); -1 off the block."""
    ref_of_slot = np.array([[r[0] for r in REFERENCES].index(m[1]) for m in fs.materials])
    ix, iy = np.floor(x / PX_MM).astype(int), np.floor(y / PX_MM).astype(int)
    inside = (ix >= 0) & (iy >= 0) & (ix < fs.labels.shape[1]) & (iy < fs.labels.shape[0])
    out = np.full(x.shape, -1)
    out[inside] = ref_of_slot[fs.labels[iy[inside], ix[inside]]]
    return out


def cell_grid_wrong(fs, xs: np.ndarray, ys: np.ndarray, truth: np.ndarray) -> float:
    """Share of the known area the cell grid labels wrong when each cell holds the true material at its centre."""
    (ox, oy), c = fs.grid_origin_mm, fs.cell_mm
    cx, cy = np.floor((xs - ox) / c).astype(int), np.floor((ys - oy) / c).astype(int)
    centre = label_at(fs, *np.meshgrid(ox + (np.arange(fs.grid_cells[0]) + 0.5) * c,
                                       oy + (np.arange(fs.grid_cells[1]) + 0.5) * c))
    labels = centre[cy[:, None], cx[None, :]]
    known = truth >= 0
    return float(np.mean(labels[known] != truth[known]))


def oracle_wrong(fs, xs: np.ndarray, ys: np.ndarray, truth: np.ndarray, presses: int, reach: float) -> float:
    """Share of the known area the oracle fine map labels wrong after ``presses`` presses (the better set)."""
    gx, gy = np.meshgrid(xs, ys)
    pts = np.stack([gx[truth >= 0], gy[truth >= 0]], axis=-1)
    true = truth[truth >= 0]
    return min(_greedy_wrong(fs, pts, true, presses, reach), _lattice_wrong(fs, pts, true, presses, reach))


def _wrong(fs, pts: np.ndarray, true: np.ndarray, at: np.ndarray, reach: float) -> float:
    """Share of ``pts`` the oracle labels wrong with presses ``at`` (K, 2), mm."""
    d2 = np.sum((pts[:, None, :] - at[None, :, :]) ** 2, axis=-1)
    near = np.argmin(d2, axis=1)
    right = (d2[np.arange(len(pts)), near] <= reach**2) | (label_at(fs, at[:, 0], at[:, 1])[near] == true)
    return float(1.0 - right.mean())


def _lattice_wrong(fs, pts: np.ndarray, true: np.ndarray, presses: int, reach: float) -> float:
    """The oracle on the even lattice of at most ``presses`` points over the map (its shape closest to the map's)."""
    (ox, oy), (nx, ny), c = fs.grid_origin_mm, fs.grid_cells, fs.cell_mm
    w, h = nx * c, ny * c
    best = None
    for kx in range(1, presses + 1):
        ky = max(1, presses // kx)
        if best is None or abs(math.log((w / kx) / (h / ky))) < best[0]:
            best = (abs(math.log((w / kx) / (h / ky))), kx, ky)
    _, kx, ky = best
    at = np.stack([a.ravel() for a in np.meshgrid(ox + (np.arange(kx) + 0.5) * w / kx,
                                                  oy + (np.arange(ky) + 0.5) * h / ky)], axis=-1)
    return _wrong(fs, pts, true, at, reach)


def _greedy_wrong(fs, pts: np.ndarray, true: np.ndarray, presses: int, reach: float) -> float:
    """The oracle after ``presses`` greedy presses."""
    (ox, oy), (nx, ny), c = fs.grid_origin_mm, fs.grid_cells, fs.cell_mm
    step = c / 3
    cxs = ox + (np.arange(int(nx * c / step)) + 0.5) * step
    cys = oy + (np.arange(int(ny * c / step)) + 0.5) * step
    cand = np.stack([a.ravel() for a in np.meshgrid(cxs, cys)], axis=-1)
    cand_label = label_at(fs, cand[:, 0], cand[:, 1])
    keep = cand_label >= 0
    cand, cand_label = cand[keep], cand_label[keep]
    nearest = np.full(len(pts), np.inf)  # squared distance to the nearest press
    label = np.full(len(pts), -1)  # the nearest press's material
    right_now = np.zeros(len(pts), dtype=bool)
    for _ in range(presses):
        best, best_gain = -1, -1
        for chunk in np.array_split(np.arange(len(cand)), max(1, len(cand) * len(pts) // 4_000_000)):
            d2 = np.sum((pts[None, :, :] - cand[chunk, None, :]) ** 2, axis=-1)  # (C, P)
            closer = d2 < nearest[None, :]
            new_label = np.where(closer, cand_label[chunk, None], label[None, :])
            new_near = np.minimum(d2, nearest[None, :])
            right = (new_near <= reach**2) | (new_label == true[None, :])
            gain = right.sum(axis=1)
            k = int(np.argmax(gain))
            if gain[k] > best_gain:
                best, best_gain = int(chunk[k]), int(gain[k])
        d2 = np.sum((pts - cand[best]) ** 2, axis=-1)
        closer = d2 < nearest
        label = np.where(closer, cand_label[best], label)
        nearest = np.minimum(d2, nearest)
        right_now = (nearest <= reach**2) | (label == true)
    return float(1.0 - right_now.mean())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--first", type=int, default=100000)
    parser.add_argument("--scenes", type=int, default=24)
    parser.add_argument("--shares", default="0.1,0.25", help="shares of raster's presses (one per cell)")
    parser.add_argument("--reach", type=float, default=REACH_MM, help="a perfect reading's reach, mm")
    parser.add_argument("--res", type=float, default=1.0, help="scoring raster, mm")
    args = parser.parse_args()
    shares = [float(s) for s in args.shares.split(",")]
    print(f"{'seed':>7} {'split':6} {'family':10} {'cells':>5} {'cell grid':>9} "
          + " ".join(f"{'oracle ' + format(s, 'g'):>11}" for s in shares))
    print("(share of the area labelled wrong: the cell grid after a full raster at its best; the oracle fine map after "
          "that share of raster's presses)")
    rows = []
    for seed in range(args.first, args.first + args.scenes):
        fs = make_scene(seed)
        xs, ys, truth = truth_raster(fs, args.res)
        n_cells = fs.grid_cells[0] * fs.grid_cells[1]
        grid = cell_grid_wrong(fs, xs, ys, truth)
        oracle = [oracle_wrong(fs, xs, ys, truth, max(1, math.ceil(s * n_cells)), args.reach) for s in shares]
        rows.append((grid, oracle))
        print(f"{seed:7d} {'report' if is_report_seed(seed) else 'tuning':6} {fs.family:10} {n_cells:5d} {grid:9.1%} "
              + " ".join(f"{o:11.1%}" for o in oracle), flush=True)
    grid = np.array([r[0] for r in rows])
    for k, s in enumerate(shares):
        o = np.array([r[1][k] for r in rows])
        print(f"share {s:g}: oracle no worse than the cell grid on {int(np.sum(o <= grid))} of {len(rows)} scenes; "
              f"median wrong {np.median(o):.1%} against the cell grid's {np.median(grid):.1%}")


if __name__ == "__main__":
    main()
