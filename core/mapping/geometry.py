"""Where a map lies: its kind, origin, cell size and shape (:class:`MapGeometry`), cell centres, and the checks
every map's geometry goes through.

Conventions (SI): ``origin`` is the (x, y) corner with the smallest coordinates, m; a 2-D grid's shape is (nx, ny)
and its arrays are indexed [iy, ix] like images; a voxel grid's shape is (nx, ny, nz) below ``z_top`` (m), indexed
[ix, iy, iz] with iz = 0 at the surface.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from palpate.core import limits
from palpate.core.errors import ValidationError
from palpate.core.files import brief
from palpate.core.mapping.probability import check_base

MAP_KINDS = ("grid2d", "voxel")


def check_materials(materials) -> list[str]:
    if isinstance(materials, str):
        raise ValidationError("materials must be a list of names, not a single string")
    names = list(materials)
    if len(names) < 2:
        raise ValidationError(f"a map needs at least 2 materials, got {brief(names)}")
    if not all(isinstance(n, str) and n for n in names):
        raise ValidationError(f"materials must be non-empty strings, got {brief(names)}")
    if len(set(names)) != len(names):
        raise ValidationError(f"materials must be unique, got {brief(names)}")
    return names


def check_positive(value, name: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValidationError(f"{name} must be a number > 0, got {brief(value)}") from None
    if not (np.isfinite(v) and v > 0):
        raise ValidationError(f"{name} must be a finite number > 0, got {brief(value)}")
    return v


def check_finite_tuple(value, n: int, name: str) -> tuple[float, ...]:
    try:
        arr = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise ValidationError(f"{name} must be {n} numbers, got {brief(value)}") from None
    if arr.shape != (n,) or not np.all(np.isfinite(arr)):
        raise ValidationError(f"{name} must be {n} finite numbers, got {brief(value)}")
    return tuple(float(v) for v in arr)


def check_shape(shape, n: int, name: str) -> tuple[int, ...]:
    try:
        vals = tuple(shape)
    except TypeError:
        raise ValidationError(f"{name} must be {n} positive integers, got {brief(shape)}") from None
    if len(vals) != n or not all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) and v > 0
                                 for v in vals):
        raise ValidationError(f"{name} must be {n} positive integers, got {brief(shape)}")
    return tuple(int(v) for v in vals)


def index_along(coord: float, start: float, cell: float, n: int, axis: str) -> int:
    """Cell index containing ``coord`` on one axis; the far edge belongs to the last cell."""
    if not math.isfinite(coord):
        raise ValidationError(f"{axis} must be finite, got {coord!r}")
    end = start + n * cell
    # A small tolerance so that a point on the far edge (or a rounding hair outside) maps to the last cell.
    tol = 1e-9 * cell
    if coord < start - tol or coord > end + tol:
        raise ValidationError(f"{axis} = {coord!r} m is outside the map [{start!r}, {end!r}] m")
    return int(min(max(math.floor((coord - start) / cell), 0), n - 1))


def cell_centres(origin: tuple[float, float], cell_size: float, nx: int, ny: int) -> np.ndarray:
    """Centres of a grid's cells, shape (ny, nx, 2) holding (x, y), m (indexed like a 2-D map's arrays)."""
    xs = origin[0] + (np.arange(nx) + 0.5) * cell_size
    ys = origin[1] + (np.arange(ny) + 0.5) * cell_size
    gx, gy = np.meshgrid(xs, ys)
    return np.stack([gx, gy], axis=-1)


@dataclass(frozen=True)
class MapGeometry:
    """Everything needed to build an object's empty map (and to rebuild it from a recording).

    Attributes:
        kind: "grid2d" or "voxel".
        materials: the reference materials, in the haptic memory's order.
        origin: (x0, y0), m.
        cell_size: cell (voxel) side, m.
        shape: (nx, ny) for a 2-D grid, (nx, ny, nz) for voxels.
        entropy_base: logarithm base of the map's entropies.
        z_top: surface height of a voxel map, m (None for 2-D maps).
    """

    kind: str
    materials: tuple[str, ...]
    origin: tuple[float, float]
    cell_size: float
    shape: tuple[int, ...]
    entropy_base: float = 10.0
    z_top: float | None = None

    def __post_init__(self) -> None:
        if self.kind not in MAP_KINDS:
            raise ValidationError(f"map kind must be one of {MAP_KINDS}, got {self.kind!r}")
        object.__setattr__(self, "materials", tuple(check_materials(self.materials)))
        object.__setattr__(self, "origin", check_finite_tuple(self.origin, 2, "origin"))
        object.__setattr__(self, "cell_size", check_positive(self.cell_size, "cell_size"))
        what = "shape (nx, ny, nz)" if self.kind == "voxel" else "shape (nx, ny)"
        object.__setattr__(self, "shape", check_shape(self.shape, 3 if self.kind == "voxel" else 2, what))
        limits.check("map_cells", f"a map of shape {list(self.shape)}: its cell count", math.prod(self.shape))
        limits.check("materials", "a map's materials", len(self.materials))
        object.__setattr__(self, "entropy_base", check_base(self.entropy_base))
        if self.kind == "voxel":
            if self.z_top is None:
                raise ValidationError("a voxel map needs z_top (the surface height, m)")
            object.__setattr__(self, "z_top", check_finite_tuple((self.z_top,), 1, "z_top")[0])
        elif self.z_top is not None:
            raise ValidationError("z_top applies to voxel maps only")

    @property
    def voxel(self) -> bool:
        """True for a volumetric map."""
        return self.kind == "voxel"

    @property
    def plane_shape(self) -> tuple[int, int]:
        """(nx, ny) of the columns a press chooses among."""
        return int(self.shape[0]), int(self.shape[1])

    def plane(self) -> MapGeometry:
        """The 2-D map of the plane's cells: a voxel map's surface layer (a 2-D map is its own plane)."""
        if not self.voxel:
            return self
        return MapGeometry("grid2d", self.materials, self.origin, self.cell_size, self.plane_shape,
                           self.entropy_base)

    def cell_centres(self) -> np.ndarray:
        """Centres of the plane's cells, (ny, nx, 2) holding (x, y), m."""
        nx, ny = self.plane_shape
        return cell_centres(self.origin, self.cell_size, nx, ny)

    def cells_at(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(ix, iy) of the plane cells holding the points ``xy`` (..., 2), m; points off the plane take the nearest
        cell on its rim."""
        nx, ny = self.plane_shape
        ix = np.clip(np.floor((xy[..., 0] - self.origin[0]) / self.cell_size).astype(int), 0, nx - 1)
        iy = np.clip(np.floor((xy[..., 1] - self.origin[1]) / self.cell_size).astype(int), 0, ny - 1)
        return ix, iy

    def to_dict(self) -> dict:
        """JSON-ready form, as recordings store it (keys carry their unit)."""
        out = {"map": self.kind, "origin_m": list(self.origin), "cell_size_m": self.cell_size,
               "shape": list(self.shape), "entropy_base": self.entropy_base, "materials": list(self.materials)}
        if self.z_top is not None:
            out["z_top_m"] = self.z_top
        return out

    @classmethod
    def from_dict(cls, doc, source: str = "<map geometry>") -> MapGeometry:
        """Inverse of :meth:`to_dict`; ValidationError naming ``source`` and the key for anything wrong."""
        if not isinstance(doc, dict):
            raise ValidationError(f"{source}: a map geometry must be an object, got {type(doc).__name__}")
        for key in ("map", "origin_m", "cell_size_m", "shape", "materials"):
            if key not in doc:
                raise ValidationError(f"{source}: map geometry lacks key {key!r}")
        try:
            return cls(kind=doc["map"], materials=tuple(doc["materials"]), origin=tuple(doc["origin_m"]),
                       cell_size=doc["cell_size_m"], shape=tuple(doc["shape"]),
                       entropy_base=doc.get("entropy_base", 10.0), z_top=doc.get("z_top_m"))
        except (TypeError, ValueError) as exc:
            raise ValidationError(f"{source}: malformed map geometry: {exc}") from None


def plane_probabilities(probabilities: np.ndarray) -> np.ndarray:
    """A map's probabilities on its plane, (ny, nx, M) indexed [iy, ix] as a 2-D map's: a voxel map's
    (nx, ny, nz, M) surface layer (iz = 0), a 2-D map's as they are."""
    p = np.asarray(probabilities)
    return np.transpose(p[:, :, 0], (1, 0, 2)) if p.ndim == 4 else p
