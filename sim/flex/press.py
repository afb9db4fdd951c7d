"""The `flex` fidelity: a MuJoCo deformable block (trilinear flexcomp, linear elasticity) pressed by the tip.

What MuJoCo computes: the block's elastic deformation (per-cell stiffness with the material at each cell: layers and
inclusions, see :mod:`palpate.sim.flex.model`), the tip's drive dynamics, the frictionless contact between the tip
sphere and the block's surface vertices, and each contact's normal force. What palpate adds: the window of the object
(bottom bonded to the table, cut sides pinned, free object edges free), the mesh correction (the coarse trilinear grid
is stiffer than the elastic continuum by a factor that depends on the contact radius over the cell and the block's
thickness, measured against the reference of homogeneous blocks, :mod:`palpate.sim.flex.calibration`, so finite
thickness, layers and edges come from the block itself; a stiff top layer, a plate, by the block's factor times the
plate's, measured on calibration plates, :mod:`palpate.sim.flex.plate`; over a lump, by the factor its pocket's
surface vertices add, measured on calibration lumps, :mod:`palpate.sim.flex.lump`; cells holding two materials (a
soft skin, part of a lump) are corrected by the continuum's ratio of the mixed cells to the object,
:mod:`palpate.sim.flex.mixing`), and the taxels: each contact force stands for the surface patch of its vertex (side =
vertex spacing) and is spread uniformly over it on the pad, which then averages over each sensel.

The model is built once per window (a ``models`` dict the caller keeps, e.g. one per SimSource) and its state reset
between presses; the calibration tables are read once per run too (``tables``, :mod:`palpate.sim.flex.tables`). A
cylinder narrow enough for the window is meshed whole (its curved side free), a wider one by the square inscribed in
it; meshes are not supported. Gravity is off so that the undeformed top stays at the object's height.
"""

from __future__ import annotations

import numpy as np

from palpate.core.errors import SimulationDiverged, ValidationError
from palpate.core.session.sources import PressTarget
from palpate.core.world.scene import FingertipSpec, Material, ObjectSpec, Scene
from palpate.sim.analytic import material_under
from palpate.sim.controller import press_profile
from palpate.sim.flex.calibration import load_calibration, mesh_curve
from palpate.sim.flex.grid import DEFAULT_RESOLUTION, DEFAULT_WINDOW, flex_grid
from palpate.sim.flex.lump import load_lump_calibration, lump_curve, pocket_at
from palpate.sim.flex.model import (
    CONTACT_SOLREF,
    MAX_TIMESTEP,
    SOLVER_ITERATIONS,
    VERTS_PER_CELL,
    build_flex_model,
    mixing_at,
)
from palpate.sim.flex.plate import load_plate_calibration, plate_curve, plate_skin
from palpate.sim.flex.tables import FlexTables
from palpate.sim.limits import check_holds
from palpate.sim.stability import (
    MAX_STEPS,
    SolverWarnings,
    check_depth,
    check_dropped,
    check_iterations,
    check_reached,
    check_resolves_press,
    check_step_budget,
    check_warnings,
    inertia_warnings,
)
from palpate.sim.trace import PhysicsTrace

#: Contact penetration, m, beyond which (and beyond PENETRATION_FRACTION of the indentation) the run diverged.
PENETRATION_LIMIT = 5.0e-4
PENETRATION_FRACTION = 0.65
#: Smallest contact radius, in cells, whose force the mesh correction is measured for (below it one vertex
#: touches and the force is the vertex's, not the block's).
MIN_CONTACT_OVER_CELL = 0.25
#: Side of the surface patch a contact force stands for, in collision-vertex spacings (1.5, chosen on the 40 mm
#: block of tests/test_sim_flex.py so that the active-sensel map is the reference's within one sensel from 0.5 to 3 mm;
#: 1 leaves the diagonal pattern of single contacts, 2 lights a ring too many): MuJoCo places a flex contact
#: on a surface element (two triangles per vertex square, split along one diagonal), not at a vertex, so a force
#: belongs to the elements around it.
PATCH = 1.5


