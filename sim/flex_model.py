"""The `flex` fidelity's MuJoCo model: a trilinear flexcomp window of the object under the press, built once and
reused (see :mod:`palpate.sim.flex` for the press that runs it).

- The window: at most ``window`` wide around the press point (snapped to a 1 mm grid so nearby presses share a
  model), the object's full height, cubic cells of about ``resolution``; its bottom is bonded to the table and
  where it cuts through the object its sides are pinned, with MuJoCo's ``<pin>`` (not by deleting joints).
- The stiffness: MuJoCo's trilinear cell integrates lambda (div u)^2 at 2x2x2 points, which locks as nu -> 0.5
  (3.4x Hertz at nu = 0.49). Each cell's 24x24 block is replaced by the same element with selective reduced
  integration (the volumetric term at the cell centre, the deviatoric 2 mu e:e at 2x2x2 points), with the Lame
  parameters of the cell's material (:func:`cell_moduli`: a cell holding a skin and its base gets their mix), so
  layers and inclusions are per cell and nu up to 0.49 does not lock. The block layout (node (i, j, k) with k
  fastest, dof 3 node + axis, stored as -K) is MuJoCo 4.0's; a
  compiled cell is checked against it, so a MuJoCo that stores it differently is refused, not misread.
- Mass scaling: presses are quasi-static, so the density is scaled with the softest modulus (1000 kg/m^3 at
  200 kPa) and the tip's drive with the stiffest: a homogeneous block of any modulus then runs the same dynamics,
  and the force scales with E exactly (E-invariance), with the same contact softness (the direct solref is an
  acceleration).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.world.scene import ObjectSpec, Scene, material_index_at

#: Default cell edge of the elastic grid (under the press, if graded), m.
DEFAULT_RESOLUTION = 0.005
#: Ratio of neighbouring cell edges beyond the fine region of a graded grid (flex_grid(core=...)).
GROWTH = 1.5
#: Default lateral size of the simulated window around the press point, m.
DEFAULT_WINDOW = 0.03
#: Longest physics step, s (the default is the shorter of this and a twelfth of the press phase).
MAX_TIMESTEP = 0.01
#: Collision vertices per cell edge (the contact is resolved at resolution / VERTS_PER_CELL).
VERTS_PER_CELL = 2
#: Direct-form contact solref (stiffness, damping), accelerations: with mass scaling, the same for every modulus.
CONTACT_SOLREF = (-1.0e8, -2.0e4)
#: The modulus at which the block has its physical density (DENSITY); the density scales with the stiffest one.
REFERENCE_YOUNG = 2.0e5
DENSITY = 1000.0
#: Press points are snapped to this grid to choose the window, m (nearby presses share a model).
SNAP = 0.001
#: Fewest cells through the thickness (a thin block bends and squeezes over its thickness, not over a cell).
MIN_LAYERS = 2
#: Name of the flexcomp (and the prefix of its bodies) in the model.
NAME = "obj"


@dataclass(frozen=True)
class FlexGrid:
    """The simulated window of the object: a tensor grid of nodes, fine at the press point and coarser away.

    Attributes:
        x, y, z: node coordinates along each axis, m, world frame, increasing (z from the table, 0, to the top).
        pinned: which side faces are pinned, order (x-, x+, y-, y+) (the bottom is always pinned).
    """

    x: np.ndarray
    y: np.ndarray
    z: np.ndarray
    pinned: tuple[bool, bool, bool, bool]

    @property
    def lower(self) -> np.ndarray:
        """(x, y, z) lower corner, m."""
        return np.array([self.x[0], self.y[0], self.z[0]])

    @property
    def size(self) -> np.ndarray:
        """(sx, sy, sz) extents, m."""
        return np.array([self.x[-1] - self.x[0], self.y[-1] - self.y[0], self.z[-1] - self.z[0]])

    @property
    def cells(self) -> tuple[int, int, int]:
        """(nx, ny, nz) trilinear cells per axis."""
        return (len(self.x) - 1, len(self.y) - 1, len(self.z) - 1)

    @property
    def finest(self) -> float:
        """The smallest lateral cell edge (the cells under the press), m."""
        return float(min(np.diff(self.x).min(), np.diff(self.y).min()))

    def _per_cell(self, values) -> np.ndarray:
        """(n, 3) of per-axis cell values in MuJoCo's cell order (z fastest, then y, then x)."""
        i, j, k = np.meshgrid(*values, indexing="ij")
        return np.stack([i.ravel(), j.ravel(), k.ravel()], axis=1)

    def cell_edges(self) -> np.ndarray:
        """(n, 3) cell edge lengths (hx, hy, hz) in MuJoCo's cell order, m."""
        return self._per_cell([np.diff(self.x), np.diff(self.y), np.diff(self.z)])

    def cell_centres(self) -> np.ndarray:
        """(n, 3) cell centres in MuJoCo's cell order, m."""
        mid = [(a[1:] + a[:-1]) / 2.0 for a in (self.x, self.y, self.z)]
        return self._per_cell(mid)

    def nodes(self) -> np.ndarray:
        """(N, 3) node positions in MuJoCo's node order (k fastest, i slowest), m."""
        return self._per_cell([self.x, self.y, self.z])

    def pinned_nodes(self) -> np.ndarray:
        """Indices of the pinned grid nodes (MuJoCo's node order: k fastest, i slowest)."""
        nx, ny, nz = (c + 1 for c in self.cells)
        i, j, k = np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij")
        pin = k == 0
        for flag, face in zip(self.pinned, (i == 0, i == nx - 1, j == 0, j == ny - 1), strict=True):
            if flag:
                pin |= face
        return np.nonzero(pin.ravel())[0]

    def key(self) -> tuple:
        """A hashable identity (for model caches)."""
        return tuple(tuple(np.round(a, 9)) for a in (self.x, self.y, self.z)) + (self.pinned,)


