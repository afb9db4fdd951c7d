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

Validity: thick homogeneous objects (the kernel ignores finite thickness, layers and inclusions: use ``flex``),
moderate indentation (the kernel is local: no coupling between neighbouring points, so pressure at sharp edges is
not smoothed), vertical surface sampling (on a tilted top the surface is sampled along z under the tip).
"""

from __future__ import annotations

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.scene import ObjectSpec, Scene
from palpate.sim.analytic import local_material
from palpate.sim.controller import PressProfile
from palpate.sim.fingertip import cap_height, sensel_quadrature
from palpate.sim.scene import FingerDrive, build_press_model, surface_heights
from palpate.sim.stability import check_run, check_warnings
from palpate.sim.trace import PhysicsTrace


def _footprint_grid(radius: float, n: int) -> tuple[np.ndarray, float]:
    """Cell centres (m, 2) of an n x n grid over the tip's footprint disc and the cell area, m^2."""
    h = 2.0 * radius / n
    g = -radius + h * (np.arange(n) + 0.5)
    gx, gy = np.meshgrid(g, g)
    pts = np.column_stack([gx.ravel(), gy.ravel()])
    return pts[np.sum(pts**2, axis=1) < radius**2], h * h


def force_table(gaps: np.ndarray, cell_area: float, kernel: float, s: np.ndarray) -> np.ndarray:
    """Total force F(s) = sum_i A kernel sqrt(max(g_i - s, 0)) at sphere-bottom heights s (m), N.

    gaps: per footprint cell, the height at which the sphere's surface there meets the object (surface height
    minus the cap height), m. Binned on the grid of s, so the cost is len(s)^2, not len(s) * len(gaps).
    """
    ds = s[1] - s[0]
    idx = np.clip(np.floor((gaps - s[0]) / ds).astype(int), -1, len(s) - 1)
    inside = idx >= 0
    # weight each bin by its cells' area, at the mean gap of the cells in it
    counts = np.bincount(idx[inside], minlength=len(s)).astype(float)
    sums = np.bincount(idx[inside], weights=gaps[inside], minlength=len(s))
    g_bin = np.where(counts > 0, sums / np.maximum(counts, 1.0), 0.0)
    used = np.nonzero(counts)[0]
    pen = g_bin[None, used] - s[:, None]
    return kernel * cell_area * (np.sqrt(np.maximum(pen, 0.0)) @ counts[used])


def run_rigid_press(
    scene: Scene, obj: ObjectSpec, profile: PressProfile, *, timestep: float = 0.002,
    drive: FingerDrive | None = None, grid: int = 96, order: int = 6, young: float | None = None, mesh=None,
) -> PhysicsTrace:
    """Press-and-release of the MuJoCo finger on a rigid object with the Hertz-shaped contact.

    Args:
        scene: the scene (fingertip, objects).
        obj: the pressed object; its local material at the press point sets E* and damping.
        profile: the setpoint trajectory (controller).
        timestep: physics step, s.
        drive: finger servo.
        grid: cells across the tip footprint for the total force table.
        order: Gauss-Legendre order per sensel side.
        young: override of the local Young's modulus, Pa (for stability studies).
        mesh: the object's pre-loaded trimesh mesh, if a mesh object.

    Raises:
        SimulationDiverged: MuJoCo warning, NaN, runaway penetration or speed, naming what to change.
    """
    import mujoco

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
    pts, cell = _footprint_grid(radius, grid)
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
    n_tab = 400
    s_tab = np.linspace(s_lo, s_hi, n_tab)
    f_tab = force_table(gaps, cell, kernel, s_tab)
    df_tab = np.gradient(f_tab, s_tab)
    inv_ds = (n_tab - 1) / (s_hi - s_lo)
    tau = mat.damping

    n = int(np.ceil(profile.duration / timestep)) + 1
    t = profile.t[0] + timestep * np.arange(n)
    ctrl = np.interp(t, profile.t, q_set)
    q = np.empty(n)
    v = np.empty(n)
    f = np.empty(n)
    z0 = float(start[2])
    az = float(axis[2])
    qpos, qvel, qfrc, dctrl = data.qpos, data.qvel, data.qfrc_applied, data.ctrl
    step = mujoco.mj_step
    for k in range(n):
        qk = qpos[0]
        vk = qvel[0]
        x = (z0 + qk * az - radius - s_lo) * inv_ds
        if x != x:  # NaN: stop and report below
            q[k:] = np.nan
            v[k:] = np.nan
            f[k:] = np.nan
            break
        i = min(max(int(x), 0), n_tab - 2)
        w = min(max(x - i, 0.0), 1.0)
        fk = f_tab[i] + (f_tab[i + 1] - f_tab[i]) * w
        if tau > 0.0 and fk > 0.0:
            # Kelvin-Voigt: F + tau dF/dt with dF/dt = F'(s) ds/dt, never pulling the tip in
            fk = max(fk + tau * (df_tab[i] + (df_tab[i + 1] - df_tab[i]) * w) * vk * az, 0.0)
        q[k] = qk
        v[k] = vk
        f[k] = fk
        qfrc[0] = fk
        dctrl[0] = ctrl[k]
        step(model, data)
    context = f" (rigid, young={e_star * (1 - mat.poisson**2):g} Pa)"
    check_warnings(model, data, timestep=timestep, context=context)
    zc = z0 + q * az
    s_run = zc - radius
    indentation = np.maximum(g_ref - s_run, 0.0)
    check_run(t=t, indentation=np.where(np.isnan(q), np.nan, indentation), velocity=v,
              max_depth=float(profile.meta.get("depth", 0.004)), speed=float(profile.meta.get("speed", 0.01)),
              timestep=timestep, young=e_star * (1 - mat.poisson**2), context=context)

    # sensel pressures from the same kernel, only at steps in contact
    pressure = np.zeros((n,) + qpts.shape[:2])
    touching = s_run < float(np.max(sensel_gaps))
    if touching.any():
        pen = sensel_gaps[None] - s_run[touching, None, None, None]
        p = kernel * np.sqrt(np.maximum(pen, 0.0)) @ qw
        if tau > 0:
            elastic = np.interp(s_run[touching], s_tab, f_tab)
            ratio = np.divide(f[touching], elastic, out=np.ones_like(elastic), where=elastic > 0)
            p = p * ratio[:, None, None]
        pressure[touching] = p
    pos = centres[0][None, :] + axis[None, :] * q[:, None]
    trace = PhysicsTrace(
        t=t, tip_position=pos, tip_quaternion=np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)), sensel_pressure=pressure,
        force=f, indentation=indentation, surface_z=profile.surface_z, material=mat.name,
        meta={"fidelity": "rigid", "timestep": float(timestep), "young_eff": float(e_star), "grid": int(grid),
              "drive": {"kp": drive.kp, "kv": drive.kv, "armature": drive.armature, "mass": drive.mass}},
    )
    trace.check_finite()
    return trace
