"""The `flex` fidelity's mixed cells: each cell's moduli from the materials inside it, and the continuum's answer to
that mixing, which the mesh correction (measured on homogeneous blocks) does not know.

A 5 mm cell holding two materials is given their mix (:func:`cell_moduli`), exact for the cell squeezed uniformly;
a contact narrower than the cell strains it unevenly, so the mixed cells answer a press differently from the
materials they hold. The press divides its force by F_continuum(window's cells) / F_continuum(object), from
- :func:`mixing_correction` where only layers mix (laterally uniform): the exact layered contact law of the window's
  column of cells against that of the object's layers;
- :func:`lateral_mixing_correction` where the object varies laterally (an inclusion, a haptic-material map): the
  window's cells and the object, each averaged around the press axis as the contact law averages an object
  (:func:`palpate.sim.contact.axisymmetric.azimuthal_materials`), solved on one coarse axisymmetric FE mesh, whose
  own error cancels in the ratio (as in :func:`palpate.sim.contact.axisymmetric.axisymmetric_law`). A sphere just
  under the top is spread over the cells around the press axis, whose mix is softer than a hard lump (stiffer than a
  soft one) under a contact narrower than them (docs/results.md has the measurements).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.world.scene import Layer, Material, ObjectSpec, material_index_at
from palpate.sim.blas import one_blas_thread
from palpate.sim.contact import axisymmetric
from palpate.sim.contact.law import solve_contact_law
from palpate.sim.contact.stack import object_breaks, object_lookup, object_radial_breaks
from palpate.sim.flex.element import UNIT_CORNERS
from palpate.sim.flex.grid import FlexGrid
from palpate.sim.reference.fe import fe_presses
from palpate.sim.reference.sample import AxisymmetricSample
from palpate.sim.stability import MAX_DEPTH_OVER_RADIUS

#: Sub-points per cell edge at which the material is sampled (a cell holding two materials gets their mix).
SUBCELL = 4


def cell_moduli(obj: ObjectSpec, grid: FlexGrid) -> tuple[np.ndarray, np.ndarray]:
    """Young's modulus (Pa) and Poisson ratio of each cell (MuJoCo's cell order), from SUBCELL^3 points inside it:
    E in series down each vertical sub-column (harmonic mean: exact for the squeeze of a layered cell), the
    sub-columns in parallel (mean: a lump filling part of the cell carries its share); the mean Poisson ratio. A
    cell of one material gets exactly its own; the grid puts node planes under stiff layers
    (:func:`palpate.sim.flex.grid.flex_grid`), so the cells that mix hold a soft skin or part of an inclusion (their
    mix is corrected by :func:`mixing_correction` or :func:`lateral_mixing_correction`)."""
    mats = obj.materials()
    names = [m.name for m in mats]
    young = np.array([m.young for m in mats])
    poisson = np.array([m.poisson for m in mats])
    frac = (np.arange(SUBCELL) + 0.5) / SUBCELL
    sub = np.stack(np.meshgrid(frac, frac, frac, indexing="ij"), axis=-1).reshape(-1, 3)
    # trilinear weights of each sub-point on the 8 corners (so a disc's distorted cells are sampled inside)
    weights = np.prod(np.where(UNIT_CORNERS[None, :, :] > 0, sub[:, None, :], 1.0 - sub[:, None, :]), axis=2)
    pts = np.einsum("sa,nai->nsi", weights, grid.cell_corners())
    idx = material_index_at(obj, pts.reshape(-1, 3), names).reshape(len(pts), -1)
    centre = material_index_at(obj, grid.cell_centres(), names)
    idx = np.where(idx >= 0, idx, np.maximum(centre, 0)[:, None])
    # sub-points are ordered (x, y, z) with z fastest: series down each sub-column, parallel across them
    columns = 1.0 / np.mean(1.0 / young[idx].reshape(len(pts), SUBCELL * SUBCELL, SUBCELL), axis=2)
    return np.mean(columns, axis=1), np.mean(poisson[idx], axis=1)


#: Indentations, in tip radii, at which the mixing correction is tabulated (to the deepest press allowed).
MIXING_DEPTHS = np.geomspace(1e-3, MAX_DEPTH_OVER_RADIUS, 60)
#: Young's modulus of the homogeneous block whose contact radius the window's is compared with, Pa (any: a
#: homogeneous block's contact radius does not depend on it).
CONTACT_BLOCK_YOUNG = 2.0e5


@dataclass(frozen=True)
class MixingCorrection:
    """How much stiffer (or softer) the window's column of mixed cells is than the object's layers, as a continuum.

    Attributes:
        depth: (n,) indentations, m, increasing.
        ratio: (n,) F_law(mixed column) / F_law(layers) at each indentation (both exact layered contact laws).
        contact: (n,) a(mixed column) / a(homogeneous block of the object's height and top Poisson ratio), the
            contact radii of the two laws at each indentation, or None (the lateral correction has none): where
            the window's contact stands against the calibration block's, see :meth:`contact_at`.
    """

    depth: np.ndarray
    ratio: np.ndarray
    contact: np.ndarray | None = None

    def at(self, depth: float) -> float:
        """The ratio at an indentation ``depth`` (m), held at the table's ends."""
        return float(np.interp(depth, self.depth, self.ratio))

    def contact_at(self, depth: float) -> float:
        """How much wider the window's contact is at ``depth`` (m) than the calibration block's (1 without a
        ``contact`` table; held at its ends). The mesh correction ripples as the contact's edge crosses the rings
        of surface vertices, so the press reads it where the block's contact was as wide as the window's: at
        sqrt(R d) times this (a soft skin's column, whose contact is 5-14% wider than a block's, was read 6-11%
        off in a / cell and out of phase with that ripple; docs/results.md)."""
        return 1.0 if self.contact is None else float(np.interp(depth, self.depth, self.contact))


def mixing_correction(obj: ObjectSpec, grid: FlexGrid, tip_radius: float) -> MixingCorrection | None:
    """The continuum's answer to the window's mixing of thin layers into cells (None where no cell mixes layers).

    A soft layer thinner than a cell is mixed into it (:func:`cell_moduli`; a stiff one gets node planes and cells
    of its own, :func:`palpate.sim.flex.grid.flex_grid`). The series mix is exact for a cell squeezed uniformly,
    but a contact narrower than the cell strains the cell's top, where the soft layer is, more than its bottom: the
    mixed column is stiffer than the layers (+33% at 0.2 mm and +14% at 0.5 mm on a 2 mm skin of 20 kPa on 200
    kPa in 5 mm cells), which the mesh correction, measured on homogeneous blocks, does not know. This is that
    ratio from the exact layered law (:func:`palpate.sim.contact.law.solve_contact_law`) of the window's column of
    cells (layers only; an inclusion is not laterally uniform and keeps its mix) against that of the object's layers,
    so the press divides its force by it as it does by the mesh correction.
    """
    if not obj.layers:
        return None
    layered = replace(obj, inclusions=())
    h = grid.finest / 2.0
    cx, cy = grid.lower[:2] + grid.size[:2] / 2.0
    column = FlexGrid(x=np.array([cx - h, cx + h]), y=np.array([cy - h, cy + h]), z=grid.z,
                      pinned=(False, False, False, False))
    young, poisson = cell_moduli(layered, column)
    own = np.array([[m.young, m.poisson] for m in layered.materials()])
    mixed = ~np.any(np.all(np.isclose(np.stack([young, poisson], axis=1)[:, None, :], own[None]), axis=2), axis=1)
    if not mixed.any():
        return None
    cells = []  # top down, neighbouring cells of one mix merged
    for k in range(len(young) - 1, -1, -1):
        dz = float(grid.z[k + 1] - grid.z[k])
        if cells and np.isclose(cells[-1][0], young[k]) and np.isclose(cells[-1][1], poisson[k]):
            cells[-1][2] += dz
        else:
            cells.append([float(young[k]), float(poisson[k]), dz])
    mats = [Material(f"cell{i}", e, nu) for i, (e, nu, _) in enumerate(cells)]
    column_stack = AxisymmetricSample(mats[-1], obj.height,
                                      layers=tuple(Layer(m, c[2]) for m, c in zip(mats[:-1], cells[:-1], strict=True)))
    depth = MIXING_DEPTHS * tip_radius
    deepest = float(depth[-1])
    column_law = solve_contact_law(column_stack, tip_radius, deepest)
    ratio = (column_law.force_at(depth)
             / solve_contact_law(AxisymmetricSample(obj.material, obj.height, layers=obj.layers), tip_radius,
                                 deepest).force_at(depth))
    # the calibration block: homogeneous, the object's height, the Poisson ratio the press reads kappa at (its top's)
    block = AxisymmetricSample(replace(obj.layers[0].material, young=CONTACT_BLOCK_YOUNG), obj.height)
    block_law = solve_contact_law(block, tip_radius, deepest)
    contact = column_law.contact_radius_at(depth) / block_law.contact_radius_at(depth)
    if not np.all(np.isfinite(ratio) & (ratio > 0) & np.isfinite(contact) & (contact > 0)):
        raise ValidationError(f"flex: the mixing correction of {obj.name!r} is not a finite positive ratio")
    return MixingCorrection(depth=depth, ratio=ratio, contact=contact)


#: Indentations, in tip radii, at which the lateral mixing correction is tabulated, up to the deepest allowed; held
#: below the shallowest (0.5 mm on the 8 mm tip), because the coarse mesh's spacing follows the smallest contact
#: radius and its cost with it (tabulated from a 32nd of the deepest, the ratio at 0.5-4 mm on lump_hard_1mm moved
#: by under 1%).
LATERAL_DEPTHS = MAX_DEPTH_OVER_RADIUS * np.geomspace(1.0 / 12.0, 1.0, 8)


def varies_laterally(obj: ObjectSpec) -> bool:
    """Whether ``obj``'s material may vary across a horizontal plane (an inclusion or a haptic-material map)."""
    return bool(obj.inclusions) or obj.material_map is not None


def _cell_index(nodes: np.ndarray, v: np.ndarray) -> np.ndarray:
    return np.clip(np.searchsorted(nodes, v, side="right") - 1, 0, len(nodes) - 2)


def cell_lookup(obj: ObjectSpec, grid: FlexGrid, young: np.ndarray, poisson: np.ndarray, x: float, y: float):
    """The window's cells as a material lookup in the contact law's convention (fn(offsets (n, 2) m from (x, y),
    depths (n,) m below the top) -> (Young Pa, Poisson, inside mask)), ``young`` and ``poisson`` per cell in
    MuJoCo's order. Inside is the object's own; a point of the object outside the window takes the nearest cell's
    moduli (the pinned sides hold the window there)."""
    nx, ny, nz = grid.cells
    e_cells = np.asarray(young, dtype=float).reshape(nx, ny, nz)
    nu_cells = np.asarray(poisson, dtype=float).reshape(nx, ny, nz)
    top = float(grid.z[-1])
    within = object_lookup(obj, x, y, obj.height)
    centre = grid.lower[:2] + grid.size[:2] / 2.0

    def lookup(offsets: np.ndarray, depths: np.ndarray):
        p = np.column_stack([x + offsets[:, 0], y + offsets[:, 1]])
        if grid.disc_radius > 0:  # back through the concentric map: each circle onto its square ring
            rel = p - centre
            ring = np.max(np.abs(rel), axis=1)
            norm = np.linalg.norm(rel, axis=1)
            p = centre + rel * np.where(ring > 0, norm / np.where(ring > 0, ring, 1.0), 0.0)[:, None]
        i, j = _cell_index(grid.x, p[:, 0]), _cell_index(grid.y, p[:, 1])
        k = _cell_index(grid.z, top - np.asarray(depths, dtype=float))
        return e_cells[i, j, k], nu_cells[i, j, k], within(offsets, depths)[2]

    return lookup


def lateral_mixing_correction(obj: ObjectSpec, grid: FlexGrid, young: np.ndarray, poisson: np.ndarray,
                              tip_radius: float, x: float, y: float) -> MixingCorrection:
    """F(window's cells) / F(object) for a press at (x, y) (m) on an object that varies laterally (see the module
    docstring): both averaged around the press axis, solved on one coarse axisymmetric mesh whose lines hold both
    the object's interfaces and the cells' faces. ``young``, ``poisson``: the cells' moduli (:func:`cell_moduli`).
    Nothing is fitted; it costs two factorisations of the coarse mesh, run with BLAS on one thread
    (:func:`palpate.sim.blas.one_blas_thread`)."""
    depth = LATERAL_DEPTHS * tip_radius
    top = obj.height
    cells = cell_lookup(obj, grid, young, poisson, x, y)
    own = object_lookup(obj, x, y, top)
    breaks_z = sorted(set(object_breaks(obj, top)) | {round(float(top - z), 9) for z in grid.z[1:-1]})
    # the cells' faces as radial mesh lines: distances from the press point (a disc's rings: radii from its centre)
    axis = grid.lower[:2] + grid.size[:2] / 2.0 if grid.disc_radius > 0 else np.array([x, y])
    lines = np.abs(np.concatenate([grid.x - axis[0], grid.y - axis[1]]))
    breaks_r = sorted(set(object_radial_breaks(obj, x, y)) | {round(float(v), 9) for v in lines if v > 1e-9})
    # a rim within the contact's reach is a free side, found as the contact law finds it
    rim = axisymmetric.free_side(own, 1.3 * 1.15 * math.sqrt(tip_radius * float(depth[-1])), breaks_r)
    sample = AxisymmetricSample(bulk=obj.material, thickness=top)
    solve = dict(refinement=axisymmetric.REFINEMENT, growth=axisymmetric.GROWTH,
                 depth_growth=axisymmetric.DEPTH_GROWTH, breaks_z=breaks_z, breaks_r=breaks_r, free_side=rim)
    with one_blas_thread():
        mixed, true = fe_presses(sample, tip_radius, depth, [axisymmetric.azimuthal_materials(cells),
                                                            axisymmetric.azimuthal_materials(own)], **solve)
    ratio = mixed.force / true.force
    if not np.all(np.isfinite(ratio) & (ratio > 0)):
        raise ValidationError(f"flex: the lateral mixing correction of {obj.name!r} is not a finite positive ratio")
    return MixingCorrection(depth=depth, ratio=ratio)
