"""The `flex` fidelity's MuJoCo model: a trilinear flexcomp window of the object under the press, built once and
reused (see :mod:`palpate.sim.flex` for the press that runs it).

- The window (:func:`palpate.sim.flex_grid.flex_grid`): its bottom is bonded to the table and where it cuts
  through the object its sides are pinned, with MuJoCo's ``<pin>`` (not by deleting joints). The flexcomp is
  compiled as a uniform box with the grid's cell counts and its nodes then moved to the grid (graded, or mapped
  onto a cylinder's disc).
- The stiffness: MuJoCo's trilinear cell integrates lambda (div u)^2 at 2x2x2 points, which locks as nu -> 0.5
  (3.4x Hertz at nu = 0.49). Each cell's 24x24 block is replaced by the same element with selective reduced
  integration (the volumetric term at the cell centre, the deviatoric 2 mu e:e at 2x2x2 points;
  :mod:`palpate.sim.flex_element`), with the Lame parameters of the cell's material (:func:`cell_moduli`), so
  layers and inclusions are per cell and nu up to 0.49 does not lock; the cells of a stiff skin thinner than a
  cell also get incompatible bending modes. The block layout (node (i, j, k) with k fastest, dof 3 node + axis,
  stored as -K) is MuJoCo 4.0's; a compiled cell is checked against it, so a MuJoCo that stores it differently is
  refused, not misread.
- Mass scaling: presses are quasi-static, so the density is scaled with the softest modulus (1000 kg/m^3 at
  200 kPa) and the tip's drive with the stiffest: a homogeneous block of any modulus then runs the same dynamics,
  and the force scales with E exactly (E-invariance), with the same contact softness (the direct solref is an
  acceleration).
- The mixing correction (:func:`mixing_correction`): a layer thinner than a cell that is not given node planes (a
  soft skin) is mixed into its cells, which the continuum answers differently from the layer itself; the ratio of
  the exact layered law of the mixed column to that of the real layers divides the contact force.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.world.scene import Layer, Material, ObjectSpec, Scene, material_index_at
from palpate.sim.contact.law import solve_contact_law
from palpate.sim.flex_element import UNIT_CORNERS, bending_ee, box_corners, hex_bases, hex_volumes, lame
from palpate.sim.flex_grid import FlexGrid
from palpate.sim.reference.sample import AxisymmetricSample
from palpate.sim.stability import MAX_DEPTH_OVER_RADIUS

#: Longest physics step, s (the default is the shorter of this and a twelfth of the press phase).
MAX_TIMESTEP = 0.01
#: Collision vertices per cell edge (the contact is resolved at resolution / VERTS_PER_CELL).
VERTS_PER_CELL = 2
#: Direct-form contact solref (stiffness, damping), accelerations: with mass scaling, the same for every modulus.
CONTACT_SOLREF = (-1.0e8, -2.0e4)
#: The modulus at which the block has its physical density (DENSITY); the density scales with the stiffest one.
REFERENCE_YOUNG = 2.0e5
DENSITY = 1000.0
#: Name of the flexcomp (and the prefix of its bodies) in the model.
NAME = "obj"


#: Sub-points per cell edge at which the material is sampled (a cell holding two materials gets their mix).
SUBCELL = 4


def cell_moduli(obj: ObjectSpec, grid: FlexGrid) -> tuple[np.ndarray, np.ndarray]:
    """Young's modulus (Pa) and Poisson ratio of each cell (MuJoCo's cell order), from SUBCELL^3 points inside it:
    E in series down each vertical sub-column (harmonic mean: exact for the squeeze of a layered cell), the
    sub-columns in parallel (mean: a lump filling part of the cell carries its share); the mean Poisson ratio. A
    cell of one material gets exactly its own; the grid puts node planes on layer and inclusion interfaces
    (:func:`palpate.sim.flex_grid.flex_grid`), so only a curved inclusion's cells mix."""
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


@dataclass(frozen=True)
class MixingCorrection:
    """How much stiffer (or softer) the window's column of mixed cells is than the object's layers, as a continuum.

    Attributes:
        depth: (n,) indentations, m, increasing.
        ratio: (n,) F_law(mixed column) / F_law(layers) at each indentation (both exact layered contact laws).
    """

    depth: np.ndarray
    ratio: np.ndarray

    def at(self, depth: float) -> float:
        """The ratio at an indentation ``depth`` (m), held at the table's ends."""
        return float(np.interp(depth, self.depth, self.ratio))


