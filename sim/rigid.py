"""``rigid`` fidelity: a MuJoCo-driven finger against the object's contact law mapped onto its real geometry.

MuJoCo models the finger: a sphere on a slide joint along the surface normal, driven by a position servo (lag,
overshoot, compliance of the drive). Contacts are disabled in MuJoCo; the contact force is applied to the joint each
step from a table over the tip's height, built once per press. MuJoCo's step of this finger is affine in its state,
setpoint and applied force, so it is read from MuJoCo once per model (:func:`finger_step`) and taken in plain floats
(the states MuJoCo's to rounding, a fraction of a MuJoCo call); MuJoCo steps where that does not hold. The table:

- the press point's :class:`~palpate.sim.contact.law.ContactLaw` (finite thickness, layers, inclusions; exact
  sphere) gives the pressure p(r; d) of a press d deep on a flat top;
- the object's top under the tip's footprint (polar cells, sampled along z under the deepest tip position, so
  edges, curved and sloped tops count) gives each cell's clearance h (how much further the tip must descend to
  touch it); the cell feels the law's pressure at the radius r_eq where a flat top has the same clearance
  (h = R - sqrt(R^2 - r_eq^2)), so a flat top gives exactly the law, and a cell off the object (past an edge)
  nothing. The force is the sum over cells; sensel pressures are the same field averaged over each sensel.

Kelvin-Voigt damping of the material scales the force by (1 + tau d(log F)/dt). The servo gets the feedforward a
robot controller gives it (the setpoint's velocity and the law's force at the setpoint), so it tracks the
commanded depth; a press that still misses it (or its force target) by over 2% raises PressShortfall naming the
drive stiffness and the speed.

Validity: as the contact law's (see its module; small strain, refused beyond 0.75 tip radii), plus the local
geometry mapping: exact on flat tops; on a curved top of radius R2 it gives R_eff / R of the law's force where two
spheres give sqrt(R_eff / R) (R_eff = 1 / (1/R + 1/R2)); vertical surface sampling on tilted tops.
"""

from __future__ import annotations

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.world.scene import ObjectSpec, Scene
from palpate.sim.analytic import local_material
from palpate.sim.bem.law import press_law
from palpate.sim.blas import one_blas_thread
from palpate.sim.contact.law import ContactLaw
from palpate.sim.controller import PressProfile
from palpate.sim.fingertip import cap_height, sensel_quadrature
from palpate.sim.footprint import contact_geometry, equivalent_radius, law_pressure
from palpate.sim.limits import check_holds
from palpate.sim.scene import FingerDrive, build_press_model, surface_heights
from palpate.sim.stability import (
    MAX_STEPS,
    check_depth,
    check_reached,
    check_resolves_press,
    check_run,
    check_step_budget,
    check_warnings,
    law_depth,
)
from palpate.sim.trace import PhysicsTrace

#: Largest omega * dt of the contact against the drive's inertia (omega = sqrt(contact stiffness / moving mass)):
#: the contact force enters each step from the last state, explicitly. Hard foam (435 MPa, presses of 20-30 um) ran
#: at 1.75-2.1 with 2 ms steps: its fits moved up to 40% (n2) against 0.25 ms steps, and some presses overshot
#: past the reach check; at 0.5 they are within 3% of 0.25 ms.
STABLE_OMEGA_DT = 0.5
#: At most this many halvings (1/16 of the step asked for: 256 times the stiffness): a contact stiffer still is an
#: absurd magnitude for the drive, left to diverge and be reported with the step and the stiffness to change.
MAX_HALVINGS = 4


