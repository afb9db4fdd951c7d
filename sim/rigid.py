"""``rigid`` fidelity: a MuJoCo-driven finger against a rigid object with a Hertz-shaped contact impedance.

The object is rigid geometry (box, cylinder, mesh); the finger is a sphere on a slide joint along the surface
normal, driven by a position servo (MuJoCo integrates its dynamics: lag, overshoot, compliance of the drive).
The contact is a per-step force applied to the joint, built from the *local* penetration delta(u, v) of the tip
below the undeformed surface at every point of the tip's footprint, with the local Hertz kernel

    p(u, v) = (2 E* / pi) sqrt(2 (delta - d / 2) / R),      d = max over the footprint of delta,

(Hertz: the surface sinks d/2 at the contact edge, so the contact radius is sqrt(R d), not the geometric
sqrt(2 R d)), which integrates exactly to F = 4/3 E* sqrt(R) d^1.5 and p = p0 sqrt(1 - r^2/a^2) for a paraboloid
on a flat surface, and follows the real geometry elsewhere (sphere vs paraboloid, edges, curved or sloped tops).
The force as a function of tip height is tabulated once per press (the tip moves on one axis), so a step costs one
MuJoCo step and a table look-up. Sensel pressures are the same kernel averaged over each sensel (Gauss-Legendre).
Kelvin-Voigt damping of the material scales the force by (1 + tau * d(log F)/dt).

Layers, inclusions and haptic-material maps enter through the depth-weighted effective modulus E*_eff(a) of
:mod:`palpate.sim.effective_modulus`, tabulated per press against the contact radius a = sqrt(R d): the force
table and the sensel pressures are scaled by E*_eff(a(d)) / E*(surface); damping is the surface material's.

Validity: thick objects (the kernel ignores finite thickness; layers and inclusions only to first order, see
:mod:`palpate.sim.effective_modulus` for where that fails: thin stiff skins, large indentation: use ``flex``),
moderate indentation (the kernel is local: no coupling between neighbouring points, so pressure at sharp edges is
not smoothed), vertical surface sampling (on a tilted top the surface is sampled along z under the tip).
"""

from __future__ import annotations

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.world.scene import ObjectSpec, Scene
from palpate.sim.analytic import effective_modulus_along, local_material
from palpate.sim.controller import PressProfile
from palpate.sim.fingertip import cap_height, sensel_quadrature
from palpate.sim.scene import FingerDrive, build_press_model, surface_heights
from palpate.sim.stability import check_resolves_press, check_run, check_warnings
from palpate.sim.trace import PhysicsTrace


def footprint_rings(radius: float, rings: int, sectors: int) -> tuple[np.ndarray, np.ndarray]:
    """Polar cells over the tip's footprint disc: centres (rings*sectors, 2), m, and exact cell areas, m^2.

    Rings are concentric with the tip axis, where a press on a flat top starts, so small contacts are resolved
    by whole rings (a flat top gives one gap value per ring).
    """
    edges = np.linspace(0.0, radius, rings + 1)
    r = 0.5 * (edges[1:] + edges[:-1])
    theta = (np.arange(sectors) + 0.5) * 2.0 * np.pi / sectors
    pts = np.stack([np.outer(r, np.cos(theta)), np.outer(r, np.sin(theta))], axis=-1).reshape(-1, 2)
    area = np.repeat(np.pi * (edges[1:] ** 2 - edges[:-1] ** 2) / sectors, sectors)
    return pts, area


def force_table(gaps: np.ndarray, areas: np.ndarray, kernel: float, s: np.ndarray) -> np.ndarray:
    """Total force F(s) = kernel * sum_i A_i sqrt(max(g_i - s, 0)) at sphere-bottom heights s (m), N.

    gaps: per footprint cell, the effective height at which that cell meets the object, m. Cells with the
    same gap (to 0.1 um) are merged first, so a flat top costs one term per ring.
    """
    keys = np.round(gaps / 1e-7).astype(np.int64)
    uniq, inverse = np.unique(keys, return_inverse=True)
    weight = np.bincount(inverse, weights=areas)
    g = np.bincount(inverse, weights=gaps * areas) / weight
    reach = g > s[0]
    pen = g[None, reach] - s[:, None]
    return kernel * (np.sqrt(np.maximum(pen, 0.0)) @ weight[reach])