def mixing_correction(obj: ObjectSpec, grid: FlexGrid, tip_radius: float) -> MixingCorrection | None:
    """The continuum's answer to the window's mixing of thin layers into cells (None where no cell mixes layers).

    A soft layer thinner than a cell is mixed into it (:func:`cell_moduli`; a stiff one gets node planes and cells
    of its own, :func:`palpate.sim.flex_grid.flex_grid`). The series mix is exact for a cell squeezed uniformly,
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
    ratio = (solve_contact_law(column_stack, tip_radius, deepest).force_at(depth)
             / solve_contact_law(AxisymmetricSample(obj.material, obj.height, layers=obj.layers), tip_radius,
                                 deepest).force_at(depth))
    if not np.all(np.isfinite(ratio) & (ratio > 0)):
        raise ValidationError(f"flex: the mixing correction of {obj.name!r} is not a finite positive ratio")
    return MixingCorrection(depth=depth, ratio=ratio)


@dataclass
class FlexModel:
    """A compiled flex window and what a press needs of it (built once, reused by every press in the window).

    Attributes:
        model: the MuJoCo model; grid: its window; tip_joint, tip_body, tip_geom: MuJoCo ids;
        cell_material: per-cell material name; young_max: the stiffest modulus (Pa), which scales mass and drive;
        kp: drive stiffness, N/m; vertex_spacing: collision vertex spacing on the top, m;
        mixing: the mixing correction (:func:`mixing_correction`), None where no cell mixes layers.
    """

    model: object
    grid: FlexGrid
    tip_joint: int
    tip_body: int
    tip_geom: int
    cell_material: list[str]
    young_max: float
    kp: float
    vertex_spacing: float
    mixing: MixingCorrection | None = None
    meta: dict = field(default_factory=dict)


def flexcomp_xml(grid: FlexGrid, *, verts_per_cell: int, mass: float, damping: float, timestep: float) -> str:
    """MJCF of the flex window alone (the tip is added with MjSpec), with the bottom and cut sides pinned, on a
    uniform grid of the window's cell counts (:func:`place_nodes` moves its nodes to the graded grid)."""
    count = " ".join(str(c * verts_per_cell + 1) for c in grid.cells)
    cells = " ".join(str(c) for c in grid.cells)
    spacing = " ".join(repr(float(h) / verts_per_cell) for h in _uniform_cell(grid))
    centre = " ".join(repr(float(c)) for c in grid.lower + grid.size / 2.0)
    pins = " ".join(str(int(i)) for i in grid.pinned_nodes())
    solref = " ".join(repr(float(v)) for v in CONTACT_SOLREF)
    return (
        f'<mujoco model="palpate_flex"><option timestep="{timestep!r}" integrator="discrete" solver="CG" '
        f'gravity="0 0 0"/><worldbody><body name="{NAME}" pos="{centre}">'
        f'<flexcomp name="{NAME}" type="box" dim="3" dof="trilinear" count="{count}" cellcount="{cells}" '
        f'spacing="{spacing}" mass="{mass!r}" radius="0">'
        f'<elasticity young="1" poisson="0.3" damping="{damping!r}"/>'
        f'<contact condim="1" selfcollide="none" solref="{solref}"/><pin id="{pins}"/></flexcomp>'
        f"</body></worldbody></mujoco>"
    )


def _uniform_cell(grid: FlexGrid) -> np.ndarray:
    """Cell edges (3,) of the uniform grid with the window's size and cell counts, m."""
    return grid.size / np.asarray(grid.cells)


def place_nodes(model, flex_id: int, grid: FlexGrid, density: float) -> None:
    """Move the compiled (uniform) flex's nodes to ``grid``'s graded positions, in place.

    MuJoCo interpolates the collision vertices from the nodes by fixed cell-local coordinates, and the elastic
    force is the per-cell blocks times the nodes' displacements, so moving the nodes' reference positions (free
    nodes: their bodies; pinned nodes: their offsets in the flex's body) and giving each cell its own block
    (:func:`build_flex_model`) is the graded mesh. Each free node gets the mass of an eighth of each cell it
    touches (``density`` kg/m^3), as a lumped-mass element has.
    """
    nodes = grid.nodes()
    adr, num = int(model.flex_nodeadr[flex_id]), int(model.flex_nodenum[flex_id])
    if num != len(nodes):
        raise ValidationError(f"flex: the compiled window has {num} nodes, the grid {len(nodes)}")
    body = model.flex_nodebodyid[adr:adr + num]
    owner = int(model.body_parentid[body[body != body.min()][0]]) if np.any(body != body.min()) else int(body[0])
    origin = model.body_pos[owner].copy()
    pinned = body == owner
    model.flex_node[adr:adr + num][pinned] = nodes[pinned] - origin
    model.body_pos[body[~pinned]] = nodes[~pinned] - origin
    model.flex_node0[adr:adr + num] = nodes
    nx, ny, nz = grid.cells
    vol = hex_volumes(grid.cell_corners()).reshape(nx, ny, nz) / 8.0
    share = np.zeros((nx + 1, ny + 1, nz + 1))
    for di in (0, 1):
        for dj in (0, 1):
            for dk in (0, 1):
                share[di:di + nx, dj:dj + ny, dk:dk + nz] += vol
    model.body_mass[body[~pinned]] = density * share.ravel()[~pinned]