def stable_timestep(timestep: float, law: ContactLaw, depth: float, drive: FingerDrive) -> float:
    """``timestep`` (s) halved until omega dt <= STABLE_OMEGA_DT for the law's stiffness at ``depth`` (m, clipped to
    the law) against the drive's moving mass (armature + tip), at most MAX_HALVINGS times; halving keeps the steps
    few and the compiled models shared."""
    stiffness = float(law.stiffness_at(min(depth, law.max_depth)))
    if not (np.isfinite(stiffness) and stiffness > 0):
        return timestep
    omega = np.sqrt(stiffness / (drive.armature + drive.mass))
    for _ in range(MAX_HALVINGS):
        if omega * timestep <= STABLE_OMEGA_DT:
            break
        timestep /= 2.0
    return timestep


def run_rigid_press(
    scene: Scene, obj: ObjectSpec, profile: PressProfile, *, timestep: float = 0.002,
    drive: FingerDrive | None = None, rings: int = 96, sectors: int = 24, order: int = 6,
    young: float | None = None, mesh=None, law: ContactLaw | None = None, max_steps: int = MAX_STEPS,
    models: dict | None = None, pressure_rows=None,
) -> PhysicsTrace:
    """Press-and-release of the MuJoCo finger on ``obj`` under the contact law (see the module docstring).

    Args:
        scene: the scene (fingertip, objects).
        obj: the pressed object; its material at the press point sets damping and the trace's material name.
        profile: the setpoint trajectory (controller).
        timestep: physics step, s (halved where the contact is too stiff for it: :func:`stable_timestep`).
        drive: finger servo.
        rings, sectors: polar cells over the tip footprint for the total force table.
        order: Gauss-Legendre order per sensel side.
        young: override of the Young's modulus, Pa (stability studies): the object is taken as homogeneous.
        mesh: the object's pre-loaded trimesh mesh, if a mesh object.
        law: the press point's contact law (computed here when not given; a SimSource caches it).
        max_steps: step budget; a longer press is refused before it runs.
        models: a dict the caller keeps for ``scene`` alone (a SimSource does): compiled press models by timestep,
            drive and axis, moved to each press's start instead of compiled again.
        pressure_rows: ``rows(t) -> mask``: of the trace's times t (s), the rows whose sensel pressure is wanted
            (e.g. :func:`palpate.sim.trace.frame_rows`, what the pad's frames read; none when a later stage draws
            the image anew); the others are left 0. None: every row.

    Raises:
        SimulationDiverged: MuJoCo warning, NaN, runaway penetration or speed, naming what to change.
        PressShortfall: the press missed its commanded depth or force target by over 2%.
        ValidationError: a press deeper than 0.75 tip radii or too short for the timestep.
    """
    import mujoco

    check_resolves_press(profile, timestep, " (rigid)")
    check_step_budget(profile.duration, timestep, max_steps, " (rigid)")
    drive = FingerDrive() if drive is None else drive
    tip = scene.fingertip
    radius = tip.radius
    check_depth(profile, radius, " (rigid)")
    check_holds("rigid", obj, profile, " (rigid)")
    mat = local_material(obj, profile.x, profile.y, profile.surface_z)
    if young is not None:
        if not (np.isfinite(young) and young > 0):
            raise ValidationError(f"run_rigid_press: young must be a positive modulus in Pa, got {young!r}")
        from dataclasses import replace

        obj = replace(obj, material=replace(mat, young=float(young)), layers=(), inclusions=(), material_map=None,
                      map_materials=())
        mat = obj.material
        law = None
    if law is None:
        with one_blas_thread():  # its FE solves (an inclusion, an edge within reach): see palpate.sim.blas
            law = press_law(obj, profile.x, profile.y, profile.surface_z, scene.fingertip, law_depth(profile))
    timestep = stable_timestep(timestep, law, law_depth(profile), drive)
    check_step_budget(profile.duration, timestep, max_steps, " (rigid, a step the contact's stiffness holds)")
    axis = np.asarray(profile.meta.get("normal", (0.0, 0.0, 1.0)), dtype=float)
    centres = profile.centres()
    start = centres[0]
    q_set = profile.z - profile.z[0]  # the centre is start + q * axis (see PressProfile.centres)
    model, data, finger = press_model(scene, start, axis, timestep, drive, models)

    # surface sampled under the deepest tip position (the tip moves on one axis)
    deepest = centres[int(np.argmin(profile.z))]
    foot = contact_geometry(obj, deepest, tip, mesh, rings=rings, sectors=sectors)
    r_cells, areas, g_ref = foot.radius, foot.area, foot.first_contact
    qpts, qw = sensel_quadrature(tip, order)
    sensel_gaps = surface_heights(obj, deepest[:2] + qpts.reshape(-1, 2), mesh).reshape(qpts.shape[:-1]) - cap_height(
        tip, qpts)
    sensel_r = equivalent_radius(g_ref - sensel_gaps, radius)

    # sphere-bottom height s = centre_z - R; the table covers every height the run can reach (plus margin)
    depth_cmd = float(profile.meta.get("depth", 0.004))
    s_lo = float(np.min(profile.z)) - radius - 2.0 * depth_cmd - 0.002
    s_hi = g_ref + 1e-4
    n_tab = 1000
    s_tab = np.linspace(s_lo, s_hi, n_tab)
    d_tab = np.maximum(g_ref - s_tab, 0.0)
    inv_ds = (n_tab - 1) / (s_hi - s_lo)
    # the table's deep part is there for a runaway: evaluated first only over the heights a press that passes its
    # reach check can reach (the setpoint's deepest, past it by more than the check's 2% or 1 um), the rest if the
    # tip ever goes lower (same values either way)
    band = max(int((float(np.min(profile.z)) - radius - 0.05 * depth_cmd - 5e-6 - s_lo) * inv_ds) - 2, 0)
    rows = np.arange(n_tab) >= band
    f_tab = law_pressure(law, d_tab, r_cells, rows) @ areas
    df_tab = np.gradient(f_tab, s_tab)  # exact from row band + 1 on
    tau = mat.damping

    n = int(np.ceil(profile.duration / timestep)) + 1
    t = profile.t[0] + timestep * np.arange(n)
    q_cmd = np.interp(t, profile.t, q_set)
    # feedforward of a robot controller: the setpoint's velocity through the servo damping and the law's force at
    # the setpoint through its stiffness, so the drive's compliance does not leave the press short
    v_cmd = np.gradient(q_cmd, t)
    az = float(axis[2])
    s_cmd = float(start[2]) - radius + q_cmd * az
    f_cmd = np.interp(s_cmd, s_tab, f_tab)
    ctrl = (q_cmd + (drive.kv * v_cmd - f_cmd) / drive.kp).tolist()
    q = [float("nan")] * n
    v = [float("nan")] * n
    f = [float("nan")] * n
    # plain Python floats and lists: indexing numpy scalars would cost more than the MuJoCo step itself
    base = (float(start[2]) - radius - s_lo) * inv_ds
    slope = az * inv_ds
    ftab = f_tab.tolist()
    dftab = df_tab.tolist()
    top = n_tab - 1.000001
    x_band = band + 1.0 if band > 0 else -1.0
    # MuJoCo's step as an affine map (finger_step; module docstring), MuJoCo itself near a joint or setpoint limit
    a00, a01, b0, e0, c0, a10, a11, b1, e1, c1, lim = finger
    # memoryviews read and write plain floats, cheaper per step than numpy's scalar indexing
    qpos, qvel, qfrc, dctrl = (memoryview(a) for a in (data.qpos, data.qvel, data.qfrc_applied, data.ctrl))
    step = mujoco.mj_step
    qk = qpos[0]
    vk = qvel[0]
    for k in range(n):
        x = base + qk * slope
        if not 0.0 <= x <= top:
            if x != x:  # NaN: stop and report below
                break
            x = 0.0 if x < 0.0 else top  # beyond the table: deeper than any run can go, or out of contact
        if x < x_band:  # deeper than the band: the whole table
            f_tab = law_pressure(law, d_tab, r_cells) @ areas
            df_tab = np.gradient(f_tab, s_tab)
            ftab, dftab, x_band = f_tab.tolist(), df_tab.tolist(), -1.0
        i = int(x)
        w = x - i
        fk = ftab[i] + (ftab[i + 1] - ftab[i]) * w
        if tau > 0.0 and fk > 0.0:
            # Kelvin-Voigt: F + tau dF/dt with dF/dt = F'(s) ds/dt, never pulling the tip in
            fk = max(fk + tau * (dftab[i] + (dftab[i + 1] - dftab[i]) * w) * vk * az, 0.0)
        q[k] = qk
        v[k] = vk
        f[k] = fk
        u = ctrl[k]
        if -lim < qk < lim and -lim < u < lim:
            qk, vk = (a00 * qk + a01 * vk + b0 * u + e0 * fk + c0, a10 * qk + a11 * vk + b1 * u + e1 * fk + c1)
        else:
            qpos[0] = qk
            qvel[0] = vk
            qfrc[0] = fk
            dctrl[0] = u
            step(model, data)
            qk = qpos[0]
            vk = qvel[0]
    q = np.array(q)
    v = np.array(v)
    f = np.array(f)
    z0 = float(start[2])
    context = f" (rigid, {mat.name}: E {mat.young:g} Pa)"
    check_warnings(model, data, timestep=timestep, context=context)
    zc = z0 + q * az
    s_run = zc - radius
    indentation = np.maximum(g_ref - s_run, 0.0)
    check_run(t=t, indentation=np.where(np.isnan(q), np.nan, indentation), velocity=v,
              max_depth=depth_cmd, speed=float(profile.meta.get("speed", 0.01)),
              timestep=timestep, young=mat.young, context=context)
    reached = depth_cmd + float(np.min(q_cmd) - np.nanmin(q))
    check_reached(reached, float(np.nanmax(f)), profile, context, knobs=(
        f"the finger drive (kp {drive.kp:g} N/m, kv {drive.kv:g} N s/m) cannot follow this press: slow the press "
        f"(now {profile.meta.get('speed', 0.0)} m/s), use a shorter timestep (now {timestep} s) or a stiffer "
        "drive (FingerDrive.kp)"))

    # sensel pressures from the same field at steps in contact, interpolated in the force's height table as the
    # force is: evaluating the law per step costs steps x sensels x order^2 basis terms (minutes for a slow press)
    pressure = np.zeros((n,) + qpts.shape[:2])
    touching = indentation > 0
    if pressure_rows is not None:
        touching &= np.asarray(pressure_rows(t), dtype=bool)
    if touching.any():
        x = np.clip((s_run[touching] - s_lo) * inv_ds, 0.0, top)
        i = x.astype(int)
        rows = np.zeros(n_tab, dtype=bool)
        rows[i] = rows[i + 1] = True  # the heights the run reached, of the table's 1000
        p_tab = law_pressure(law, d_tab, sensel_r, rows, weights=qw)
        w = (x - i)[:, None, None]
        p = p_tab[i] * (1.0 - w) + p_tab[i + 1] * w
        if tau > 0:
            elastic = np.interp(s_run[touching], s_tab, f_tab)
            ratio = np.divide(f[touching], elastic, out=np.ones_like(elastic), where=elastic > 0)
            p = p * ratio[:, None, None]
        pressure[touching] = p
    pos = centres[0][None, :] + axis[None, :] * q[:, None]
    trace = PhysicsTrace(
        t=t, tip_position=pos, tip_quaternion=np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)), sensel_pressure=pressure,
        force=f, indentation=indentation, surface_z=profile.surface_z, material=mat.name,
        meta={"fidelity": "rigid", "timestep": float(timestep), "young_eff_surface": float(mat.effective_modulus),
              "rings": int(rings), "sectors": int(sectors), "contact_law_max_depth": law.max_depth,
              "drive": {"kp": drive.kp, "kv": drive.kv, "armature": drive.armature, "mass": drive.mass}},
    )
    trace.check_finite()
    return trace