def graded_nodes(lo: float, hi: float, focus: float, fine: float, core: float, growth: float) -> np.ndarray:
    """Node coordinates on [lo, hi] (m): steps of ``fine`` within ``core`` of ``focus`` (a node), then steps growing
    by ``growth`` each to the ends (the last ones stretched or shrunk so the ends are nodes). ``focus`` may be an
    end (a one-sided grading, e.g. down from the top)."""
    out = [np.array([focus])]
    for side, length in ((-1.0, focus - lo), (1.0, hi - focus)):
        if length <= 1e-12:
            continue
        n_core = int(max(1, round(min(core, length) / fine)))
        steps = [min(core, length) / n_core] * n_core
        rest = length - sum(steps)
        if rest > 1e-12:
            grown, h = [], steps[-1]
            while sum(grown) < rest:
                h *= growth
                grown.append(h)
            if len(grown) > 1 and sum(grown) - rest > 0.5 * grown[-1]:
                grown.pop()  # the last step would be mostly overshoot: stretch the others instead
            steps += list(np.asarray(grown) * rest / sum(grown))
        out.append(focus + side * np.cumsum(steps))
    nodes = np.sort(np.concatenate(out))
    nodes[0], nodes[-1] = lo, hi
    return nodes


def flex_grid(obj: ObjectSpec, x: float, y: float, resolution: float = DEFAULT_RESOLUTION,
              window: float = DEFAULT_WINDOW, core: float | None = None, growth: float = GROWTH) -> FlexGrid:
    """Window of ``obj`` around the press point (x, y) (m, snapped to SNAP), meshed with cells of ``resolution`` m
    within ``core`` m of the press (laterally and down from the top) growing by ``growth`` per cell beyond (a node
    column stands under the press). ``core`` None (the default): a uniform grid.

    A graded grid resolves the contact better for its node count, but the discrete integrator solves M + K
    iteratively each step and its cost grows with the node count and the grading's ill-conditioning: 1.5 mm cells
    graded to the 30 mm window (14 x 14 x 10 cells) run several times slower than the uniform 5 mm default, which
    is why the default stays uniform."""
    core = max(window, obj.height, resolution) if core is None else core
    for name, v in (("resolution", resolution), ("window", window), ("core", core)):
        if not (np.isfinite(v) and v > 0):
            raise ValidationError(f"flex: {name} must be a length > 0 m, got {v!r}")
    if not (np.isfinite(growth) and growth >= 1.0):
        raise ValidationError(f"flex: growth must be a cell-to-cell ratio >= 1, got {growth!r}")
    cx, cy = obj.position
    if obj.shape == "box":
        half = np.array(obj.size[:2], dtype=float) / 2.0
        edges_free = True
    elif obj.shape == "cylinder":
        half = np.full(2, obj.size[0] / np.sqrt(2.0))
        edges_free = False
    else:
        raise ValidationError(f"object {obj.name!r}: the flex fidelity supports shapes 'box' and 'cylinder', "
                              f"not {obj.shape!r}; use fidelity 'rigid' or 'analytic' for meshes")
    lo_obj = np.array([cx, cy]) - half
    hi_obj = np.array([cx, cy]) + half
    w = np.minimum(window / 2.0, half)
    snapped = np.round(np.array([x, y], dtype=float) / SNAP) * SNAP
    centre = np.clip(snapped, lo_obj + w, hi_obj - w)
    lo, hi = centre - w, centre + w
    focus = np.clip(snapped, lo, hi)
    eps = 1e-9
    pinned = (
        bool(lo[0] > lo_obj[0] + eps or not edges_free), bool(hi[0] < hi_obj[0] - eps or not edges_free),
        bool(lo[1] > lo_obj[1] + eps or not edges_free), bool(hi[1] < hi_obj[1] - eps or not edges_free),
    )
    xs, ys = (graded_nodes(lo[a], hi[a], focus[a], resolution, core, growth) for a in range(2))
    zs = graded_nodes(0.0, obj.height, obj.height, resolution, core, growth)
    if len(zs) - 1 < MIN_LAYERS:
        zs = np.linspace(0.0, obj.height, MIN_LAYERS + 1)
    return FlexGrid(x=xs, y=ys, z=zs, pinned=pinned)


