"""A 3-D check of the contact law off the press axis: a rigid frictionless sphere pressed into a box-shaped elastic
block bonded to a rigid base, with a box-shaped inclusion beside (or under) the press point.

It exists because the axisymmetric reference (:mod:`.fe`) can only hold what is symmetric about the press axis,
while the contact law averages laterally varying material around the axis (sim/contact/axisymmetric.py): off the
axis that average is an approximation that nothing axisymmetric can check.

Model (quasi-static, linear elastic, small strain):

- geometry: press point at the origin, the block spans x in [-half_x, half_x], y in [-half_y, half_y], depth in
  [0, thickness]; the inclusion spans x in [near, near + length] and is centred on y = 0, so the plane y = 0 (through
  the press axis and the lump's centre) is a symmetry plane and only y >= 0 is meshed (u_y = 0 there);
- mesh: a tensor-product hex mesh, uniform (spacing ``h``) across the contact and growing geometrically away, with
  grid lines on the inclusion's faces (each element one material: ratios with and without the lump on the same
  grid cancel most of the discretisation error); trilinear bricks with selective reduced integration (the volumetric
  term at one point: no locking at nu 0.45; triquadratic bricks cost ~40x more to assemble and factorise here);
- boundary: the bottom bonded (u = 0), the sides free (as the scene's box), the symmetry plane u_y = 0;
- contact: the stiffness is factorised once and the surface compliance of the top nodes within reach condensed from
  it (vertical settlement per unit downward nodal force); at each indentation d the active set of nodes is found
  with f >= 0, settlement = d - (R - sqrt(R^2 - r^2)) (the exact sphere) where f > 0 and no penetration elsewhere
  (Murty's active-set iteration on the dense LCP); the force is twice the half model's nodal sum.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.world.scene import Material
from palpate.sim.reference.mesh import graded_line


@dataclass(frozen=True)
class BoxLump:
    """A box-shaped inclusion beside the press axis, centred on the symmetry plane y = 0.

    Attributes:
        material: its material.
        near: x of its face nearest the press axis, m (>= 0: 0 puts the press over its edge; negative puts the
            press point over the lump, |near| inside it).
        length: its extent along x, m; width: along y (centred on y = 0), m.
        depth: depth of its top below the surface, m (> 0); height: its vertical extent, m.
    """

    material: Material
    near: float
    length: float
    width: float
    depth: float
    height: float

    def __post_init__(self) -> None:
        for key in ("length", "width", "depth", "height"):
            value = getattr(self, key)
            if not (math.isfinite(value) and value > 0):
                raise ValidationError(f"BoxLump.{key} must be > 0 m, got {value!r}")
        if not math.isfinite(self.near):
            raise ValidationError(f"BoxLump.near must be finite (m), got {self.near!r}")


@dataclass(frozen=True)
class BoxBlock:
    """A box-shaped block on a rigid base, pressed at the centre of its top (x = y = 0).

    Attributes:
        material: the bulk material.
        thickness: m; half_x, half_y: half its extents, m.
        lump: an optional inclusion (see :class:`BoxLump`), inside the block.
    """

    material: Material
    thickness: float
    half_x: float
    half_y: float
    lump: BoxLump | None = None

    def __post_init__(self) -> None:
        for key in ("thickness", "half_x", "half_y"):
            value = getattr(self, key)
            if not (math.isfinite(value) and value > 0):
                raise ValidationError(f"BoxBlock.{key} must be > 0 m, got {value!r}")
        lump = self.lump
        if lump is not None and (lump.near < -self.half_x or lump.near + lump.length > self.half_x
                                 or lump.width / 2 > self.half_y or lump.depth + lump.height > self.thickness):
            raise ValidationError("BoxBlock.lump must lie inside the block")

    def materials_at(self, x: np.ndarray, y: np.ndarray, depth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(Young Pa, Poisson) at points (m; depth below the top)."""
        x, y, depth = (np.asarray(v, dtype=float) for v in (x, y, depth))
        young = np.full(x.shape, self.material.young)
        poisson = np.full(x.shape, self.material.poisson)
        lump = self.lump
        if lump is not None:
            inside = ((x > lump.near) & (x < lump.near + lump.length) & (np.abs(y) < lump.width / 2)
                      & (depth > lump.depth) & (depth < lump.depth + lump.height))
            young[inside] = lump.material.young
            poisson[inside] = lump.material.poisson
        return young, poisson


@dataclass(frozen=True)
class FE3DPress:
    """The 3-D model's answer at each indentation.

    Attributes:
        depth: indentations, m, (n,); force: normal force on the whole (unhalved) block, N, (n,).
        contact_nodes: top nodes in contact in the half model, (n,); dofs: degrees of freedom; h: the element
            edge across the contact, m.
    """

    depth: np.ndarray
    force: np.ndarray
    contact_nodes: np.ndarray
    dofs: int
    h: float


@dataclass(frozen=True)
class TensorGrid:
    """Grid lines of the tensor-product mesh, m: x and y from the press axis, depth below the top."""

    x: np.ndarray
    y: np.ndarray
    depth: np.ndarray