def finger_step(model) -> tuple[float, ...]:
    """MuJoCo's step of the press model's finger as plain floats: (a00, a01, b0, e0, c0, a10, a11, b1, e1, c1, lim)
    with q' = a00 q + a01 v + b0 u + e0 f + c0 and v' = a10 q + a11 v + b1 u + e1 f + c1 for the joint's position q
    (m), velocity v (m/s), the servo's setpoint u (m) and the applied force f (N), valid while |q|, |u| < lim (m;
    the joint's and the setpoint's limits lie beyond). Read from MuJoCo's own steps of ``model``, which are affine
    there (one slide joint, a linear servo, no gravity, contacts off): the states agree with MuJoCo's to rounding.
    A model whose step is not affine (a check step off the map by over 1e-9 of its scale) gets lim 0: MuJoCo
    steps it."""
    import mujoco

    lim = 0.5 * min(float(model.jnt_range[0, 1]), -float(model.jnt_range[0, 0]),
                    float(model.actuator_ctrlrange[0, 1]), -float(model.actuator_ctrlrange[0, 0]))
    probe = mujoco.MjData(model)
    h = 0.5 * lim
    scales = np.array([h, h, h, 1.0])  # q m, v m/s, u m, f N

    def stepped(x: np.ndarray) -> np.ndarray:
        mujoco.mj_resetData(model, probe)
        probe.qpos[0], probe.qvel[0], probe.ctrl[0], probe.qfrc_applied[0] = (float(c) for c in x)
        mujoco.mj_step(model, probe)
        return np.array([probe.qpos[0], probe.qvel[0]])

    c = stepped(np.zeros(4))
    cols = np.stack([(stepped(s * e) - c) / s for s, e in zip(scales, np.eye(4), strict=True)], axis=1)  # (2, 4)
    check = np.array([0.3, -0.7, 0.45, -0.25]) * scales
    scale = np.abs(cols) @ np.abs(check) + np.abs(c)
    # what the probes cannot see is ruled out by the model's form: one degree of freedom, one actuator without an
    # activation state, no dry friction
    affine = (model.nq == model.nv == model.nu == 1 and model.na == 0 and float(model.dof_frictionloss[0]) == 0.0
              and bool(np.all(np.abs(stepped(check) - (cols @ check + c)) <= 1e-9 * scale)))
    return (*(float(x) for x in (*cols[0], c[0], *cols[1], c[1])), lim if affine else 0.0)


def press_model(scene: Scene, start: np.ndarray, axis: np.ndarray, timestep: float, drive: FingerDrive,
                models: dict | None = None):
    """(model, data, step) of :func:`palpate.sim.scene.build_press_model`'s finger alone with MuJoCo's contacts off
    (the law is ours), the tip's body at ``start`` (m), the data fresh, and the model's :func:`finger_step`.
    ``models``: compiled models of ``scene`` kept by the caller; a kept one is moved to ``start`` and reset, which
    is what compiling it there gives (where the finger starts does not change its step)."""
    import mujoco

    key = (float(timestep), drive, tuple(float(c) for c in axis))
    kept = None if models is None else models.get(key)
    if kept is None:
        # the finger alone: the law is the contact, and the objects' geoms and the sites would only cost steps
        model, data = build_press_model(scene, start, axis, timestep=timestep, drive=drive, finger_only=True)
        model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
        step = finger_step(model)
        if models is not None:
            models[key] = (model, data, step)
        return model, data, step
    model, data, step = kept
    model.body("fingertip").pos[:] = [float(c) for c in start]
    mujoco.mj_resetData(model, data)
    return model, data, step