#: Sub-points per cell edge at which the material is sampled (a cell holding two materials gets their mix).
SUBCELL = 4


def cell_moduli(obj: ObjectSpec, grid: FlexGrid) -> tuple[np.ndarray, np.ndarray]:
    """Young's modulus (Pa) and Poisson ratio of each cell (MuJoCo's cell order), from SUBCELL^3 points inside it:
    E in series down each vertical sub-column (harmonic mean: exact for the squeeze of a layered cell, which is how
    a soft skin thinner than a cell is pressed), the sub-columns in parallel (mean: a lump filling part of the cell
    carries its share); the mean Poisson ratio. A cell of one material gets exactly its own. A stiff skin thinner
    than a cell carries load by bending, which no mix of moduli in a coarse cell gives: flex underestimates it (see
    the validity table)."""
    mats = obj.materials()
    names = [m.name for m in mats]
    young = np.array([m.young for m in mats])
    poisson = np.array([m.poisson for m in mats])
    frac = (np.arange(SUBCELL) + 0.5) / SUBCELL - 0.5
    sub = np.stack(np.meshgrid(frac, frac, frac, indexing="ij"), axis=-1).reshape(-1, 3)
    pts = grid.cell_centres()[:, None, :] + sub[None, :, :] * grid.cell_edges()[:, None, :]
    idx = material_index_at(obj, pts.reshape(-1, 3), names).reshape(len(pts), -1)
    centre = material_index_at(obj, grid.cell_centres(), names)
    idx = np.where(idx >= 0, idx, np.maximum(centre, 0)[:, None])
    # sub-points are ordered (x, y, z) with z fastest: series down each sub-column, parallel across them
    columns = 1.0 / np.mean(1.0 / young[idx].reshape(len(pts), SUBCELL * SUBCELL, SUBCELL), axis=2)
    return np.mean(columns, axis=1), np.mean(poisson[idx], axis=1)


def _lame(young, poisson):
    """Lame parameters (lambda, mu), Pa."""
    return young * poisson / ((1 + poisson) * (1 - 2 * poisson)), young / (2 * (1 + poisson))