def pad_coordinates(offsets: np.ndarray, radius: float) -> np.ndarray:
    """Map points on the tip sphere (offsets from its centre, (k, 3), m) to pad-plane coordinates (k, 2), m.

    The pad is wrapped onto the sphere by arc length from the lowest point (azimuthal equidistant), so a pad
    wider than the sphere's diameter still fits, as a flexible Tekscan pad wrapped round a fingertip does.
    """
    off = np.asarray(offsets, dtype=float)
    r = np.linalg.norm(off, axis=1)
    r = np.where(r > 0, r, 1.0)
    cos_t = np.clip(-off[:, 2] / r, -1.0, 1.0)
    arc = radius * np.arccos(cos_t)
    rho = np.linalg.norm(off[:, :2], axis=1)
    scale = np.where(rho > 1e-15, arc / np.where(rho > 1e-15, rho, 1.0), 0.0)
    return off[:, :2] * scale[:, None]


def sensel_pressure(pad_xy: np.ndarray, forces: np.ndarray, fingertip: FingertipSpec, patch: float) -> np.ndarray:
    """Mean pressure over each sensel, Pa, (rows, cols), of point forces each spread uniformly over a square patch.

    Args:
        pad_xy: (k, 2) force positions on the pad plane, m (see :func:`pad_coordinates`).
        forces: (k,) normal forces, N, >= 0.
        fingertip: pad layout.
        patch: side of the square each force stands for (the contact vertex's share of the surface), m.
    """
    if len(forces) == 0:
        return np.zeros((fingertip.rows, fingertip.cols))
    centres = fingertip.sensel_centres().reshape(-1, 2)
    half = fingertip.sensel_size / 2.0
    d = centres[None, :, :] - np.asarray(pad_xy)[:, None, :]  # (k, s, 2)
    # overlap length of [-patch/2, patch/2] with [d - half, d + half] per axis, exact
    lo = np.maximum(d - half, -patch / 2.0)
    hi = np.minimum(d + half, patch / 2.0)
    frac = np.prod(np.clip(hi - lo, 0.0, None), axis=2) / patch**2
    p = np.asarray(forces) @ frac / fingertip.sensel_area
    return p.reshape(fingertip.rows, fingertip.cols)


def _diverged(what: str, t: float, timestep: float) -> SimulationDiverged:
    return SimulationDiverged(
        f"flex: {what} at t={t:.4f} s (timestep {timestep} s); pass a shorter timestep or a slower press "
        "(run_flex_press(timestep=...), simulate_press(timestep=..., speed=...)), or press less deep"
    )


def default_timestep(profile) -> float:
    """The flex step for a press, s: MAX_TIMESTEP, or a thirtieth of the time the press takes to go its depth at
    its speed if that is shorter (the drive turns round at the deepest point within a fraction of a step, so the
    step bounds how far short it stops: well inside the 2% a press must reach)."""
    depth = float(profile.meta.get("depth", 0.0))
    speed = float(profile.meta.get("speed_in", profile.meta.get("speed", 0.0)))
    if depth > 0 and speed > 0:
        return float(min(MAX_TIMESTEP, depth / speed / 30.0))
    t0, t1 = profile.meta.get("phases", {}).get("press", (0.0, profile.duration))
    return float(min(MAX_TIMESTEP, max(t1 - t0, 1e-6) / 30.0))


def _model(scene: Scene, obj: ObjectSpec, grid, dt: float, verts_per_cell: int, models: dict | None):
    """The cached (model, data) of a window, or a new one (kept in ``models``)."""
    import mujoco

    key = (obj, grid.key(), float(dt), int(verts_per_cell), scene.fingertip.radius)
    if models is not None and key in models:
        fm, data = models[key]
        mujoco.mj_resetData(fm.model, data)
        return fm, data
    fm = build_flex_model(scene, obj, grid, timestep=dt, verts_per_cell=verts_per_cell)
    data = mujoco.MjData(fm.model)
    if models is not None:
        if len(models) > 32:  # one window per press region; a long run must not keep them all
            models.clear()
        models[key] = (fm, data)
    return fm, data


