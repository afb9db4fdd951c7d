"""The buried lumps a run read, written into a fine volume under a voxel map's surface.

A voxel map labels 5 mm voxels from presses that feel a column as a whole, so a lump under one material rarely
becomes a region of its own. The fine map of the surface (:mod:`palpate.core.mapping.fine`) finds such a lump as a
stiffness spot (:mod:`palpate.core.mapping.anomalies`), and its strongest press reads the lump's material and how
deep its top lies (:mod:`palpate.core.boundary.lump_depth`). The lump layer puts the two together on a raster of
``resolution`` cubes under the fine map:

- laterally, the lump lies under the spot's presses (the points within half a cell of one of them): the press
  reads the lump's size no better than a guess (size trades against depth), but which presses felt it says where;
- in depth, a point at depth z lies in the lump with the probability that the top lies above it, Phi((z - top) /
  top_sd); nothing in one press says where the lump ends, so it reaches the layer's bottom;
- a point in the lump holds the read material with the reading's ``p_material``; the rest of its probability, and
  every point outside a lump, keep the fine map's distribution of the surface above them (a wall read at the
  surface is taken to reach down, as the voxel map takes it).

The seed's voxel map is left as it is; the layer is written beside it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import ndtr

from palpate.core.errors import ValidationError
from palpate.core.mapping.fine import FineMap


@dataclass(frozen=True)
class LumpLayer:
    """Material probabilities in cubes under a fine map.

    Attributes:
        origin: (x0, y0) of the raster's corner, m (the fine map's).
        z_top: the surface's height, m; layer iz spans depths iz * resolution to (iz + 1) * resolution below it.
        resolution: side of one cube, m.
        probabilities: (nx, ny, nz, M), indexed as a voxel map's (iz = 0 at the surface).
        materials: their names.
        lumps: how many read lumps the layer holds.
        footprint: (nx, ny) the columns a read lump reaches (under its spot's presses).
    """

    origin: tuple[float, float]
    z_top: float
    resolution: float
    probabilities: np.ndarray
    materials: tuple[str, ...]
    lumps: int
    footprint: np.ndarray

    def centres(self) -> np.ndarray:
        """(nx, ny, nz, 3) cube centres (x, y, z), m."""
        nx, ny, nz = self.probabilities.shape[:3]
        ix, iy, iz = np.indices((nx, ny, nz))
        return np.stack([self.origin[0] + (ix + 0.5) * self.resolution, self.origin[1] + (iy + 0.5) * self.resolution,
                         self.z_top - (iz + 0.5) * self.resolution], axis=-1)


def layer_depths(depth: float, resolution: float) -> int:
    """How many cubes of ``resolution`` m a layer ``depth`` m deep holds (at least one)."""
    return max(1, int(round(depth / resolution)))


def voxels_on_layer(layer: LumpLayer, origin: tuple[float, float], cell: float, voxels: np.ndarray) -> np.ndarray:
    """A voxel map's per-voxel values, (nx, ny, nz, ...) of ``cell`` m cubes from ``origin`` down from the layer's
    surface, at each of the layer's cubes (the voxel holding its centre; the deepest where the layer reaches below)."""
    c = layer.centres()
    shape = voxels.shape[:3]
    ix, iy = (np.clip(((c[..., k] - origin[k]) // cell).astype(int), 0, shape[k] - 1) for k in (0, 1))
    iz = np.clip(((layer.z_top - c[..., 2]) // cell).astype(int), 0, shape[2] - 1)
    return voxels[ix, iy, iz]


def lump_layer(fine: FineMap, z_top: float, depth: float, cell: float, spots: list[dict]) -> LumpLayer:
    """The lump layer of a voxel map (see the module docstring).

    Args:
        fine: the fine map of the voxel map's surface layer.
        z_top: the surface's height, m.
        depth: how deep the layer reaches, m (the voxel map's depth; whole cubes of ``fine.resolution``).
        cell: the voxel map's cell side, m: a spot's press covers the points within half of it.
        spots: summary.json's ``stiffness_anomalies`` of the fine map, each with ``press_locations_m`` (the spot's
            presses, m) and ``lump`` (a read lump: ``material``, ``top_m``, ``top_sd_m``, ``p_material``; or None:
            such a spot adds nothing).

    Raises:
        ValidationError: a depth or cell that is not a positive finite length, or a spot's lump with a material the
            fine map does not know or a top, spread or probability that is not finite and in range.
    """
    res = float(fine.resolution)
    if not (np.isfinite(depth) and depth > 0 and np.isfinite(cell) and cell > 0 and np.isfinite(z_top)):
        raise ValidationError(f"lump_layer: depth and cell must be finite lengths > 0 m and z_top finite, got depth "
                              f"{depth!r}, cell {cell!r}, z_top {z_top!r}")
    nz = layer_depths(depth, res)
    column = np.transpose(np.asarray(fine.probabilities, dtype=float), (1, 0, 2))  # (nx, ny, M)
    nx, ny, m = column.shape
    probs = np.repeat(column[:, :, None, :], nz, axis=2)
    centres = np.transpose(fine.centres(), (1, 0, 2))  # (nx, ny, 2)
    z = (np.arange(nz) + 0.5) * res
    lumps = 0
    footprint = np.zeros((nx, ny), dtype=bool)
    for spot in spots:
        lump = spot.get("lump")
        if not lump:
            continue
        k, top, sd, p = _checked(lump, fine.materials)
        where = np.asarray(spot.get("press_locations_m") or [spot["centroid_m"]], dtype=float).reshape(-1, 2)
        gap = np.abs(centres[:, :, None, :] - where[None, None, :, :]).max(axis=-1)  # (nx, ny, presses), m
        under = (gap <= cell / 2).any(axis=-1)
        if not under.any():
            continue
        lumps += 1
        footprint |= under
        inside = p * ndtr((z - top) / sd)  # (nz,)
        q = inside[None, :, None]
        block = probs[under] * (1.0 - q)
        block[..., k] += q[..., 0]
        probs[under] = block
    return LumpLayer((float(fine.origin[0]), float(fine.origin[1])), float(z_top), res, probs,
                     tuple(fine.materials), lumps, footprint)


def _checked(lump: dict, materials) -> tuple[int, float, float, float]:
    """(material index, top m, spread m, p_material) of a read lump, validated."""
    try:
        k = list(materials).index(lump["material"])
        top, sd, p = float(lump["top_m"]), float(lump["top_sd_m"]), float(lump["p_material"])
    except (KeyError, TypeError, ValueError):
        raise ValidationError(f"lump_layer: a spot's lump must name one of {list(materials)} with top_m, top_sd_m "
                              f"and p_material, got {lump!r}") from None
    if not (np.isfinite(top) and top >= 0 and np.isfinite(sd) and sd > 0 and 0 <= p <= 1):
        raise ValidationError(f"lump_layer: a lump's top must be >= 0 m, its spread > 0 m and p_material in [0, 1], "
                              f"got {top!r}, {sd!r}, {p!r}")
    return k, top, sd, p
