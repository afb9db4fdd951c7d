"""The `flex` fidelity's MuJoCo model: a trilinear flexcomp window of the object under the press, with per-cell
Lame stiffness for layers and inclusions (see :mod:`palpate.sim.flex` for the press that runs it)."""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.world.scene import ObjectSpec, Scene, material_index_at

#: Default cell edge of the elastic grid, m.
DEFAULT_RESOLUTION = 0.0065
#: Default physics step, s (the discrete integrator was stable here; 50 Hz taxels need far less).
DEFAULT_TIMESTEP = 0.005
#: Default lateral size of the simulated window around the press point, m.
DEFAULT_WINDOW = 0.04
#: Direct-form contact solref (stiffness, damping): the reference form lets the tip sink through the flex.
CONTACT_SOLREF = (-1.0e8, -2.0e4)
#: Name of the flexcomp (and the prefix of its bodies) in the model.
NAME = "obj"


@dataclass(frozen=True)
class FlexGrid:
    """The simulated window of the object.

    Attributes:
        lower: (x, y, z) lower corner, m, world frame.
        size: (sx, sy, sz) extents, m.
        cells: (nx, ny, nz) trilinear cells per axis.
        pinned: which side faces are pinned, order (x-, x+, y-, y+) (the bottom is always pinned).
    """

    lower: np.ndarray
    size: np.ndarray
    cells: tuple[int, int, int]
    pinned: tuple[bool, bool, bool, bool]

    @property
    def cell(self) -> np.ndarray:
        """Cell edge lengths (hx, hy, hz), m."""
        return self.size / np.asarray(self.cells)

    def cell_centres(self) -> np.ndarray:
        """(n, 3) cell centres in MuJoCo's cell order (z fastest, then y, then x), m."""
        nx, ny, nz = self.cells
        i, j, k = np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij")
        idx = np.stack([i.ravel(), j.ravel(), k.ravel()], axis=1) + 0.5
        return self.lower + idx * self.cell


def flex_grid(obj: ObjectSpec, x: float, y: float, resolution: float = DEFAULT_RESOLUTION,
              window: float = DEFAULT_WINDOW) -> FlexGrid:
    """Window of ``obj`` around the press point (x, y) (m), meshed with cells of about ``resolution`` m."""
    if not (np.isfinite(resolution) and resolution > 0):
        raise ValidationError(f"flex: resolution must be a cell size > 0 m, got {resolution!r}")
    if not (np.isfinite(window) and window > 0):
        raise ValidationError(f"flex: window must be > 0 m, got {window!r}")
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
    centre = np.clip(np.array([x, y], dtype=float), lo_obj + w, hi_obj - w)
    lo, hi = centre - w, centre + w
    eps = 1e-9
    pinned = (
        bool(lo[0] > lo_obj[0] + eps or not edges_free), bool(hi[0] < hi_obj[0] - eps or not edges_free),
        bool(lo[1] > lo_obj[1] + eps or not edges_free), bool(hi[1] < hi_obj[1] - eps or not edges_free),
    )
    size = np.array([hi[0] - lo[0], hi[1] - lo[1], obj.height])
    # an even lateral count puts a node column under a centred press: a cell centre there would reduce the
    # trilinear field to one averaged spring (exponent ~1 instead of ~1.4)
    nx, ny = (int(2 * max(1, round(s / (2.0 * resolution)))) for s in size[:2])
    nz = int(max(2, round(size[2] / resolution)))
    cells = (nx, ny, nz)
    return FlexGrid(lower=np.array([lo[0], lo[1], 0.0]), size=size, cells=cells, pinned=pinned)


def _lame(young: float, poisson: float) -> tuple[float, float]:
    """Lame parameters (lambda, mu), Pa."""
    return young * poisson / ((1 + poisson) * (1 - 2 * poisson)), young / (2 * (1 + poisson))


def _cell_basis(cell: np.ndarray, verts_per_cell: int) -> tuple[np.ndarray, np.ndarray]:
    """Stiffness blocks per unit lambda and per unit mu of one trilinear cell of edges ``cell`` (m).

    MuJoCo's linear elasticity is linear in the Lame parameters, so two single-cell compiles span every material.
    """
    import mujoco

    blocks = []
    for young, poisson in ((1.0, 0.0), (1.0, 0.25)):
        spec = mujoco.MjSpec()
        body = spec.worldbody.add_body(name="b")
        flex = body.make_flex("c", type="box", dim=3, dof="trilinear", count=[verts_per_cell + 1] * 3,
                              cellcount=[1, 1, 1], spacing=list(cell / verts_per_cell), mass=1.0)
        flex.young, flex.poisson = young, poisson
        with warnings.catch_warnings():
            # a lone cell with no constraints is fine here: only its stiffness matrix is read
            warnings.simplefilter("ignore", UserWarning)
            blocks.append(spec.compile().flex_stiffness.copy())
    k_mu = blocks[0] / _lame(1.0, 0.0)[1]
    lam1, mu1 = _lame(1.0, 0.25)
    k_lam = (blocks[1] - mu1 * k_mu) / lam1
    return k_lam, k_mu


