"""Where each material lies on a 2-D map: its connected regions (4-neighbour) of points whose most probable material
it is, each with its area, centroid and how sure the map is of it. A buried lump or a band shows up as one region of
its material; a run reports them for the cell map and, at its finer resolution, for the fine map."""

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