def _strain_parts(s: float, t: float, u: float) -> np.ndarray:
    """Strain tensors (3, 24, 3, 3) of each unit nodal dof of a unit trilinear cell at local point (s, t, u) in
    [0, 1]^3, split by the axis of the shape-function derivative: a cell of edges h has strain sum_i part_i / h_i."""
    out = np.zeros((3, 24, 3, 3))
    node = 0
    for bx in range(2):
        for by in range(2):
            for bz in range(2):
                px, py, pz = (1 - s, s)[bx], (1 - t, t)[by], (1 - u, u)[bz]
                dx, dy, dz = (-1.0, 1.0)[bx], (-1.0, 1.0)[by], (-1.0, 1.0)[bz]
                grad = (dx * py * pz, px * dy * pz, px * py * dz)
                for i in range(3):
                    for axis in range(3):
                        du = np.zeros((3, 3))
                        du[axis, i] = grad[i]
                        out[i, 3 * node + axis] = 0.5 * (du + du.T)
                node += 1
    return out


def _unit_parts() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(3, 3, 24, 24) stiffness parts of a unit cell per unit Lame parameter, each to be weighted by
    vol / (h_i h_j): volumetric at 2x2x2 points, volumetric at the centre, deviatoric 2 e:e at 2x2x2 points."""
    xg, wg = np.polynomial.legendre.leggauss(2)
    xg, wg = (xg + 1.0) / 2.0, wg / 2.0
    lam_full = np.zeros((3, 3, 24, 24))
    dev = np.zeros((3, 3, 24, 24))
    for a in range(2):
        for b in range(2):
            for c in range(2):
                eps = _strain_parts(xg[a], xg[b], xg[c])
                w = wg[a] * wg[b] * wg[c]
                tr = np.einsum("iaxx->ia", eps)
                lam_full += w * np.einsum("ia,jb->ijab", tr, tr)
                dev += 2.0 * w * np.einsum("iaxy,jbxy->ijab", eps, eps)
    tr0 = np.einsum("iaxx->ia", _strain_parts(0.5, 0.5, 0.5))
    return lam_full, np.einsum("ia,jb->ijab", tr0, tr0), dev


_UNIT_PARTS = _unit_parts()


def cell_bases(cell: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Stiffness of cells of edges ``cell`` (m; (3,) or (n, 3)) per unit Lame parameter, in MuJoCo's layout and
    sign (-K): (volumetric at 2x2x2 points, volumetric at the centre, deviatoric 2 e:e at 2x2x2 points), each
    (24, 24) or (n, 24, 24)."""
    h = np.asarray(cell, dtype=float)
    inv = 1.0 / h
    weight = -np.prod(h, axis=-1)[..., None, None] * inv[..., :, None] * inv[..., None, :]
    return tuple(np.einsum("...ij,ijab->...ab", weight, part) for part in _UNIT_PARTS)


@dataclass
class FlexModel:
    """A compiled flex window and what a press needs of it (built once, reused by every press in the window).

    Attributes:
        model: the MuJoCo model; grid: its window; tip_joint, tip_body, tip_geom: MuJoCo ids;
        cell_material: per-cell material name; young_max: the stiffest modulus (Pa), which scales mass and drive;
        kp: drive stiffness, N/m; vertex_spacing: collision vertex spacing on the top, m.
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
    vol = np.prod(grid.cell_edges(), axis=1).reshape(nx, ny, nz) / 8.0
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
    lam_full, _, dev = cell_bases(_uniform_cell(grid))
    lam1, mu1 = _lame(1.0, 0.3)
    if not np.allclose(blocks[0], lam1 * lam_full + mu1 * dev, rtol=1e-6, atol=1e-9 * np.abs(dev).max()):
        raise ValidationError("flex: this MuJoCo build's trilinear cell stiffness is not the element palpate "
                              "expects; use fidelity 'rigid' or 'analytic'")
    place_nodes(model, fid, grid, mass / float(np.prod(grid.size)))
    _, lam_centre, dev = cell_bases(grid.cell_edges())
    lam, mu = _lame(young_cell, poisson_cell)
    blocks[:] = lam[:, None, None] * lam_centre + mu[:, None, None] * dev
    return FlexModel(
        model=model, grid=grid, tip_joint=model.joint("tip_z").id, tip_body=model.body("tip").id,
        tip_geom=model.geom("tip").id, cell_material=[names[i] for i in idx], young_max=float(young_max),
        kp=float(kp), vertex_spacing=grid.finest / verts_per_cell,
        meta={"young_range": [float(young_cell.min()), young_max], "mass_scale": float(scale)},
    )