def run_rigid_press(
    scene: Scene, obj: ObjectSpec, profile: PressProfile, *, timestep: float = 0.002,
    drive: FingerDrive | None = None, rings: int = 96, sectors: int = 24, order: int = 6,
    young: float | None = None, mesh=None,
) -> PhysicsTrace:
    """Press-and-release of the MuJoCo finger on a rigid object with the Hertz-shaped contact.

    Args:
        scene: the scene (fingertip, objects).
        obj: the pressed object; its material at the press point sets damping and the trace's material name,
            its depth-weighted E*_eff (layers, inclusions) the stiffness.
        profile: the setpoint trajectory (controller).
        timestep: physics step, s.
        drive: finger servo.
        rings, sectors: polar cells over the tip footprint for the total force table.
        order: Gauss-Legendre order per sensel side.
        young: override of the local Young's modulus, Pa (for stability studies; the object is then taken as
            homogeneous).
        mesh: the object's pre-loaded trimesh mesh, if a mesh object.

    Raises:
        SimulationDiverged: MuJoCo warning, NaN, runaway penetration or speed, naming what to change.
    """
    import mujoco

    check_resolves_press(profile, timestep, " (rigid)")
    drive = FingerDrive() if drive is None else drive
    tip = scene.fingertip
    radius = tip.radius
    mat = local_material(obj, profile.x, profile.y, profile.surface_z)
    e_star = mat.effective_modulus if young is None else young / (1.0 - mat.poisson**2)
    if not (np.isfinite(e_star) and e_star > 0):
        raise ValidationError(f"run_rigid_press: young must be a positive modulus in Pa, got {young!r}")
    kernel = 2.0 * e_star / np.pi * np.sqrt(2.0 / radius)
    axis = np.asarray(profile.meta.get("normal", (0.0, 0.0, 1.0)), dtype=float)
    centres = profile.centres()
    start = centres[0]
    q_set = profile.z - profile.z[0]  # the centre is start + q * axis (see PressProfile.centres)
    model, data = build_press_model(scene, start, axis, timestep=timestep, drive=drive,
                                    meshes={obj.name: mesh} if mesh is not None else None)
    model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONTACT)  # the contact law is ours

    # surface sampled under the deepest tip position (the tip moves on one axis)
    deepest = centres[int(np.argmin(profile.z))]
    pts, areas = footprint_rings(radius, rings, sectors)
    gaps = surface_heights(obj, deepest[:2] + pts, mesh) - cap_height(tip, pts)
    qpts, qw = sensel_quadrature(tip, order)
    sensel_gaps = surface_heights(obj, deepest[:2] + qpts.reshape(-1, 2), mesh).reshape(qpts.shape[:-1]) - cap_height(
        tip, qpts)
    # first point of contact; with delta - d/2 = (2 g - g_ref - s) / 2 the kernel keeps the table form
    g_ref = float(np.max(gaps))
    gaps = 2.0 * gaps - g_ref
    sensel_gaps = 2.0 * sensel_gaps - g_ref
    kernel = kernel / np.sqrt(2.0)

    # sphere-bottom height s = centre_z - R; the table covers every height the run can reach (plus margin)
    s_lo = float(np.min(profile.z)) - radius - 2.0 * float(profile.meta.get("depth", 0.004)) - 0.002
    s_hi = float(np.max(gaps)) + 1e-4
    n_tab = 1000
    s_tab = np.linspace(s_lo, s_hi, n_tab)
    f_tab = force_table(gaps, areas, kernel, s_tab)
    # what the press feels below the surface: E*_eff at the contact radius of each table height, relative to
    # the surface E* the kernel was built with (1 everywhere on one material, so nothing changes there)
    e_scale = None
    if young is None:
        e_tab = effective_modulus_along(obj, profile.x, profile.y, profile.surface_z, radius,
                                        np.maximum(g_ref - s_tab, 0.0))
        if np.ndim(e_tab):
            e_scale = (s_tab, np.asarray(e_tab) / e_star)
            f_tab = f_tab * e_scale[1]
    df_tab = np.gradient(f_tab, s_tab)
    inv_ds = (n_tab - 1) / (s_hi - s_lo)
    tau = mat.damping

    n = int(np.ceil(profile.duration / timestep)) + 1
    t = profile.t[0] + timestep * np.arange(n)
    ctrl = np.interp(t, profile.t, q_set).tolist()
    q = [float("nan")] * n
    v = [float("nan")] * n
    f = [float("nan")] * n
    # plain Python floats and lists: indexing numpy scalars would cost more than the MuJoCo step itself
    base = (float(start[2]) - radius - s_lo) * inv_ds
    az = float(axis[2])
    slope = az * inv_ds
    ftab = f_tab.tolist()
    dftab = df_tab.tolist()
    top = n_tab - 1.000001
    qpos, qvel, qfrc, dctrl = data.qpos, data.qvel, data.qfrc_applied, data.ctrl
    step = mujoco.mj_step
    for k in range(n):
        qk = float(qpos[0])
        vk = float(qvel[0])
        x = base + qk * slope
        if not 0.0 <= x <= top:
            if x != x:  # NaN: stop and report below
                break
            x = 0.0 if x < 0.0 else top  # beyond the table: deeper than any run can go, or out of contact
        i = int(x)
        w = x - i
        fk = ftab[i] + (ftab[i + 1] - ftab[i]) * w
        if tau > 0.0 and fk > 0.0:
            # Kelvin-Voigt: F + tau dF/dt with dF/dt = F'(s) ds/dt, never pulling the tip in
            fk = max(fk + tau * (dftab[i] + (dftab[i + 1] - dftab[i]) * w) * vk * az, 0.0)
        q[k] = qk
        v[k] = vk
        f[k] = fk
        qfrc[0] = fk
        dctrl[0] = ctrl[k]
        step(model, data)
    q = np.array(q)
    v = np.array(v)
    f = np.array(f)
    z0 = float(start[2])
    context = f" (rigid, young={e_star * (1 - mat.poisson**2):g} Pa)"
    check_warnings(model, data, timestep=timestep, context=context)
    zc = z0 + q * az
    s_run = zc - radius
    indentation = np.maximum(g_ref - s_run, 0.0)
    check_run(t=t, indentation=np.where(np.isnan(q), np.nan, indentation), velocity=v,
              max_depth=float(profile.meta.get("depth", 0.004)), speed=float(profile.meta.get("speed", 0.01)),
              timestep=timestep, young=e_star * (1 - mat.poisson**2), context=context)

    if not indentation.max() > 0.0:
        # the servo lags a very fast, shallow press and never reaches the surface: zero force, silently
        raise ValidationError(
            f"rigid: the finger never reached the surface{context} (commanded {profile.meta.get('depth', 0) * 1e3:.2f}"
            f" mm at {profile.meta.get('speed', 0.0)} m/s): the press is faster than the finger drive follows; "
            "slow the press speed or press deeper"
        )
    # sensel pressures from the same kernel, only at steps in contact
    pressure = np.zeros((n,) + qpts.shape[:2])
    touching = s_run < float(np.max(sensel_gaps))
    if touching.any():
        pen = sensel_gaps[None] - s_run[touching, None, None, None]
        p = kernel * np.sqrt(np.maximum(pen, 0.0)) @ qw
        if e_scale is not None:
            p = p * np.interp(s_run[touching], *e_scale)[:, None, None]
        if tau > 0:
            elastic = np.interp(s_run[touching], s_tab, f_tab)
            ratio = np.divide(f[touching], elastic, out=np.ones_like(elastic), where=elastic > 0)
            p = p * ratio[:, None, None]
        pressure[touching] = p
    pos = centres[0][None, :] + axis[None, :] * q[:, None]
    trace = PhysicsTrace(
        t=t, tip_position=pos, tip_quaternion=np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)), sensel_pressure=pressure,
        force=f, indentation=indentation, surface_z=profile.surface_z, material=mat.name,
        meta={"fidelity": "rigid", "timestep": float(timestep),
              "young_eff": float(e_star if e_scale is None else e_star * np.interp(s_run.min(), *e_scale)),
              "young_eff_surface": float(e_star),
              "rings": int(rings), "sectors": int(sectors),
              "drive": {"kp": drive.kp, "kv": drive.kv, "armature": drive.armature, "mass": drive.mass}},
    )
    trace.check_finite()
    return trace
