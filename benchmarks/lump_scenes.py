"""Seeded scenes of lumps at depth, for measuring how well a map finds what lies under the surface.

Each scene is a block of one material (the shape families' generator, benchmarks/scene_families.py, paints the
surface; here it is plain) with 1-3 buried lumps of other materials, each

==============  ===============================================================================================
shape           a box (sides 1-2.5 cells, 5-20 mm tall) or a sphere (radius 0.5-1.2 cells)
top             0.5-6 mm under the surface (a press goes 4 mm deep)
material        another of the scene's 2-3 reference materials (harder or softer than the block), sometimes a
                like-material 0.8-1.25x the reference's modulus
==============  ===============================================================================================

kept a cell apart from each other and at least half a cell inside the map. Cell size, grid and offset are drawn as
the shape families draw them. Seeds split as theirs: below 100000 tuning, from 100000 on report only.

Run: .venv/bin/python benchmarks/lump_scenes.py [--seed 100000]   (prints the scene)
"""

from __future__ import annotations

import argparse
import math
from concurrent.futures import ProcessPoolExecutor

import numpy as np
from scene_families import HEIGHT_MM, PX_MM, REFERENCES, FamilyScene, slot_materials

#: Depth of a lump's top under the surface, mm (drawn uniformly).
TOP_MM = (0.5, 6.0)


def lump_top_mm(lump: dict) -> float:
    """Depth of a lump's top under the surface, mm."""
    cz = lump["center_mm"][2]
    half = lump["size_mm"][0] if lump["shape"] == "sphere" else lump["size_mm"][2] / 2
    return HEIGHT_MM - (cz + half)