def run_flex_press(scene: Scene, obj: ObjectSpec, target, profile, *, timestep: float | None = None,
                   resolution: float | None = None, seed: int = 0, window: float = DEFAULT_WINDOW,
                   calibrate: bool = True, verts_per_cell: int = VERTS_PER_CELL, models: dict | None = None,
                   max_steps: int = MAX_STEPS, iterations: int = SOLVER_ITERATIONS,
                   tables: FlexTables | None = None) -> PhysicsTrace:
    """Simulate one press-and-release of ``obj`` with a deformable flex block; return the physics-rate trace.

    Args:
        scene: the scene (fingertip geometry and pad layout).
        obj: the pressed object (box or cylinder; materials, layers, inclusions).
        target: the press target (kept for the trace's provenance; the motion comes from ``profile``).
        profile: a PressProfile: t (s), z (tip-centre height setpoints, m), x, y (m), surface_z (m), meta.
        timestep: physics step, s (default :func:`default_timestep`).
        resolution: elastic cell edge, m (default 5 mm).
        seed: recorded for provenance; the physics is deterministic and draws no random numbers.
        window: lateral size of the simulated window around the press point, m.
        calibrate: apply the mesh correction (False only to measure it).
        verts_per_cell: collision vertices per cell edge.
        models: a dict the caller keeps to reuse built windows between presses.
        max_steps: step budget; a longer press is refused before it runs.
        iterations: MuJoCo's iteration limit (opt.iterations) for its M + K solve and its constraint solve.
        tables: the calibration tables, read once by a caller that presses many times
            (:func:`palpate.sim.flex.tables.load_flex_tables`); None reads the ones this press needs from disk.

    Returns:
        PhysicsTrace with sensel_pressure (n, rows, cols) Pa, force N (total normal contact force), indentation m
        (surface_z minus the tip's lowest point, clipped at 0); meta["solver_warnings"] counts the MuJoCo
        warnings that leave the force valid (:class:`palpate.sim.stability.SolverWarnings`: the steps whose
        M + K solve ran out of iterations), which a run reports.

    Raises:
        SimulationDiverged: a MuJoCo warning that invalidates the force (a reset state: BADQACC, BADQPOS,
            BADQVEL, BADCTRL; dropped contacts or constraints: CONTACTFULL, CNSTRFULL), NaN, or the tip sinking
            through the block; PressShortfall: the tip missed its commanded depth by over 2%; ValidationError:
            unsupported shape, bad parameters, a press deeper than 0.75 tip radii or longer than the step budget, or
            (with ``calibrate``) one flex does not hold (:mod:`palpate.sim.limits`: deeper than half the material
            over the base, a Poisson ratio over 0.49, a layer under 1 mm).
    """
    import mujoco

    dt = default_timestep(profile) if timestep is None else float(timestep)
    res = DEFAULT_RESOLUTION if resolution is None else float(resolution)
    if not (np.isfinite(dt) and dt > 0):
        raise ValidationError(f"flex: timestep must be > 0 s, got {timestep!r}")
    iterations = check_iterations(iterations, "flex: iterations")
    check_resolves_press(profile, dt, " (flex)")
    tip = scene.fingertip
    check_depth(profile, tip.radius, " (flex)")
    if calibrate:  # an uncorrected press measures the mesh itself (its calibration), not an answer for a user
        check_holds("flex", obj, profile, " (flex)")
    t_prof = np.asarray(profile.t, dtype=float)
    z_prof = np.asarray(profile.z, dtype=float)
    if t_prof.ndim != 1 or t_prof.shape != z_prof.shape or len(t_prof) < 2 or np.any(np.diff(t_prof) <= 0):
        raise ValidationError("flex: profile.t must be strictly increasing and match profile.z in shape")
    if not (np.all(np.isfinite(z_prof)) and np.isfinite(profile.x) and np.isfinite(profile.y)):
        raise ValidationError("flex: profile z, x, y must be finite (m)")
    check_step_budget(t_prof[-1] - t_prof[0], dt, max_steps, " (flex)")
    times = profile.step_times(dt)
    n = len(times)
    x, y = float(profile.x), float(profile.y)
    surface_z = float(profile.surface_z)
    grid = flex_grid(obj, x, y, res, window)
    shallowest = (MIN_CONTACT_OVER_CELL * grid.finest) ** 2 / tip.radius
    if float(profile.meta.get("depth", np.inf)) < shallowest:
        raise ValidationError(
            f"flex resolves presses from {shallowest * 1e3:.2f} mm deep with {res * 1e3:g} mm cells (a contact "
            f"radius of {MIN_CONTACT_OVER_CELL} cells), not {profile.meta['depth'] * 1e3:.3f} mm: press deeper or "
            "use fidelity 'analytic' or 'rigid'")
    fm, data = _model(scene, obj, grid, dt, verts_per_cell, models)
    model = fm.model
    model.opt.iterations = int(iterations)  # the cached model keeps the last press's limit otherwise
    z0 = float(np.interp(times[0], t_prof, z_prof))
    model.body_pos[fm.tip_body] = [x, y, z0]
    mujoco.mj_forward(model, data)
    cell = grid.finest
    pinned_fraction = 0.0 if grid.far_sides else sum(grid.pinned) / len(grid.pinned)
    under = material_under(obj, x, y, obj.height)
    nu = float((under or obj.materials()[0]).poisson)
    curve = None
    if calibrate:
        mesh = load_calibration() if tables is None else tables.mesh
        curve = mesh_curve(nu, cell / tip.radius, mesh, obj.height, pinned_fraction)
    mixing = mixing_at(fm, obj, x, y, tip.radius) if calibrate else None
    # a stiff top layer in the plate window: the block's kappa over-corrects a plate (flex_plate)
    skin = plate_skin(obj) if calibrate and grid.far_sides else None
    plate = None if skin is None else plate_curve(load_plate_calibration() if tables is None else tables.plate, skin,
                                                  obj.height, cell / tip.radius)
    # a lump under the press: the surface vertices over its pocket, which neither kappa nor the mixing sees (flex_lump)
    pocket = pocket_at(obj, grid, fm.cell_young, fm.cell_poisson, x, y) if calibrate and fm.lateral else None
    # r was measured on lumps centred on the axis; off it, it did not help (docs/results.md, off-axis lumps): faded to 1
    lump = None if pocket is None else lump_curve(load_lump_calibration() if tables is None else tables.lump,
                                                  pocket.moduli, cell / tip.radius, pocket.centring)
    qadr = model.jnt_qposadr[fm.tip_joint]
    gid = fm.tip_geom
    inertia_steps = 0

    setpoints = np.interp(times, t_prof, z_prof) - z0
    # velocity and acceleration feedforward (a robot controller's), so the servo follows the press's reversal.
    # The discrete integrator is implicit Euler (drive stiffness and damping at the step's end), so the control of
    # step k that lands the tip on setpoint k at the setpoint's own speed takes the backward differences ending at
    # k: central ones start braking a step before a sharp reversal and turn round short of the depth.
    vel = np.diff(setpoints, prepend=setpoints[0]) / dt
    acc = np.diff(vel, prepend=0.0) / dt
    inertia = float(model.dof_armature[model.jnt_dofadr[fm.tip_joint]] + model.body_mass[fm.tip_body])
    lead = setpoints + (_damping(model) * vel + inertia * acc) / fm.kp
    tip_z = np.empty(n)
    force = np.empty(n)
    pressure = np.empty((n, tip.rows, tip.cols))
    factors = np.ones(n)
    extrapolated = False
    min_dist = 0.0
    pushed = 0.0  # MuJoCo's contact force on the tip at the last step, N
    for k in range(n):
        # the drive is told the force it will meet (last step's), as a robot's force feedforward: without it a
        # stiff block leaves the tip short of its setpoint by F / kp
        data.ctrl[0] = lead[k] - pushed / fm.kp
        if k > 0:
            before = inertia_warnings(data)
            mujoco.mj_step(model, data)
            inertia_steps += inertia_warnings(data) > before
        check_warnings(model, data, timestep=dt, context=" (flex)")
        check_dropped(data, timestep=dt, context=" (flex)")
        if not np.all(np.isfinite(data.qacc)) or not np.all(np.isfinite(data.qpos)):
            raise _diverged("non-finite state", times[k], dt)
        zc = z0 + data.qpos[qadr]
        tip_z[k] = zc
        ind_k = surface_z - (zc - tip.radius)
        ncon = data.ncon
        force[k] = 0.0
        pressure[k] = 0.0
        pushed = 0.0
        if not ncon:
            continue
        con = data.contact
        mine = np.any(con.geom[:ncon] == gid, axis=1) & (con.efc_address[:ncon] >= 0)
        if not mine.any():
            continue
        fn = np.clip(data.efc_force[con.efc_address[:ncon][mine]], 0.0, None)
        pushed = float(fn.sum())
        pos = con.pos[:ncon][mine]
        pen = -float(con.dist[:ncon][mine].min())
        min_dist = min(min_dist, -pen)
        # a sound contact penetrates a small fraction of the indentation; more means the tip is passing through
        # the surface and the force no longer comes from the block's elasticity
        if pen > PENETRATION_LIMIT and pen > PENETRATION_FRACTION * ind_k:
            raise _diverged(f"the tip penetrates the flex surface by {pen * 1e3:.2f} mm at {ind_k * 1e3:.2f} mm "
                            "indentation", times[k], dt)
        if calibrate:
            contact = np.sqrt(tip.radius * max(ind_k, 0.0)) * (1.0 if mixing is None else mixing.contact_at(ind_k))
            factor = curve.at(contact / cell)
            factors[k] = (factor.kappa * (1.0 if mixing is None else mixing.at(max(ind_k, 0.0)))
                          * (1.0 if plate is None else plate.at(contact / cell))
                          * (1.0 if lump is None else lump.at(contact / cell)))
            extrapolated |= (factor.extrapolated or (plate is not None and plate.extrapolated(contact / cell))
                             or (lump is not None and lump.extrapolated(contact / cell)))
        fn = fn / factors[k]
        force[k] = fn.sum()
        pressure[k] = sensel_pressure(pad_coordinates(pos - [x, y, zc], tip.radius), fn, tip, PATCH * fm.vertex_spacing)
        if zc - tip.radius < 0.02 * obj.height:
            raise _diverged("the tip sank through the flex block", times[k], dt)
        if not np.isfinite(force[k]):
            raise _diverged("non-finite contact force", times[k], dt)

    indentation = np.clip(surface_z - (tip_z - tip.radius), 0.0, None)
    _check_force_order(times, force, indentation, dt)
    depth_cmd = float(profile.meta.get("depth", 0.0))
    reached = depth_cmd + float(np.min(setpoints) - np.min(tip_z - z0))
    check_reached(reached, float(force.max()), profile, " (flex)", check_force=False, knobs=(
        f"the flex tip drive (kp {fm.kp:.3g} N/m) lags this press: pass a shorter timestep (now {dt:g} s) or a "
        "slower press"))
    trace = PhysicsTrace(
        t=times,
        tip_position=np.column_stack([np.full(n, x), np.full(n, y), tip_z]),
        tip_quaternion=np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)),
        sensel_pressure=pressure,
        force=force,
        indentation=indentation,
        surface_z=surface_z,
        material=None if under is None else under.name,
        meta={
            "fidelity": "flex", "timestep": dt, "integrator": "discrete", "resolution": res,
            "cell": grid.finest, "cells": list(grid.cells),
            "window_lower": [float(v) for v in grid.lower], "window_size": [float(v) for v in grid.size],
            "pinned_sides": list(grid.pinned), "far_sides": grid.far_sides, "disc_radius": grid.disc_radius,
            "mesh_factor_range": [float(factors.min()), float(factors.max())],
            "calibration_extrapolated": bool(extrapolated), "mixing_corrected": mixing is not None,
            "plate_corrected": plate is not None, "lump_corrected": lump is not None,
            "young_range": fm.meta["young_range"],
            "materials": sorted(set(fm.cell_material)), "vertex_patch": fm.vertex_spacing,
            "contact_solref": list(CONTACT_SOLREF), "kp": fm.kp, "max_contact_penetration": -min_dist,
            "dofs": int(model.nv), "seed": int(seed),
            "solver_warnings": SolverWarnings(steps=n - 1, inertia_steps=inertia_steps,
                                              iterations=int(iterations)).to_dict(),
            "target": None if target is None else {"x": target.x, "y": target.y, "depth": target.depth,
                                                   "force": target.force, "speed": target.speed},
            "press_end": float(profile.meta.get("phases", {}).get("press", [0.0, times[int(np.argmin(tip_z))]])[1]),
        },
    )
    trace.check_finite()
    return trace