def build_flex_model(scene: Scene, obj: ObjectSpec, grid: FlexGrid, *, timestep: float,
                     verts_per_cell: int = VERTS_PER_CELL, min_damping: float = 2.0e-3) -> FlexModel:
    """Compile the window (see the module docstring) with the tip on a vertical slide joint and its drive.

    The tip is placed by the press (its body position is set per press), so one model serves every press point
    in the window.
    """
    import mujoco

    mats = obj.materials()
    names = [m.name for m in mats]
    idx = material_index_at(obj, grid.cell_centres(), names)
    idx[idx < 0] = 0  # a cell centre outside the object (never in a box or the square inside a cylinder)
    young_cell, poisson_cell = cell_moduli(obj, grid)
    young_max = float(young_cell.max())
    scale = young_max / REFERENCE_YOUNG
    # the softest cell sets the density: a soft skin over a hard base must not be made heavy (it would be too slow
    # to get out of the tip's way); stiffer cells only have faster, implicitly integrated dynamics
    mass = float(DENSITY * young_cell.min() / REFERENCE_YOUNG * np.prod(grid.size))
    damping = max([m.damping for m in mats] + [min_damping])
    spec = mujoco.MjSpec.from_string(flexcomp_xml(grid, verts_per_cell=verts_per_cell, mass=mass, damping=damping,
                                                  timestep=timestep))
    tip_r = scene.fingertip.radius
    tip = spec.worldbody.add_body(name="tip", pos=[float(grid.lower[0] + grid.size[0] / 2),
                                                   float(grid.lower[1] + grid.size[1] / 2),
                                                   float(grid.size[2] + tip_r + 0.002)])
    armature = 0.1 * scale
    joint = tip.add_joint(name="tip_z", type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[0, 0, 1], armature=armature)
    tip.add_geom(name="tip", type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[tip_r, 0, 0], mass=0.01 * scale, condim=1)
    e_star = float(np.max(young_cell / (1.0 - poisson_cell**2)))
    kp = 100.0 * 2.0 * e_star * np.sqrt(tip_r * 0.004)
    act = spec.add_actuator(name="tip_drive", target="tip_z", trntype=mujoco.mjtTrn.mjTRN_JOINT)
    act.set_to_position(kp=float(kp), kv=float(2.0 * np.sqrt(kp * joint.armature)))
    model = spec.compile()

    fid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_FLEX, NAME)
    ncell = int(np.prod(grid.cells))
    stiff = model.flex_stiffness[model.flex_stiffnessadr[fid]:model.flex_stiffnessadr[fid] + ncell * 576]
    if stiff.size != ncell * 576:
        raise ValidationError("flex: this MuJoCo build stores the trilinear cell stiffness differently; "
                              "use fidelity 'rigid' or 'analytic'")
    blocks = stiff.reshape(ncell, 24, 24)
    lam_full, _, dev = hex_bases(box_corners(_uniform_cell(grid)))
    lam1, mu1 = lame(1.0, 0.3)
    if not np.allclose(blocks[0], lam1 * lam_full + mu1 * dev, rtol=1e-6, atol=1e-9 * np.abs(dev).max()):
        raise ValidationError("flex: this MuJoCo build's trilinear cell stiffness is not the element palpate "
                              "expects; use fidelity 'rigid' or 'analytic'")
    place_nodes(model, fid, grid, mass / float(np.prod(grid.size)))
    lam, mu = lame(young_cell, poisson_cell)
    corners = grid.cell_corners()
    _, lam_centre, dev = hex_bases(corners)
    bend = grid.bending_cells()
    if bend.any():  # only there: the enriched cells cost the iterative M + K solve more iterations
        dev[bend] = bending_ee(corners[bend])
    blocks[:] = lam[:, None, None] * lam_centre + mu[:, None, None] * dev
    return FlexModel(
        model=model, grid=grid, tip_joint=model.joint("tip_z").id, tip_body=model.body("tip").id,
        tip_geom=model.geom("tip").id, cell_material=[names[i] for i in idx], young_max=float(young_max),
        kp=float(kp), vertex_spacing=grid.finest / verts_per_cell, mixing=mixing_correction(obj, grid, tip_r),
        meta={"young_range": [float(young_cell.min()), young_max], "mass_scale": float(scale)},
    )