def block_grids(block: BoxBlock, a_max: float, h: float, growth: float = 1.3) -> TensorGrid:
    """Grid lines: spacing ``h`` out to 1.3 a_max from the press axis (and 0.25 a_max deep), growing by ``growth``
    per cell beyond; the lump's faces are grid lines."""
    lump = block.lump
    bx, by, bz = [], [], []
    if lump is not None:
        bx = [lump.near, lump.near + lump.length]
        by = [lump.width / 2]
        bz = [lump.depth, lump.depth + lump.height]
    uniform = 1.3 * a_max
    right = graded_line(block.half_x, h, uniform, growth, [b for b in bx if b > 0])
    left = graded_line(block.half_x, h, uniform, growth, [-b for b in bx if b < 0])
    x = np.unique(np.concatenate([-left[::-1], right]))
    y = graded_line(block.half_y, h, uniform, growth, by)
    z = graded_line(block.thickness, h, 0.25 * a_max, growth, bz)
    return TensorGrid(x=x, y=y, depth=z)


def _stiffness(block: BoxBlock, grid: TensorGrid):
    from skfem import Basis, BilinearForm, ElementHex1, ElementVector, MeshHex, asm
    from skfem.helpers import ddot, sym_grad, trace

    # mesh coordinates: height above the base (depth = thickness - height)
    mesh = MeshHex.init_tensor(grid.x, grid.y, np.sort(block.thickness - grid.depth))
    centroid = mesh.p[:, mesh.t].mean(axis=1)
    young, poisson = block.materials_at(centroid[0], centroid[1], block.thickness - centroid[2])
    lam = young * poisson / ((1 + poisson) * (1 - 2 * poisson))
    mu = young / (2 * (1 + poisson))

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


def solve_contact(compliance: np.ndarray, gap: np.ndarray, max_iter: int = 500) -> np.ndarray:
    """Nodal forces f >= 0 (N) with ``compliance`` @ f >= ``gap`` (m), equality where f > 0: the frictionless
    contact of the condensed surface (an LCP, solved by active-set iteration)."""
    active = gap > 0
    if not np.any(active):
        return np.zeros(len(gap))
    f = np.zeros(len(gap))
    for _ in range(max_iter):
        f = np.zeros(len(gap))
        idx = np.flatnonzero(active)
        f[idx] = np.linalg.solve(compliance[np.ix_(idx, idx)], gap[idx])
        negative = f < 0
        # penetration of the free nodes, relative to the deepest gap so round-off does not cycle
        penetrating = (~active) & (compliance @ f < gap - 1e-10 * float(gap.max()))
        if not negative.any() and not penetrating.any():
            return f
        active = (active & ~negative) | penetrating
        if not active.any():
            active[int(np.argmax(gap))] = True
    raise ValidationError("fe3d: the contact active set did not settle; refine the mesh (smaller h)")


def fe3d_press(block: BoxBlock, tip_radius: float, depths, *, h: float = 0.001,
               growth: float = 1.3) -> FE3DPress:
    """Force of a rigid frictionless sphere (radius ``tip_radius`` m) pressed ``depths`` (m) into the centre of
    ``block``'s top (see the module docstring).

    Args:
        block: the block.
        tip_radius: m.
        depths: indentations, m, each in (0, 0.9 tip_radius).
        h: element edge (node spacing) across the contact, m.
        growth: element size growth per cell away from the contact.
    """
    from scipy.sparse.linalg import splu

    d = np.sort(np.atleast_1d(np.asarray(depths, dtype=float)))
    if not (tip_radius > 0 and d.size and np.all(np.isfinite(d)) and d[0] > 0 and d[-1] < 0.9 * tip_radius):
        raise ValidationError(f"fe3d_press: depths must lie in (0, {0.9 * tip_radius}) m, got {depths!r}")
    if not (h > 0 and growth >= 1.0):
        raise ValidationError(f"fe3d_press: need h > 0 and growth >= 1, got {h!r}, {growth!r}")
    a_max = 1.15 * math.sqrt(tip_radius * d[-1])
    basis, stiffness = _stiffness(block, block_grids(block, a_max, h, growth))
    locs = basis.doflocs
    dofs = basis.get_dofs()
    uy, uz = dofs.all("u^2"), dofs.all("u^3")
    fixed = np.unique(np.concatenate([np.flatnonzero(np.isclose(locs[2], 0.0)), uy[np.isclose(locs[1, uy], 0.0)]]))
    free = np.setdiff1d(np.arange(basis.N), fixed)
    at = -np.ones(basis.N, dtype=int)
    at[free] = np.arange(len(free))

    top = uz[np.isclose(locs[2, uz], block.thickness)]
    r_top = np.hypot(locs[0, top], locs[1, top])
    reach = min(1.3 * a_max, 0.95 * tip_radius)
    cand = top[r_top <= reach]
    r_cand = r_top[r_top <= reach]
    if len(cand) < 8:
        raise ValidationError("fe3d_press: fewer than 8 surface nodes under the contact; make h smaller")
    lu = splu(stiffness[free][:, free].tocsc(), permc_spec="MMD_AT_PLUS_A")
    loads = np.zeros((len(free), len(cand)))
    loads[at[cand], np.arange(len(cand))] = -1.0  # unit downward force (z up)
    compliance = -lu.solve(loads)[at[cand]]  # downward settlement per unit downward force
    compliance = 0.5 * (compliance + compliance.T)
    gap0 = tip_radius - np.sqrt(tip_radius**2 - r_cand**2)
    forces, count = [], []
    for depth in d:
        f = solve_contact(compliance, depth - gap0)
        if np.any(f[r_cand > 0.97 * reach] > 0):
            raise ValidationError("fe3d_press: the contact reached the edge of the condensed surface; a bug in the "
                                  "reach")
        forces.append(2.0 * float(f.sum()))
        count.append(int(np.sum(f > 0)))
    return FE3DPress(depth=d, force=np.array(forces), contact_nodes=np.array(count), dofs=int(basis.N), h=float(h))
