"""Probabilistic material maps: a categorical distribution over the reference materials per 2-D cell or voxel.

:class:`Grid2D` and :class:`VoxelGrid` hold the arrays and their geometry; the array kernels they use live in
:mod:`~palpate.core.mapping.probability` (update, entropy) and :mod:`~palpate.core.mapping.extrapolation`
(post-processing), the file format in :mod:`~palpate.core.mapping.map_files`.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.mapping.calibration import wall_tempered
from palpate.core.mapping.categorical_map import CategoricalMap, cell_indices
from palpate.core.mapping.extrapolation import (
    check_certainty,
    check_passes,
    extrapolate_passes,
    extrapolate_plane,
    extrapolate_vertical_kernel,
    inverse_entropy,
    verify_continuity_kernel,
    vertical_gaps,
)
from palpate.core.mapping.geometry import (
    MapGeometry,
    cell_centres,
    check_finite_tuple,
    check_materials,
    check_positive,
    check_shape,
    index_along,
)
from palpate.core.mapping.map_files import common_meta, construct, meta_value, read_map_files
from palpate.core.mapping.probability import (
    check_h_min,
)


class Grid2D(CategoricalMap):
    """A 2-D probabilistic material map over the workspace plane (seed 000 §6.6-6.7).

    Geometry: ``origin`` = (x0, y0) is the corner of the grid with the smallest x and y; cell (ix, iy) covers
    x in [x0 + ix c, x0 + (ix+1) c) and y in [y0 + iy c, y0 + (iy+1) c), c = ``cell_size``; the far edge belongs
    to the last cell. Arrays are indexed like images, rows along y: ``probabilities[iy, ix, m]``,
    ``explored[iy, ix]``; every method taking indices takes them as (ix, iy), 0-based.

    Seed 000 Table 6.8 lists cells as 1-based (column, row) pairs on a 1 cm grid, e.g. (20, 8). The seed cell
    (c, r) is ``cell_centre(c - 1, r - 1)``, i.e. x = x0 + (c - 0.5) * 0.01 m, y = y0 + (r - 0.5) * 0.01 m.

    Args:
        materials: names of the M >= 2 reference materials (the haptic memory's order).
        shape: (nx, ny) number of cells along x and y.
        origin: (x0, y0), m.
        cell_size: cell side, m (1 cm as in seed 000).
        p_min: clamping floor of :func:`update`.
        base: entropy base (10, as the seeds).
    """

    _kind = "grid2d"
    _axes = "probabilities[iy, ix, m]"

    def __init__(self, materials, shape, origin=(0.0, 0.0), cell_size: float = 0.01, p_min: float = 1e-6,
                 base: float = 10.0):
        nx, ny = check_shape(shape, 2, "shape (nx, ny)")
        self.origin = check_finite_tuple(origin, 2, "origin (x0, y0)")
        self.cell_size = check_positive(cell_size, "cell_size")
        super().__init__(materials, (ny, nx), p_min, base)

    @classmethod
    def from_extent(cls, materials, x_range, y_range, cell_size: float = 0.01, **kwargs) -> Grid2D:
        """A grid covering [xmin, xmax] x [ymin, ymax] (m), rounded up to whole cells."""
        xmin, xmax = check_finite_tuple(x_range, 2, "x_range")
        ymin, ymax = check_finite_tuple(y_range, 2, "y_range")
        c = check_positive(cell_size, "cell_size")
        if not (xmax > xmin and ymax > ymin):
            raise ValidationError(f"extent must have xmax > xmin and ymax > ymin, got {x_range}, {y_range}")
        nx = max(1, math.ceil((xmax - xmin) / c - 1e-9))
        ny = max(1, math.ceil((ymax - ymin) / c - 1e-9))
        return cls(materials, (nx, ny), origin=(xmin, ymin), cell_size=c, **kwargs)

    @property
    def shape(self) -> tuple[int, int]:
        """(nx, ny)."""
        ny, nx = self._explored.shape
        return nx, ny

    def cell_of(self, x: float, y: float) -> tuple[int, int]:
        """(ix, iy) of the cell containing the point (x, y), m; ValidationError outside the grid."""
        nx, ny = self.shape
        return (index_along(x, self.origin[0], self.cell_size, nx, "x"),
                index_along(y, self.origin[1], self.cell_size, ny, "y"))

    def cell_centre(self, ix: int, iy: int) -> tuple[float, float]:
        """(x, y) of the centre of cell (ix, iy), 0-based, m. Seed cell (c, r) (1-based) is (c - 1, r - 1)."""
        ix, iy = self._check_cell(ix, iy)
        return (self.origin[0] + (ix + 0.5) * self.cell_size, self.origin[1] + (iy + 0.5) * self.cell_size)

    def cell_centres(self) -> np.ndarray:
        """Centres of all cells, shape (ny, nx, 2) holding (x, y), m (same indexing as ``probabilities``)."""
        nx, ny = self.shape
        return cell_centres(self.origin, self.cell_size, nx, ny)

    def _check_cell(self, ix, iy) -> tuple[int, int]:
        nx, ny = self.shape
        if not (isinstance(ix, (int, np.integer)) and isinstance(iy, (int, np.integer))):
            raise ValidationError(f"cell indices must be integers, got ({ix!r}, {iy!r})")
        if not (0 <= ix < nx and 0 <= iy < ny):
            raise ValidationError(f"cell ({ix}, {iy}) is outside the grid of (nx, ny) = ({nx}, {ny})")
        return int(ix), int(iy)

    def update_cell(self, ix: int, iy: int, p_meas) -> None:
        """Fuse one measurement (shape (M,)) into cell (ix, iy) with :func:`update` and mark it explored."""
        ix, iy = self._check_cell(ix, iy)
        self._check_meas(p_meas)
        self._update_at((iy, ix), p_meas)

    def update_cells(self, ix, iy, p_meas) -> None:
        """Fuse many measurements at once: ``p_meas[i]`` (shape (n, M)) into cell (ix[i], iy[i]), in order.

        The result is exactly that of ``update_cell`` called for each i in turn (a cell listed twice receives both
        measurements, one after the other), vectorised. Nothing is changed when an argument is invalid.
        """
        nx, ny = self.shape
        ix, iy = cell_indices({"ix": ix, "iy": iy}, (nx, ny))
        self._update_many((iy, ix), p_meas)

    def update(self, x: float, y: float, p_meas) -> tuple[int, int]:
        """Fuse one press at (x, y), m, into the cell containing it; returns that cell's (ix, iy)."""
        ix, iy = self.cell_of(x, y)
        self._check_meas(p_meas)
        self._update_at((iy, ix), p_meas)
        return ix, iy

    def _check_meas(self, p_meas) -> None:
        shape = np.shape(p_meas)
        if shape != (len(self.materials),):
            raise ValidationError(f"p_meas must have shape ({len(self.materials)},) (one value per material "
                                  f"{self.materials}), got {shape}")

    def postprocessed(self, h_min: float = 1e-12, passes: int | None = 1, certainty: float = 1.0,
                      wall_reliability: float = 1.0) -> Grid2D:
        """A new grid with unexplored cells extrapolated by :func:`extrapolate_unexplored`; self is untouched.

        First, pressed cells beside a pressed cell that reads otherwise are made less certain by
        :func:`~palpate.core.mapping.calibration.wall_tempered` with ``wall_reliability`` (1 = the seed: no
        change). ``passes`` repeats eq. 6.15 from the cells filled by the previous pass (1 = the seed; None =
        until every cell is filled); each pass keeps ``certainty`` of its estimate and spreads the rest uniformly
        (1 = the seed). The explored mask is copied unchanged: extrapolated cells are estimates, not measurements.
        """
        h_min = check_h_min(h_min)
        src = wall_tempered(self._p, self._explored, wall_reliability)
        p = extrapolate_passes(src, self._explored, None, check_passes(passes), self.base, h_min,
                               check_certainty(certainty))
        return self._like(p)

    def _empty_like(self) -> Grid2D:
        return Grid2D(self.materials, self.shape, origin=self.origin, cell_size=self.cell_size, p_min=self.p_min,
                      base=self.base)

    @classmethod
    def load(cls, path) -> Grid2D:
        """Read a map written by :meth:`save`, validating both files; errors name the file and key."""
        meta, p, explored = read_map_files(path, cls._kind)
        sidecar = Path(path).with_suffix(".json")
        nx, ny = meta_value(meta, "shape", sidecar, lambda v: check_shape(v, 2, "shape (nx, ny)"))
        if p.shape[:-1] != (ny, nx):
            raise ValidationError(f"{path}: 'probabilities' shape {p.shape} does not match {sidecar} shape "
                                  f"(nx, ny) = ({nx}, {ny}) (arrays are [iy, ix, m])")
        grid = construct(sidecar, lambda: cls(
            meta_value(meta, "materials", sidecar, check_materials), (nx, ny), **common_meta(meta, sidecar)))
        return grid._with_arrays(p, explored)


class VoxelGrid(CategoricalMap):
    """A volumetric probabilistic material map below a surface (seed 001).

    Geometry: ``origin`` = (x0, y0) is the corner with the smallest x and y, ``z_top`` the surface height (m);
    voxel (ix, iy, iz) covers x in [x0 + ix c, x0 + (ix+1) c), y likewise, and depth below the surface in
    [iz c, (iz+1) c), i.e. z in (z_top - (iz+1) c, z_top - iz c]. iz = 0 is the surface layer and grows
    downward. Arrays are indexed ``probabilities[ix, iy, iz, m]`` and ``explored[ix, iy, iz]`` (note: x first,
    unlike :class:`Grid2D`'s image order), so ``probabilities[ix, iy]`` is a column from the surface down.

    Args:
        materials: names of the M >= 2 reference materials.
        shape: (nx, ny, nz).
        origin: (x0, y0), m.
        z_top: height of the surface, m.
        cell_size: voxel side, m (0.25 cm as in seed 001).
        p_min: clamping floor of :func:`update`.
        base: entropy base.
    """

    _kind = "voxel"
    _axes = "probabilities[ix, iy, iz, m], iz = 0 at the surface"

    def __init__(self, materials, shape, origin=(0.0, 0.0), z_top: float = 0.0, cell_size: float = 0.0025,
                 p_min: float = 1e-6, base: float = 10.0):
        shape3 = check_shape(shape, 3, "shape (nx, ny, nz)")
        self.origin = check_finite_tuple(origin, 2, "origin (x0, y0)")
        (self.z_top,) = check_finite_tuple((z_top,), 1, "z_top")
        self.cell_size = check_positive(cell_size, "cell_size")
        super().__init__(materials, shape3, p_min, base)

    @property
    def shape(self) -> tuple[int, int, int]:
        """(nx, ny, nz)."""
        return self._explored.shape  # type: ignore[return-value]

    def _meta(self) -> dict:
        meta = super()._meta()
        meta["z_top_m"] = self.z_top
        return meta

    def column_of(self, x: float, y: float) -> tuple[int, int]:
        """(ix, iy) of the column containing (x, y), m; ValidationError outside the grid."""
        nx, ny, _ = self.shape
        return (index_along(x, self.origin[0], self.cell_size, nx, "x"),
                index_along(y, self.origin[1], self.cell_size, ny, "y"))

    def voxel_centres(self) -> np.ndarray:
        """Centres of all voxels, shape (nx, ny, nz, 3) holding (x, y, z), m."""
        nx, ny, nz = self.shape
        c = self.cell_size
        xs = self.origin[0] + (np.arange(nx) + 0.5) * c
        ys = self.origin[1] + (np.arange(ny) + 0.5) * c
        zs = self.z_top - (np.arange(nz) + 0.5) * c
        gx, gy, gz = np.meshgrid(xs, ys, zs, indexing="ij")
        return np.stack([gx, gy, gz], axis=-1)

    def _check_voxel(self, ix, iy, iz) -> tuple[int, int, int]:
        idx = (ix, iy, iz)
        if not all(isinstance(i, (int, np.integer)) for i in idx):
            raise ValidationError(f"voxel indices must be integers, got {idx!r}")
        if not all(0 <= i < n for i, n in zip(idx, self.shape, strict=True)):
            raise ValidationError(f"voxel {idx} is outside the grid of (nx, ny, nz) = {self.shape}")
        return int(ix), int(iy), int(iz)

    def column(self, ix: int, iy: int) -> np.ndarray:
        """Copy of the column at (ix, iy) from the surface down, shape (nz, M)."""
        ix, iy, _ = self._check_voxel(ix, iy, 0)
        return self._p[ix, iy].copy()

    def update_voxel(self, ix: int, iy: int, iz: int, p) -> None:
        """Fuse one measurement (shape (M,)) into voxel (ix, iy, iz) and mark it explored."""
        idx = self._check_voxel(ix, iy, iz)
        m = len(self.materials)
        if np.shape(p) != (m,):
            raise ValidationError(f"p must have shape ({m},) (materials {self.materials}), got {np.shape(p)}")
        self._update_at(idx, p)

    def update_voxels(self, ix, iy, iz, p_meas) -> None:
        """Fuse many measurements at once: ``p_meas[i]`` (shape (n, M)) into voxel (ix[i], iy[i], iz[i]), in
        order; exactly ``update_voxel`` for each i in turn, vectorised. Nothing is changed when an argument is
        invalid."""
        self._update_many(cell_indices({"ix": ix, "iy": iy, "iz": iz}, self.shape), p_meas)

    def layers_reached(self, depth_reached: float) -> int:
        """How many voxels from the surface a press of indentation ``depth_reached`` (m, > 0) passes through.

        A press to depth d passes through every voxel whose top is above d: ceil(d / c), at most nz (a press
        deeper than the grid updates the whole column).
        """
        d = check_positive(depth_reached, "depth_reached")
        # Shave a rounding hair so a press to exactly k voxels' depth does not touch voxel k + 1.
        k = math.ceil(d / self.cell_size * (1 - 1e-12))
        return int(min(max(k, 1), self.shape[2]))

    def update_press(self, x: float, y: float, depth_reached: float, p_meas) -> tuple[int, int, int]:
        """Fuse one press at (x, y), m, into the voxels it indented, from the surface to ``depth_reached``.

        Args:
            x, y: press location, m.
            depth_reached: maximum indentation below the surface, m (> 0); see :meth:`layers_reached`.
            p_meas: shape (M,) applied to every voxel passed through, or (k, M) with one row per voxel, k =
                ``layers_reached(depth_reached)``, surface first.

        Returns:
            (ix, iy, k): the column and the number of voxels updated (voxels 0..k-1 are now explored).
        """
        ix, iy = self.column_of(x, y)
        k = self.layers_reached(depth_reached)
        m = len(self.materials)
        shape = np.shape(p_meas)
        if shape not in ((m,), (k, m)):
            raise ValidationError(f"p_meas must have shape ({m},) or ({k}, {m}) (one row per voxel reached), got "
                                  f"{shape}")
        self._update_at((ix, iy, slice(0, k)), p_meas)
        return ix, iy, k

    def postprocessed(self, lateral: bool = False, h_min: float = 1e-12, certainty: float = 1.0) -> VoxelGrid:
        """A new grid after seed 001's local-context stages; self is untouched.

        Order: (1) vertical extrapolation (eq. 3) from the measured values, then (2) continuity verification
        (eq. 5) of the explored voxels. Extrapolating first uses the neighbours as measured, as seed 001 did
        (Table 3 is reproduced from Table 2's 100% column, not its continuity column); running continuity first
        would feed the lower neighbour into a gap twice. Continuity touches only explored voxels, so it does not
        change the filled gaps. (3) If ``lateral``, unexplored voxels still not filled get the 8-neighbour
        estimate of seed 000 eq. 6.15 within their layer, from explored voxels only, keeping ``certainty`` of it
        (see ``Grid2D.postprocessed``). The explored mask is copied unchanged.
        """
        h_min = check_h_min(h_min)
        # One set of weights serves both vertical stages: stage (1) changes only unexplored voxels and stage (2)
        # reads only explored ones.
        w = inverse_entropy(self._p, self.base, h_min)
        p = extrapolate_vertical_kernel(self._p, self._explored, w)
        p = verify_continuity_kernel(p, self._explored, w)
        if lateral:
            filled = self._explored | vertical_gaps(self._explored)
            side = extrapolate_plane(p, self._explored, base=self.base, h_min=h_min,
                                     certainty=check_certainty(certainty))
            p = np.where(filled[..., None], p, side)
        return self._like(p)

    @classmethod
    def load(cls, path) -> VoxelGrid:
        """Read a voxel map written by :meth:`save`, validating both files; errors name the file and key."""
        meta, p, explored = read_map_files(path, cls._kind)
        sidecar = Path(path).with_suffix(".json")
        if "z_top_m" not in meta:
            raise ValidationError(f"{sidecar}: missing key 'z_top_m'")
        shape = meta_value(meta, "shape", sidecar, lambda v: check_shape(v, 3, "shape (nx, ny, nz)"))
        if p.shape[:-1] != shape:
            raise ValidationError(f"{path}: 'probabilities' shape {p.shape} does not match {sidecar} shape {shape}")
        grid = construct(sidecar, lambda: cls(
            meta_value(meta, "materials", sidecar, check_materials), shape,
            z_top=meta_value(meta, "z_top_m", sidecar, lambda v: check_finite_tuple((v,), 1, "z_top")[0]),
            **common_meta(meta, sidecar)))
        return grid._with_arrays(p, explored)


def new_map(geometry: MapGeometry) -> Grid2D | VoxelGrid:
    """An empty (uniform, unexplored) map with ``geometry``."""
    if geometry.voxel:
        return VoxelGrid(list(geometry.materials), geometry.shape, origin=geometry.origin, z_top=geometry.z_top,
                         cell_size=geometry.cell_size, base=geometry.entropy_base)
    return Grid2D(list(geometry.materials), geometry.shape, origin=geometry.origin, cell_size=geometry.cell_size,
                  base=geometry.entropy_base)