def build_flex_model(scene: Scene, obj: ObjectSpec, grid: FlexGrid, x: float, y: float, z0: float, *,
                     timestep: float = DEFAULT_TIMESTEP, factor: float = 1.0, verts_per_cell: int = 2,
                     density: float = 1000.0, min_damping: float = 2.0e-3, kp: float | None = None):
    """Compile the MuJoCo model: the flex window, the tip on a vertical slide joint, a position actuator.

    Args:
        scene, obj: the scene and the pressed object.
        grid: the window (see :func:`flex_grid`).
        x, y, z0: tip-centre start position, m.
        timestep: physics step, s (integrator "discrete": 3D flex elasticity needs it in MuJoCo 4.0).
        factor: calibration; every modulus is divided by it.
        verts_per_cell: collision vertices per cell edge (contact resolution = cell / verts_per_cell).
        density: mass density of the block, kg/m^3.
        min_damping: floor of the flex damping, s (Kelvin-Voigt time), which keeps the grid from ringing.
        kp: actuator stiffness, N/m; by default 50x the Hertz stiffness of the stiffest material at 4 mm.

    Returns:
        (model, info) with info holding ids ("tip_joint", "tip_geom", "flex"), per-cell material names and the
        moduli used.
    """
    import mujoco

    mats = obj.materials()
    names = [m.name for m in mats]
    centres = grid.cell_centres()
    idx = material_index_at(obj, centres, names)
    # cells whose centre falls outside the object (cylinder windows never do; guard anyway) take the bulk
    idx[idx < 0] = 0
    used = sorted(set(idx.tolist()))
    bulk = obj.material

    spec = mujoco.MjSpec()
    spec.modelname = "palpate_flex"
    spec.option.timestep = timestep
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_DISCRETE
    spec.option.gravity = [0.0, 0.0, 0.0]
    count = [c * verts_per_cell + 1 for c in grid.cells]
    spacing = list(grid.cell / verts_per_cell)
    centre = grid.lower + grid.size / 2.0
    body = spec.worldbody.add_body(name=NAME, pos=list(centre))
    flex = body.make_flex(NAME, type="box", dim=3, dof="trilinear", count=count, cellcount=list(grid.cells),
                          spacing=spacing, mass=float(density * np.prod(grid.size)), radius=0.0)
    flex.young = bulk.young / factor
    flex.poisson = bulk.poisson
    flex.damping = max([mats[i].damping for i in used] + [min_damping])
    flex.solref = list(CONTACT_SOLREF)
    flex.condim = 1
    flex.selfcollide = mujoco.mjtFlexSelf.mjFLEXSELF_NONE

    # pin the bottom (bonded to the table) and the faces where the window cuts through the object
    half = grid.size / 2.0
    tol = 1e-3 * float(grid.cell.min())
    for node in list(spec.bodies):
        if not node.name.startswith(NAME + "_"):
            continue
        p = np.asarray(node.pos)
        faces = (p[0] < -half[0] + tol, p[0] > half[0] - tol, p[1] < -half[1] + tol, p[1] > half[1] - tol)
        if p[2] < -half[2] + tol or any(f and pin for f, pin in zip(faces, grid.pinned, strict=True)):
            for joint in list(node.joints):
                spec.delete(joint)

    tip_r = scene.fingertip.radius
    tip = spec.worldbody.add_body(name="tip", pos=[x, y, z0])
    joint = tip.add_joint(name="tip_z", type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[0, 0, 1], armature=1.0)
    tip.add_geom(name="tip", type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[tip_r, 0, 0], mass=0.01, condim=1)
    e_max = max(mats[i].effective_modulus for i in used) / factor
    if kp is None:
        kp = max(1.0e5, 50.0 * 2.0 * e_max * np.sqrt(tip_r * 0.004))
    act = spec.add_actuator(name="tip_drive", target="tip_z", trntype=mujoco.mjtTrn.mjTRN_JOINT)
    act.set_to_position(kp=float(kp), kv=float(2.0 * np.sqrt(kp * joint.armature)))
    model = spec.compile()

    fid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_FLEX, NAME)
    if len(used) > 1:
        ncell = int(np.prod(grid.cells))
        stiff = model.flex_stiffness[model.flex_stiffnessadr[fid]:].reshape(ncell, -1)[:ncell]
        k_lam, k_mu = _cell_basis(grid.cell, verts_per_cell)
        lam_b, mu_b = _lame(bulk.young / factor, bulk.poisson)
        ref = lam_b * k_lam + mu_b * k_mu
        if k_lam.shape != stiff[0].shape or not np.allclose(stiff[0], ref, rtol=1e-6, atol=1e-9 * np.abs(ref).max()):
            raise ValidationError("flex: this MuJoCo build stores cell stiffness differently; per-cell materials "
                                  "(layers, inclusions) are not supported with it")
        for i in used:
            lam, mu = _lame(mats[i].young / factor, mats[i].poisson)
            stiff[idx == i] = lam * k_lam + mu * k_mu
    info = {
        "tip_joint": model.joint("tip_z").id,
        "tip_geom": model.geom("tip").id,
        "flex": fid,
        "cell_material": [names[i] for i in idx],
        "young_used": {names[i]: mats[i].young / factor for i in used},
        "kp": float(kp),
    }
    return model, info