def _damping(model) -> float:
    """The tip drive's damping kv, N s/m (MuJoCo stores a position actuator's -kv in biasprm[2])."""
    return float(-model.actuator_biasprm[0, 2])


def _check_force_order(t: np.ndarray, force: np.ndarray, indentation: np.ndarray, dt: float) -> None:
    """Raise SimulationDiverged if the force falls by over 10% of its peak while the indentation grows.

    An elastic block never pushes back less when pressed deeper; the coarse flex grid does once the tip sinks
    between surface vertices at large strain of a very soft block (found by the stability matrix: 1 kPa, 8 mm
    into 10 mm). Smaller ripple (a few %) is the contact moving across vertices and is kept.
    """
    k = int(np.argmax(indentation))
    if k < 2 or force.max() <= 0:
        return
    order = np.argsort(indentation[: k + 1], kind="stable")
    f = force[: k + 1][order]
    drop = np.maximum.accumulate(f) - f
    i = int(np.argmax(drop))
    if drop[i] > 0.1 * f.max():
        raise SimulationDiverged(
            f"flex: the force falls by {drop[i]:.3g} N (peak {f.max():.3g} N) while the indentation grows to "
            f"{indentation[: k + 1][order][i] * 1e3:.2f} mm (timestep {dt} s): the tip is sinking between the "
            "surface vertices; press less deep, or use fidelity 'analytic' or 'rigid'"
        )


