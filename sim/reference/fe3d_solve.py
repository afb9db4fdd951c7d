"""The 3-D FE contact solve (:mod:`.fe3d`'s model): the block's stiffness, its top surface's compliance condensed
by a partial factorisation, and the nodal contact forces of the rigid sphere at each depth.

How it is solved:

- stiffness: trilinear bricks on the tensor grid of :func:`.fe3d.block_grids`, selective reduced integration (the
  volumetric term at the centroid, so nu 0.45-0.49 does not lock); each element one material, except elements a
  rotated wall cuts, whose Lame parameters are the volume-fraction (Voigt) mean of the two sides' (the wall at 0 or
  90 deg lies on grid lines instead);
- condensation: the free dofs are ordered by geometric nested dissection of the tensor grid (a plane of nodes
  splits it in two, recursively), with the top nodes the sphere can reach last; the sparse LU of the matrix in
  that order, with diagonal pivots (it is symmetric positive definite), leaves in its trailing block the Schur
  complement of those nodes, whose inverse is the surface compliance. That replaces one solve per surface node;
  one solve checks it;
- contact: the linear complementarity problem (:func:`palpate.sim.contact.lcp.solve_contact`) at each depth,
  gap = the exact sphere.

The half model (``half``: the block symmetric about y = 0) meshes y >= 0 with u_y = 0 on y = 0; its field is
mirrored onto the whole top, the nodes on y = 0 doubled (the half model carries half their load).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from palpate.core.errors import ValidationError
from palpate.sim.contact.lcp import solve_contact
from palpate.sim.reference.fe3d import BoxBlock, TensorGrid, block_grids


@dataclass(frozen=True)
class SurfaceContact:
    """Nodal contact forces on the block's top at each depth, over the whole top (mirrored from a half model).

    Attributes:
        depth: indentations, m, (n,).
        x, y: the top nodes' grid lines near the contact, m from the press axis, (nx,), (ny,) increasing.
        force: downward nodal forces of the sphere on the top, N, (n, ny, nx) (row i at y[i]).
        contact_nodes: nodes in contact in the model solved, (n,).
        dofs: degrees of freedom of the model solved; h: element edge across the contact, m; half: solved as a
            half model.
    """

    depth: np.ndarray
    x: np.ndarray
    y: np.ndarray
    force: np.ndarray
    contact_nodes: np.ndarray
    dofs: int
    h: float
    half: bool


def _lame(young: np.ndarray, poisson: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return young * poisson / ((1 + poisson) * (1 - 2 * poisson)), young / (2 * (1 + poisson))


def element_lame(block: BoxBlock, mesh) -> tuple[np.ndarray, np.ndarray]:
    """Lame parameters (Pa) of each hex of ``mesh`` (coordinates: height above the base), the wall's cut elements
    mixed by volume fraction (see the module docstring)."""
    corners = mesh.p[:, mesh.t]
    centroid = corners.mean(axis=1)
    depth = block.thickness - centroid[2]
    lam, mu = _lame(*replace(block, wall=None).materials_at(centroid[0], centroid[1], depth))
    if block.wall is None:
        return lam, mu
    lam_far, mu_far = _lame(*replace(block, wall=None, material=block.wall.material).materials_at(
        centroid[0], centroid[1], depth))
    phi = block.far_fraction(corners[0].min(axis=0), corners[0].max(axis=0), corners[1].min(axis=0),
                             corners[1].max(axis=0))
    return (1 - phi) * lam + phi * lam_far, (1 - phi) * mu + phi * mu_far


def _stiffness(block: BoxBlock, grid: TensorGrid):
    from skfem import Basis, BilinearForm, ElementHex1, ElementVector, MeshHex, asm
    from skfem.helpers import ddot, sym_grad, trace

    # mesh coordinates: height above the base (depth = thickness - height)
    mesh = MeshHex.init_tensor(grid.x, grid.y, np.sort(block.thickness - grid.depth))
    lam, mu = element_lame(block, mesh)

    @BilinearForm
    def shear(u, v, w):
        return 2.0 * w.mu * ddot(sym_grad(u), sym_grad(v))

    @BilinearForm
    def volume(u, v, w):
        return w.lam * trace(sym_grad(u)) * trace(sym_grad(v))

    full = Basis(mesh, ElementVector(ElementHex1()), intorder=2)
    # selective reduced integration: the volumetric term at the centroid only, so trilinear bricks do not lock
    # as nu approaches 0.5 (fully integrated, they are ~15% too stiff at nu 0.45)
    reduced = Basis(mesh, ElementVector(ElementHex1()), intorder=1)
    stiffness = (asm(shear, full, mu=np.repeat(mu[:, None], full.X.shape[1], axis=1))
                 + asm(volume, reduced, lam=np.repeat(lam[:, None], reduced.X.shape[1], axis=1)))
    return full, stiffness


def grid_indices(block: BoxBlock, grid: TensorGrid, locs: np.ndarray, h: float):
    """The mesh's node heights above the base (increasing, m) and each dof's (x, y, height) grid index, from the
    dof locations ``locs`` (3, N) m of a mesh with spacing down to ``h`` m."""
    heights = np.sort(block.thickness - grid.depth)
    index = tuple(np.clip(np.searchsorted(axis, locs[k] - 1e-9 * h), 0, len(axis) - 1)
                  for k, axis in enumerate((grid.x, grid.y, heights)))
    return heights, index


def dissection_rank(shape: tuple[int, int, int], leaf: int = 64) -> np.ndarray:
    """Elimination rank of each node of a tensor grid of ``shape`` nodes (C order) under geometric nested
    dissection: the two halves of a box before the plane of nodes between them, boxes of at most ``leaf`` nodes
    in one piece. A hex mesh couples nodes of adjacent planes only, so one plane separates."""
    rank = np.empty(int(np.prod(shape)), dtype=np.int64)
    counter = [0]
    strides = np.array([shape[1] * shape[2], shape[2], 1])

    def number(lo, hi) -> None:
        ids = ((np.arange(lo[0], hi[0])[:, None, None] * strides[0]
                + np.arange(lo[1], hi[1])[None, :, None] * strides[1]
                + np.arange(lo[2], hi[2])[None, None, :]).ravel())
        rank[ids] = counter[0] + np.arange(ids.size)
        counter[0] += ids.size

    def split(lo, hi) -> None:
        size = [hi[k] - lo[k] for k in range(3)]
        if min(size) <= 0:
            return
        k = int(np.argmax(size))
        if np.prod(size) <= leaf or size[k] < 3:
            number(lo, hi)
            return
        mid = (lo[k] + hi[k]) // 2
        split(lo, hi[:k] + [mid] + hi[k + 1:])
        split(lo[:k] + [mid + 1] + lo[k + 1:], hi)
        number(lo[:k] + [mid] + lo[k + 1:], hi[:k] + [mid + 1] + hi[k + 1:])

    split([0, 0, 0], list(shape))
    return rank


def condensed_compliance(stiffness, free: np.ndarray, surface: np.ndarray, node_rank: np.ndarray) -> np.ndarray:
    """Compliance (m/N) of the ``surface`` dofs under the stiffness restricted to the ``free`` dofs: the inverse
    of the trailing Schur complement of a nested-dissection LU (see the module docstring).

    Args:
        stiffness: sparse (N, N), N/m; free: dof indices kept; surface: dof indices (within ``free``) condensed
            onto; node_rank: (N,) elimination rank of each dof's node.
    """
    from scipy.sparse.linalg import splu

    last = np.zeros(stiffness.shape[0], dtype=bool)
    last[surface] = True
    order = free[np.lexsort((free, node_rank[free], last[free]))]
    # the surface dofs in the order the caller gave them, at the end
    order = np.concatenate([order[~last[order]], surface])
    n, m = len(order), len(surface)
    lu = splu(stiffness[order][:, order].tocsc(), permc_spec="NATURAL", diag_pivot_thresh=0.0,
              options={"SymmetricMode": True})
    if not (np.array_equal(lu.perm_c, np.arange(n)) and np.array_equal(lu.perm_r, np.arange(n))):
        raise ValidationError("fe3d: the sparse LU reordered the stiffness; the surface condensation needs its "
                              "own order (a scipy change?)")
    tail = slice(n - m, n)
    schur = lu.L.tocsc()[tail, tail].toarray() @ lu.U.tocsc()[tail, tail].toarray()
    compliance = np.linalg.inv(schur)
    probe = np.zeros(n)
    probe[n - m + m // 2] = 1.0
    check = lu.solve(probe)[tail]
    if not np.allclose(check, compliance[:, m // 2], rtol=1e-6, atol=1e-9 * float(np.abs(check).max())):
        raise ValidationError("fe3d: the condensed surface compliance failed its check against a direct solve")
    return 0.5 * (compliance + compliance.T)


def contact_field(block: BoxBlock, tip_radius: float, depths, *, h: float = 0.001, growth: float = 1.3,
                  half: bool | None = None, depth_growth: float | None = None,
                  depth_uniform: float = 0.25) -> SurfaceContact:
    """Nodal contact forces of a rigid frictionless sphere (radius ``tip_radius`` m) pressed ``depths`` (m) into
    the centre of ``block``'s top (x = y = 0).

    Args:
        block: the block.
        tip_radius: m.
        depths: indentations, m, each in (0, 0.9 tip_radius).
        h: element edge (node spacing) across the contact, m.
        growth: element size growth per cell away from the contact.
        depth_growth, depth_uniform: the growth with depth (None: ``growth``) and the depth, in largest contact
            radii, down to which the spacing stays ``h``. Near nu 0.5 the bricks grow tall under the contact
            with ``growth`` 1.3 and stiffen the block (+6% at nu 0.49); 1.1 from one contact radius down holds it.
        half: solve the half model y >= 0; None: where the block is symmetric about y = 0. True for a block that
            is not is an error.

    Raises:
        ValidationError: bad depths or mesh settings, a half model of an unsymmetric block, or a contact that
            reaches the edge of the condensed surface.
    """
    d = np.sort(np.atleast_1d(np.asarray(depths, dtype=float)))
    if not (tip_radius > 0 and d.size and np.all(np.isfinite(d)) and d[0] > 0 and d[-1] < 0.9 * tip_radius):
        raise ValidationError(f"fe3d_press: depths must lie in (0, {0.9 * tip_radius}) m, got {depths!r}")
    if not (h > 0 and growth >= 1.0 and (depth_growth is None or depth_growth >= 1.0) and depth_uniform > 0):
        raise ValidationError(f"fe3d_press: need h > 0, growths >= 1 and depth_uniform > 0, got {h!r}, {growth!r}, "
                              f"{depth_growth!r}, {depth_uniform!r}")
    half = block.symmetric_y if half is None else bool(half)
    if half and not block.symmetric_y:
        raise ValidationError("contact_field: the block is not symmetric about y = 0; pass half=False (or None)")
    a_max = 1.15 * math.sqrt(tip_radius * d[-1])
    grid = block_grids(block, a_max, h, growth, half=half, depth_growth=depth_growth, depth_uniform=depth_uniform)
    basis, stiffness = _stiffness(block, grid)
    locs = basis.doflocs
    heights, (ix, iy, iz) = grid_indices(block, grid, locs, h)
    dofs = basis.get_dofs()
    uy, uz = dofs.all("u^2"), dofs.all("u^3")
    fixed = np.flatnonzero(iz == 0)
    if half:
        fixed = np.unique(np.concatenate([fixed, uy[iy[uy] == 0]]))
    free = np.setdiff1d(np.arange(basis.N), fixed)

    # the top nodes the sphere can reach: its gap below the deepest press plus a cell (the free top sinks)
    reach = min(math.sqrt(max(2 * tip_radius * d[-1] - d[-1] ** 2, 0.0)) + 1.5 * h, 0.95 * tip_radius)
    top = uz[iz[uz] == len(heights) - 1]
    top = top[np.hypot(locs[0, top], locs[1, top]) <= reach]
    if len(top) < 8:
        raise ValidationError("fe3d_press: fewer than 8 surface nodes under the contact; make h smaller")
    node_rank = dissection_rank((len(grid.x), len(grid.y), len(heights)))[(ix * len(grid.y) + iy) * len(heights)
                                                                          + iz]
    compliance = condensed_compliance(stiffness, free, top, node_rank)
    r_top = np.hypot(locs[0, top], locs[1, top])
    gap0 = tip_radius - np.sqrt(tip_radius**2 - r_top**2)

    cols = np.flatnonzero(np.abs(grid.x) <= reach + h)
    rows = np.flatnonzero(grid.y <= reach + h) if half else np.flatnonzero(np.abs(grid.y) <= reach + h)
    force = np.zeros((len(d), len(rows), len(cols)))
    count = []
    for k, depth in enumerate(d):
        f, _ = solve_contact(compliance, depth - gap0)
        if np.any(f[r_top > reach - 1.1 * h] > 0):
            raise ValidationError("fe3d_press: the contact reached the edge of the condensed surface; the top "
                                  "heaved into the sphere beyond its reach (a bug in the reach)")
        force[k, iy[top] - rows[0], ix[top] - cols[0]] = f
        count.append(int(np.sum(f > 0)))
    x, y = grid.x[cols], grid.y[rows]
    if half:
        force[:, 0] *= 2.0
        force = np.concatenate([force[:, :0:-1], force], axis=1)
        y = np.concatenate([-y[:0:-1], y])
    return SurfaceContact(depth=d, x=x, y=y, force=force, contact_nodes=np.array(count), dofs=int(basis.N),
                          h=float(h), half=half)


@dataclass(frozen=True)
class FE3DPress:
    """The 3-D model's answer at each indentation.

    Attributes:
        depth: indentations, m, (n,); force: normal force on the whole (unhalved) block, N, (n,).
        contact_nodes: top nodes in contact in the model solved (half or whole), (n,); dofs: degrees of freedom;
            h: the element edge across the contact, m.
    """

    depth: np.ndarray
    force: np.ndarray
    contact_nodes: np.ndarray
    dofs: int
    h: float


def fe3d_press(block: BoxBlock, tip_radius: float, depths, *, h: float = 0.001,
               growth: float = 1.3) -> FE3DPress:
    """Force of a rigid frictionless sphere (radius ``tip_radius`` m) pressed ``depths`` (m) into the centre of
    ``block``'s top (see the module docstring; the solve is :func:`contact_field`,
    as a half model where the block is symmetric about y = 0).

    Args:
        block: the block.
        tip_radius: m.
        depths: indentations, m, each in (0, 0.9 tip_radius).
        h: element edge (node spacing) across the contact, m.
        growth: element size growth per cell away from the contact.
    """
    field = contact_field(block, tip_radius, depths, h=h, growth=growth)
    return FE3DPress(depth=field.depth, force=field.force.sum(axis=(1, 2)), contact_nodes=field.contact_nodes,
                     dofs=field.dofs, h=field.h)
