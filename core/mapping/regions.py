"""Where each material lies on a map: its connected regions of points (2-D, 4-neighbour) or voxels (6-neighbour)
whose most probable material it is, each with its size, centroid and how sure the map is of it (a voxel region also
with the depths of its top and bottom). A buried lump or a band shows up as one region of its material; a run
reports them for the cell or voxel map and, at its finer resolution, for the fine map."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from palpate.core.errors import ValidationError

#: The most regions a summary lists (the largest): a noisy map's specks would otherwise fill it.
MAX_REGIONS = 20


@dataclass(frozen=True)
class MaterialRegion:
    """One connected region of a map's labels.

    Attributes:
        material: the material the map labels it with.
        points: how many map points (cells or fine points) it holds.
        area_m2: its area, m^2.
        centroid_m: (x, y) of its area's centre, m, in the map's (world) frame.
        probability: the mean probability the map gives its material over its points.
    """

    material: str
    points: int
    area_m2: float
    centroid_m: tuple[float, float]
    probability: float

    def to_dict(self) -> dict:
        """JSON-ready form (summary.json)."""
        return {"material": self.material, "points": self.points, "area_m2": self.area_m2,
                "centroid_m": list(self.centroid_m), "probability": self.probability}


def material_regions(probabilities: np.ndarray, origin: tuple[float, float], spacing: float,
                     materials: Sequence[str], known: np.ndarray | None = None,
                     min_points: int = 1) -> list[MaterialRegion]:
    """The connected regions of ``probabilities`` (ny, nx, M) on a raster whose point (0, 0) has its corner at
    ``origin`` (m) and whose points are ``spacing`` (m) squares; ``known`` (ny, nx) bool leaves the points outside
    the object out; regions of fewer than ``min_points`` points are left out. Largest first.

    Raises:
        ValidationError: shapes that disagree, a non-positive spacing or probabilities that are not finite.
    """
    from scipy import ndimage

    p = np.asarray(probabilities, dtype=float)
    if p.ndim != 3 or p.shape[-1] != len(materials) or not p.shape[0] * p.shape[1]:
        raise ValidationError(f"material_regions: probabilities must be (ny, nx, {len(materials)}), got {p.shape}")
    if not (np.isfinite(spacing) and spacing > 0) or not np.all(np.isfinite(p)):
        raise ValidationError("material_regions: the spacing must be > 0 m and the probabilities finite")
    inside = np.ones(p.shape[:2], dtype=bool) if known is None else np.asarray(known, dtype=bool)
    if inside.shape != p.shape[:2]:
        raise ValidationError(f"material_regions: known must be {p.shape[:2]}, got {inside.shape}")
    labels = np.argmax(p, axis=-1)
    ys, xs = np.indices(labels.shape)
    cx, cy = origin[0] + (xs + 0.5) * spacing, origin[1] + (ys + 0.5) * spacing
    out = []
    for m, name in enumerate(materials):
        parts, n = ndimage.label((labels == m) & inside)  # 4-neighbour: a diagonal touch is two regions
        if not n:
            continue
        index = np.arange(1, n + 1)
        count = ndimage.sum_labels(np.ones_like(cx), parts, index)
        mx, my = (ndimage.mean(c, parts, index) for c in (cx, cy))
        sure = ndimage.mean(p[..., m], parts, index)
        out += [MaterialRegion(name, int(k), float(k * spacing**2), (float(x), float(y)), float(s))
                for k, x, y, s in zip(count, mx, my, sure, strict=True) if k >= min_points]
    return sorted(out, key=lambda r: -r.points)


def region_report(probabilities: np.ndarray, origin: tuple[float, float], spacing: float, materials: Sequence[str],
                  cell: float | None = None) -> list[dict]:
    """summary.json's ``material_regions``: the largest :data:`MAX_REGIONS` regions of a map (see
    :func:`material_regions`); on a raster finer than the map's cells (``cell``, m) the specks under a quarter of
    a cell are the raster's, not the object's, and are left out."""
    quarter = 1 if cell is None else int(np.ceil((cell / spacing) ** 2 / 4))
    regions = material_regions(probabilities, origin, spacing, materials, min_points=quarter)
    return [r.to_dict() for r in regions[:MAX_REGIONS]]


@dataclass(frozen=True)
class VolumeRegion:
    """One connected region (6-neighbour) of a voxel map's labels: a lump, a layer, a column.

    Attributes:
        material: the material the map labels it with.
        voxels: how many voxels it holds.
        volume_m3: its volume, m^3.
        centroid_m: (x, y, z) of its volume's centre, m, in the map's (world) frame.
        top_depth_m, bottom_depth_m: the depth below the surface of its shallowest voxel's top and its deepest
            voxel's bottom, m.
        probability: the mean probability the map gives its material over its voxels.
    """

    material: str
    voxels: int
    volume_m3: float
    centroid_m: tuple[float, float, float]
    top_depth_m: float
    bottom_depth_m: float
    probability: float

    def to_dict(self) -> dict:
        """JSON-ready form (summary.json)."""
        return {"material": self.material, "voxels": self.voxels, "volume_m3": self.volume_m3,
                "centroid_m": list(self.centroid_m), "top_depth_m": self.top_depth_m,
                "bottom_depth_m": self.bottom_depth_m, "probability": self.probability}


def volume_regions(probabilities: np.ndarray, origin: tuple[float, float], z_top: float, spacing: float,
                   materials: Sequence[str]) -> list[VolumeRegion]:
    """The connected regions of a voxel map's ``probabilities`` (nx, ny, nz, M), indexed as
    :class:`palpate.core.mapping.grids.VoxelGrid` holds them (iz = 0 at the surface ``z_top``, m; voxel (0, 0) has
    its corner at ``origin``, m; cubes of ``spacing`` m). Voxels the map knows nothing of (a distribution exactly
    uniform: never pressed nor reached by post-processing) belong to no region. Largest first.

    Raises:
        ValidationError: shapes that disagree, a non-positive spacing or probabilities that are not finite.
    """
    from scipy import ndimage

    p = np.asarray(probabilities, dtype=float)
    if p.ndim != 4 or p.shape[-1] != len(materials) or not p[..., 0].size:
        raise ValidationError(f"volume_regions: probabilities must be (nx, ny, nz, {len(materials)}), got {p.shape}")
    if not (np.isfinite(spacing) and spacing > 0) or not np.all(np.isfinite(p)) or not np.isfinite(z_top):
        raise ValidationError("volume_regions: the spacing must be > 0 m, z_top and the probabilities finite")
    known = np.ptp(p, axis=-1) > 0.0
    labels = np.argmax(p, axis=-1)
    ix, iy, iz = np.indices(labels.shape)
    cx, cy = origin[0] + (ix + 0.5) * spacing, origin[1] + (iy + 0.5) * spacing
    cz = z_top - (iz + 0.5) * spacing
    out = []
    for m, name in enumerate(materials):
        parts, n = ndimage.label((labels == m) & known)  # faces only: an edge or corner touch is two regions
        if not n:
            continue
        index = np.arange(1, n + 1)
        count = ndimage.sum_labels(np.ones_like(cx), parts, index)
        mx, my, mz = (ndimage.mean(c, parts, index) for c in (cx, cy, cz))
        top = ndimage.minimum(iz, parts, index) * spacing
        bottom = (ndimage.maximum(iz, parts, index) + 1) * spacing
        sure = ndimage.mean(p[..., m], parts, index)
        rows = zip(count, mx, my, mz, top, bottom, sure, strict=True)
        out += [VolumeRegion(name, int(k), float(k * spacing**3), (float(x), float(y), float(z)), float(t), float(b),
                             float(s)) for k, x, y, z, t, b, s in rows]
    return sorted(out, key=lambda r: -r.voxels)


def volume_region_report(probabilities: np.ndarray, origin: tuple[float, float], z_top: float, spacing: float,
                         materials: Sequence[str]) -> list[dict]:
    """summary.json's ``material_regions`` of a voxel map: its largest :data:`MAX_REGIONS` regions (see
    :func:`volume_regions`)."""
    regions = volume_regions(probabilities, origin, z_top, spacing, materials)
    return [r.to_dict() for r in regions[:MAX_REGIONS]]


def map_region_report(geometry, probabilities: np.ndarray) -> list[dict]:
    """summary.json's ``material_regions`` of a cell or voxel map (``geometry``: its
    :class:`palpate.core.mapping.geometry.MapGeometry`; ``probabilities`` as the map holds them)."""
    if geometry.voxel:
        return volume_region_report(probabilities, geometry.origin, geometry.z_top, geometry.cell_size,
                                    geometry.materials)
    return region_report(probabilities, geometry.origin, geometry.cell_size, geometry.materials)