def reference_press(*, young: float, poisson: float = 0.3, height: float = 0.02, radius: float = 0.008,
                    resolution: float = DEFAULT_RESOLUTION, timestep: float | None = None,
                    depth: float = 0.004, speed: float = 0.01, window: float = DEFAULT_WINDOW, width: float = 0.1,
                    calibrate: bool = True, damping: float = 0.0, layers: tuple = (), inclusions: tuple = (),
                    models: dict | None = None, tables: FlexTables | None = None) -> PhysicsTrace:
    """One robot press at the centre of a ``width``-wide box of one material (calibration and benchmarks): the
    window's sides are pinned where it cuts the block, as in a press on a large object.

    Args: moduli Pa, lengths m, speed m/s, timestep s; layers/inclusions as in :class:`ObjectSpec`; models and
    tables as in :func:`run_flex_press`.
    """
    mat = Material("bulk", young=young, poisson=poisson, damping=damping)
    obj = ObjectSpec(name="block", shape="box", size=(width, width, height), position=(0.0, 0.0),
                     material=mat, layers=tuple(layers), inclusions=tuple(inclusions))
    scene = Scene(objects=(obj,), fingertip=FingertipSpec(radius=radius))
    target = PressTarget(x=0.0, y=0.0, depth=depth, speed=speed)
    profile = press_profile(target, height, radius=radius, timestep=min(timestep or 0.002, 0.002))
    return run_flex_press(scene, obj, target, profile, timestep=timestep, resolution=resolution,
                          window=window, calibrate=calibrate, models=models, tables=tables)
