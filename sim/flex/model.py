"""The `flex` fidelity's MuJoCo model: a trilinear flexcomp window of the object under the press, built once and
reused (see :mod:`palpate.sim.flex.press` for the press that runs it).

- The window (:func:`palpate.sim.flex.grid.flex_grid`): its bottom is bonded to the table and where it cuts
  through the object its sides are pinned, with MuJoCo's ``<pin>`` (not by deleting joints). The flexcomp is
  compiled as a uniform box with the grid's cell counts and its nodes then moved to the grid (graded, or mapped
  onto a cylinder's disc).
- The stiffness: MuJoCo's trilinear cell integrates lambda (div u)^2 at 2x2x2 points, which locks as nu -> 0.5
  (3.4x Hertz at nu = 0.49). Each cell's 24x24 block is replaced by the same element with selective reduced
  integration (the volumetric term at the cell centre, the deviatoric 2 mu e:e at 2x2x2 points;
  :mod:`palpate.sim.flex.element`), with the Lame parameters of the cell's material (:func:`cell_moduli`), so
  layers and inclusions are per cell and nu up to 0.49 does not lock; the cells of a stiff skin thinner than a
  cell also get incompatible bending modes. The block layout (node (i, j, k) with k fastest, dof 3 node + axis,
  stored as -K) is MuJoCo 4.0's; a compiled cell is checked against it, so a MuJoCo that stores it differently is
  refused, not misread.
- Mass scaling: presses are quasi-static, so the density is scaled with the softest modulus (1000 kg/m^3 at
  200 kPa) and the tip's drive with the stiffest: a homogeneous block of any modulus then runs the same dynamics,
  and the force scales with E exactly (E-invariance), with the same contact softness (the direct solref is an
  acceleration).
- The mixing correction (:mod:`palpate.sim.flex.mixing`): a layer thinner than a cell that is not given node planes
  (a soft skin) or part of an inclusion is mixed into its cells, which the continuum answers differently from the
  materials themselves; the continuum's ratio of the mixed cells to the object divides the contact force
  (:func:`mixing_at`: per window for layers, per press point for an object that varies laterally).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.world.scene import ObjectSpec, Scene, material_index_at
from palpate.sim.flex.element import bending_ee, box_corners, hex_bases, hex_volumes, lame
from palpate.sim.flex.grid import FlexGrid
from palpate.sim.flex.mixing import (
    MixingCorrection,
    cell_moduli,
    lateral_mixing_correction,
    mixing_correction,
    varies_laterally,
)

#: Longest physics step, s (the default is the shorter of this and a twelfth of the press phase).
MAX_TIMESTEP = 0.01
#: Collision vertices per cell edge (the contact is resolved at resolution / VERTS_PER_CELL).
VERTS_PER_CELL = 2
#: Direct-form contact solref (stiffness, damping), accelerations: with mass scaling, the same for every modulus.
CONTACT_SOLREF = (-1.0e8, -2.0e4)
#: The modulus at which the block has its physical density (DENSITY); the density scales with the stiffest one.
REFERENCE_YOUNG = 2.0e5
DENSITY = 1000.0
#: MuJoCo's iteration limit (opt.iterations, its default) for the M + K solve and the constraint solve. On stiff
#: skins the M + K solve stops at it on most steps (counted, :class:`palpate.sim.stability.SolverWarnings`); 1000
#: clears it at 1.3-2.0x the CPU time (docs/results.md).
SOLVER_ITERATIONS = 100
#: Name of the flexcomp (and the prefix of its bodies) in the model.
NAME = "obj"


@dataclass
class FlexModel:
    """A compiled flex window and what a press needs of it (built once, reused by every press in the window).

    Attributes:
        model: the MuJoCo model; grid: its window; tip_joint, tip_body, tip_geom: MuJoCo ids;
        cell_material: per-cell material name; young_max: the stiffest modulus (Pa), which scales mass and drive;
        kp: drive stiffness, N/m; vertex_spacing: collision vertex spacing on the top, m;
        mixing: the layers' mixing correction (:func:`palpate.sim.flex.mixing.mixing_correction`), None where no
            cell mixes layers or where the object varies laterally (then :func:`mixing_at` gives it per point);
        cell_young, cell_poisson: (n,) each cell's mixed moduli (Pa; MuJoCo's cell order);
        lateral: the object varies laterally; points: lateral corrections computed so far, by press point.
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
    cell_young: np.ndarray | None = None
    cell_poisson: np.ndarray | None = None
    lateral: bool = False
    points: dict = field(default_factory=dict)


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
        f'iterations="{SOLVER_ITERATIONS}" '
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
        kp=float(kp), vertex_spacing=grid.finest / verts_per_cell,
        mixing=None if varies_laterally(obj) else mixing_correction(obj, grid, tip_r),
        meta={"young_range": [float(young_cell.min()), young_max], "mass_scale": float(scale)},
        cell_young=young_cell, cell_poisson=poisson_cell, lateral=varies_laterally(obj),
    )


#: Press points this close (m) share a lateral mixing correction.
POINT_SNAP = 1e-4


def mixing_at(fm: FlexModel, obj: ObjectSpec, x: float, y: float, tip_radius: float) -> MixingCorrection | None:
    """The mixing correction of a press at (x, y) (m) in window ``fm`` of ``obj``: the window's own (layers), or,
    where the object varies laterally, the press point's (:func:`palpate.sim.flex.mixing.lateral_mixing_correction`),
    computed once per point (POINT_SNAP) and kept in ``fm.points``."""
    if not fm.lateral:
        return fm.mixing
    key = (round(x / POINT_SNAP), round(y / POINT_SNAP), float(tip_radius))
    if key not in fm.points:
        if len(fm.points) > 256:  # a long run pressing everywhere must not grow without bound
            fm.points.clear()
        fm.points[key] = lateral_mixing_correction(obj, fm.grid, fm.cell_young, fm.cell_poisson, tip_radius, x, y)
    return fm.points[key]