def lump_footprint(lump: dict, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Mask of the points (x, y mm) over the lump's widest horizontal section."""
    cx, cy, _ = lump["center_mm"]
    if lump["shape"] == "sphere":
        return np.hypot(x - cx, y - cy) <= lump["size_mm"][0]
    sx, sy, _ = lump["size_mm"]
    return (np.abs(x - cx) <= sx / 2) & (np.abs(y - cy) <= sy / 2)


def footprint_gap_mm(lump: dict, x: float, y: float) -> float:
    """Distance (mm) from the point (x, y mm) to the lump's widest horizontal section (0 over it)."""
    cx, cy, _ = lump["center_mm"]
    if lump["shape"] == "sphere":
        return max(math.hypot(x - cx, y - cy) - lump["size_mm"][0], 0.0)
    sx, sy, _ = lump["size_mm"]
    return math.hypot(max(abs(x - cx) - sx / 2, 0.0), max(abs(y - cy) - sy / 2, 0.0))


def footprint_area_mm2(lump: dict) -> float:
    """Area of the lump's widest horizontal section, mm^2."""
    if lump["shape"] == "sphere":
        return math.pi * lump["size_mm"][0] ** 2
    return lump["size_mm"][0] * lump["size_mm"][1]


def scene_arguments(doc: str) -> argparse.Namespace:
    """The command line of a benchmark over seeded lump scenes: --first (default the first report seed), --scenes,
    --jobs (scenes run in that many processes)."""
    parser = argparse.ArgumentParser(description=doc.splitlines()[0])
    parser.add_argument("--first", type=int, default=100000)
    parser.add_argument("--scenes", type=int, default=24)
    parser.add_argument("--jobs", type=int, default=1, help="scenes run in this many processes")
    return parser.parse_args()


def scene_results(scene_row, args: argparse.Namespace):
    """``scene_row(seed)`` of each seed of ``args`` (:func:`scene_arguments`) in seed order, as they finish."""
    with ProcessPoolExecutor(args.jobs) as pool:
        yield from pool.map(scene_row, range(args.first, args.first + args.scenes))


def lump_read(lump: dict | None) -> tuple[str, float, float] | None:
    """A spot's lump as summary.json gives it, as the ``read`` entry :func:`lump_read_line` takes: (material, top mm,
    its spread mm), or None."""
    return None if lump is None else (lump["material"], lump["top_m"] * 1e3, lump["top_sd_m"] * 1e3)


def lump_read_line(lumps: list[dict]) -> str | None:
    """The summary of the lumps read from spots' presses: per lump dicts with ``spotted``, ``material``, ``top``
    (mm) and ``read`` ((material, top mm, its spread mm) or None); None when none was read."""
    read = [lu for lu in lumps if lu["read"] is not None]
    if not read:
        return None
    err = np.array([lu["read"][1] - lu["top"] for lu in read])
    spread = np.array([lu["read"][2] for lu in read])
    return (f"lumps read from a spot's press: {len(read)} of {sum(lu['spotted'] for lu in lumps)} spotted; material "
            f"right {sum(lu['read'][0] == lu['material'] for lu in read)}; top depth error (read - true) median "
            f"{np.median(err):+.2f} mm, |error| median {np.median(np.abs(err)):.2f} mm, within 1 / 2 mm "
            f"{np.mean(np.abs(err) <= 1):.0%} / {np.mean(np.abs(err) <= 2):.0%}, within 1 / 2 of its spreads "
            f"{np.mean(np.abs(err) <= spread):.0%} / {np.mean(np.abs(err) <= 2 * spread):.0%} (median spread "
            f"{np.median(spread):.2f} mm)")


def make_lump_scene(seed: int) -> FamilyScene:
    """The seeded lump scene of ``seed`` (family "lumps")."""
    rng = np.random.default_rng([seed, 21])
    c = float(rng.uniform(10.0, 20.0))
    nx, ny = int(rng.integers(6, 12)), int(rng.integers(5, 10))
    off = rng.uniform(0.1, 0.9, 2) * c
    sx = off[0] + nx * c + rng.uniform(0.1, 0.9) * c
    sy = off[1] + ny * c + rng.uniform(0.1, 0.9) * c
    k = int(rng.choice([2, 3, 3]))
    refs = sorted(rng.choice(len(REFERENCES), k, replace=False).tolist())
    materials = slot_materials(rng, refs, rng.permutation(k))
    lumps: list[dict] = []
    boxes: list[tuple[float, float, float, float]] = []  # footprints' bounds, for keeping lumps apart
    for _ in range(int(rng.integers(1, 4))):
        for _try in range(50):
            if rng.random() < 0.5:
                w, h = (float(v) for v in rng.uniform(1.0, 2.5, 2) * c)
                size = [round(w, 2), round(h, 2), round(float(rng.uniform(5.0, 20.0)), 2)]
                half_x, half_y, half_z = w / 2, h / 2, size[2] / 2
            else:
                r = float(rng.uniform(0.5, 1.2) * c)
                size = [round(r, 2)]
                half_x = half_y = half_z = r
            x = float(rng.uniform(off[0] + c / 2 + half_x, off[0] + nx * c - c / 2 - half_x)) if \
                nx * c - c > 2 * half_x else None
            y = float(rng.uniform(off[1] + c / 2 + half_y, off[1] + ny * c - c / 2 - half_y)) if \
                ny * c - c > 2 * half_y else None
            if x is None or y is None:
                continue
            bounds = (x - half_x, x + half_x, y - half_y, y + half_y)
            if any(b[0] - c < bounds[1] and bounds[0] < b[1] + c and b[2] - c < bounds[3] and bounds[2] < b[3] + c
                   for b in boxes):
                continue
            top = float(rng.uniform(*TOP_MM))
            cz = HEIGHT_MM - top - half_z
            slot = int(rng.integers(1, k))
            lumps.append({"material": materials[slot][0], "shape": "sphere" if len(size) == 1 else "box",
                          "center_mm": [round(x, 3), round(y, 3), round(cz, 3)], "size_mm": size})
            boxes.append(bounds)
            break
    references = tuple(r[0] for r in REFERENCES if r[0] in {m[1] for m in materials})
    npx, npy = int(math.ceil(sx / PX_MM)), int(math.ceil(sy / PX_MM))
    return FamilyScene(seed, "lumps", c, (float(sx), float(sy)), (float(off[0]), float(off[1])), (nx, ny),
                       tuple(materials), references, np.zeros((npy, npx), dtype=np.int16), lumps=tuple(lumps))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=100000)
    args = parser.parse_args()
    fs = make_lump_scene(args.seed)
    print(f"seed {fs.seed}: block {fs.size_mm[0]:.0f} x {fs.size_mm[1]:.0f} mm of {fs.materials[0][0]}, "
          f"{fs.grid_cells[0]} x {fs.grid_cells[1]} cells of {fs.cell_mm:.1f} mm")
    for lump in fs.lumps:
        print(f"  {lump['shape']:6} of {lump['material']:12} at ({lump['center_mm'][0]:.1f}, "
              f"{lump['center_mm'][1]:.1f}) mm, top {lump_top_mm(lump):.1f} mm down, size {lump['size_mm']} mm")


if __name__ == "__main__":
    main()
