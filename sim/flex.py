"""The `flex` fidelity: a MuJoCo deformable block (trilinear flexcomp with linear elasticity) pressed by the tip.

What it models: finite thickness, layers and inclusions, large indentation, with the object's bottom bonded to the
table. What it does not: the block is a *window* of the object around the press point (at most ``window`` wide,
full height); where the window cuts through the object its side faces are pinned (the material around it is
treated as rigid), free object edges stay free. A cylinder is modelled by the square inscribed in it; meshes are
not supported. Gravity is off so that the undeformed top stays at the object's height.

Validity limits (see benchmarks/flex_resolution.py for the measured table):
- The elastic field is trilinear per cell (cell edge ``resolution``, default 6.5 mm, ~0.8 tip radius), far
  coarser than the Hertz contact radius at small indentation, so the raw block is ~2x stiffer than Hertz and its
  force-indentation exponent is ~1.4 rather than 1.5. The modulus is divided by a calibrated factor
  (:mod:`palpate.sim.flex_calibration`) so that a thick homogeneous block matches Hertz in 0.3-1.5 mm.
- Layers and inclusions are resolved per cell: each cell takes the material at its centre (stiffness matrix
  rebuilt from that material's Lame parameters). Features thinner than a cell are smeared or lost.
- Damping is one value per flex (MuJoCo has no per-cell damping): the largest damping of the materials present.
- Contact is frictionless (condim 1) with the direct solref form; lateral jitter of the press point is applied
  as a fixed offset (the tip moves only vertically).

Taxels: each contact's normal force is spread over the pad by the skin model, a Gaussian of width ``skin_sigma``
on the pad plane (the pad is wrapped onto the sphere by arc length), and averaged over each sensel square exactly
(erf products), so the pressure field conserves the force and is smooth even when only a few flex vertices touch.
"""

from __future__ import annotations

import numpy as np

from palpate.core.errors import SimulationDiverged, ValidationError
from palpate.core.session.sources import PressTarget
from palpate.core.world.scene import FingertipSpec, Material, ObjectSpec, Scene, material_index_at
from palpate.sim.controller import press_profile
from palpate.sim.flex_calibration import modulus_factor
from palpate.sim.flex_model import (
    CONTACT_SOLREF,
    DEFAULT_RESOLUTION,
    DEFAULT_TIMESTEP,
    DEFAULT_WINDOW,
    build_flex_model,
    flex_grid,
)
from palpate.sim.stability import check_resolves_press
from palpate.sim.trace import PhysicsTrace

#: Contact penetration, m, beyond which (and beyond PENETRATION_FRACTION of the indentation) the run diverged.
#: Soft blocks at large strain report up to ~55% (the sphere bulges between coarse surface vertices).
PENETRATION_LIMIT = 5.0e-4
PENETRATION_FRACTION = 0.65


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


def sensel_pressure(pad_xy: np.ndarray, forces: np.ndarray, fingertip: FingertipSpec,
                    skin_sigma: float) -> np.ndarray:
    """Mean pressure over each sensel, Pa, shape (rows, cols), from point forces spread by a Gaussian skin.

    Args:
        pad_xy: (k, 2) force positions on the pad plane, m (see :func:`pad_coordinates`).
        forces: (k,) normal forces, N, >= 0.
        fingertip: pad layout.
        skin_sigma: standard deviation of the skin's spreading kernel, m.
    """
    # scipy.special costs ~0.3 s to import; only a flex press needs it, so every CLI start and sweep worker that
    # never runs one does not pay for it
    from scipy.special import ndtr

    centres = fingertip.sensel_centres().reshape(-1, 2)
    if len(forces) == 0:
        return np.zeros((fingertip.rows, fingertip.cols))
    half = fingertip.sensel_size / 2.0
    d = centres[None, :, :] - np.asarray(pad_xy)[:, None, :]  # (k, s, 2)
    # exact mean of a Gaussian over a square: product of 1-D erf differences
    frac = np.prod(ndtr((d + half) / skin_sigma) - ndtr((d - half) / skin_sigma), axis=2)
    p = np.asarray(forces) @ frac / fingertip.sensel_area
    return p.reshape(fingertip.rows, fingertip.cols)


def _diverged(what: str, t: float, timestep: float) -> SimulationDiverged:
    return SimulationDiverged(
        f"flex: {what} at t={t:.4f} s (timestep {timestep} s); reduce the timestep, the press speed or the "
        "stiffness (a coarser resolution or softer material), or stiffen the contact solref"
    )


def run_flex_press(scene: Scene, obj: ObjectSpec, target, profile, *, timestep: float | None = None,
                   resolution: float | None = None, seed: int = 0, window: float = DEFAULT_WINDOW,
                   skin_sigma: float | None = None, calibrate: bool = True, verts_per_cell: int = 2,
                   kp: float | None = None) -> PhysicsTrace:
    """Simulate one press-and-release of ``obj`` with a deformable flex block; return the physics-rate trace.

    Args:
        scene: the scene (fingertip geometry and pad layout).
        obj: the pressed object (box or cylinder; materials, layers, inclusions).
        target: the press target (kept for the trace's provenance; the motion comes from ``profile``).
        profile: a PressProfile: t (s), z (tip-centre height setpoints, m), x, y (m), surface_z (m), meta.
        timestep: physics step, s (default 5 ms).
        resolution: elastic cell edge, m (default 6.5 mm).
        seed: recorded for provenance; the physics is deterministic and draws no random numbers.
        window: lateral size of the simulated window around the press point, m.
        skin_sigma: width of the skin's Gaussian spreading kernel, m (default: 0.6 x the contact vertex spacing,
            at least 1 mm).
        calibrate: divide moduli by the calibrated factor (False only to measure the calibration).
        verts_per_cell: collision vertices per cell edge.
        kp: tip position-actuator stiffness, N/m (default from the stiffest material).

    Returns:
        PhysicsTrace with sensel_pressure (n, rows, cols) Pa, force N (total normal contact force), indentation m
        (surface_z minus the tip's lowest point, clipped at 0).

    Raises:
        SimulationDiverged: a MuJoCo warning (bad qacc, instability), NaN, or the tip sinking through the block.
        ValidationError: unsupported object shape or bad parameters.
    """
    import mujoco

    dt = DEFAULT_TIMESTEP if timestep is None else float(timestep)
    res = DEFAULT_RESOLUTION if resolution is None else float(resolution)
    if not (np.isfinite(dt) and dt > 0):
        raise ValidationError(f"flex: timestep must be > 0 s, got {timestep!r}")

    check_resolves_press(profile, dt, " (flex)")
    t_prof = np.asarray(profile.t, dtype=float)
    z_prof = np.asarray(profile.z, dtype=float)
    if t_prof.ndim != 1 or t_prof.shape != z_prof.shape or len(t_prof) < 2 or np.any(np.diff(t_prof) <= 0):
        raise ValidationError("flex: profile.t must be strictly increasing and match profile.z in shape")
    if not (np.all(np.isfinite(z_prof)) and np.isfinite(profile.x) and np.isfinite(profile.y)):
        raise ValidationError("flex: profile z, x, y must be finite (m)")
    tip = scene.fingertip
    x, y = float(profile.x), float(profile.y)
    surface_z = float(profile.surface_z)
    grid = flex_grid(obj, x, y, res, window)
    factor, extrapolated = (modulus_factor(float(grid.cell[:2].mean()), tip.radius) if calibrate else (1.0, False))
    model, info = build_flex_model(scene, obj, grid, x, y, float(z_prof[0]), timestep=dt, factor=factor,
                                   verts_per_cell=verts_per_cell, kp=kp)
    data = mujoco.MjData(model)
    sigma = skin_sigma if skin_sigma is not None else max(1.0e-3, 0.6 * float(grid.cell[:2].min()) / verts_per_cell)
    qadr = model.jnt_qposadr[info["tip_joint"]]
    gid = info["tip_geom"]
    z0 = float(z_prof[0])
    warn = data.warning
    watched = [mujoco.mjtWarning.mjWARN_BADQACC, mujoco.mjtWarning.mjWARN_CNSTRFULL,
               mujoco.mjtWarning.mjWARN_CONTACTFULL]

    n = int(np.floor((t_prof[-1] - t_prof[0]) / dt + 1e-9)) + 1
    times = t_prof[0] + dt * np.arange(n)
    setpoints = np.interp(times, t_prof, z_prof) - z0
    tip_z = np.empty(n)
    force = np.empty(n)
    pressure = np.empty((n, tip.rows, tip.cols))
    min_dist = 0.0
    for k in range(n):
        data.ctrl[0] = setpoints[k]
        if k > 0:
            mujoco.mj_step(model, data)
        for w in watched:
            if warn[w].number:
                raise _diverged(f"MuJoCo warning {w.name}", times[k], dt)
        if not np.all(np.isfinite(data.qacc)) or not np.all(np.isfinite(data.qpos)):
            raise _diverged("non-finite state", times[k], dt)
        zc = z0 + data.qpos[qadr]
        tip_z[k] = zc
        ncon = data.ncon
        if ncon:
            con = data.contact
            mine = np.any(con.geom[:ncon] == gid, axis=1) & (con.efc_address[:ncon] >= 0)
            fn = data.efc_force[con.efc_address[:ncon][mine]]
            fn = np.clip(fn, 0.0, None)
            pos = con.pos[:ncon][mine]
            if mine.any():
                pen = -float(con.dist[:ncon][mine].min())
                min_dist = min(min_dist, -pen)
                ind_k = surface_z - (zc - tip.radius)
                # a sound contact penetrates a small fraction of the indentation; more means the tip is passing
                # through the surface and the force no longer comes from the block's elasticity
                if pen > PENETRATION_LIMIT and pen > PENETRATION_FRACTION * ind_k:
                    raise _diverged(f"the tip penetrates the flex surface by {pen * 1e3:.2f} mm at "
                                    f"{ind_k * 1e3:.2f} mm indentation", times[k], dt)
            force[k] = fn.sum()
            pressure[k] = sensel_pressure(pad_coordinates(pos - [x, y, zc], tip.radius), fn, tip, sigma)
        else:
            force[k] = 0.0
            pressure[k] = 0.0
        if zc - tip.radius < 0.02 * obj.height:
            raise _diverged("the tip sank through the flex block", times[k], dt)
        if not np.isfinite(force[k]):
            raise _diverged("non-finite contact force", times[k], dt)

    _check_force_order(times, force, np.clip(surface_z - (tip_z - tip.radius), 0.0, None), dt)
    mat_names = set(info["cell_material"])
    trace = PhysicsTrace(
        t=times,
        tip_position=np.column_stack([np.full(n, x), np.full(n, y), tip_z]),
        tip_quaternion=np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)),
        sensel_pressure=pressure,
        force=force,
        indentation=np.clip(surface_z - (tip_z - tip.radius), 0.0, None),
        surface_z=surface_z,
        material=_material_under(obj, x, y),
        meta={
            "fidelity": "flex",
            "timestep": dt,
            "integrator": "discrete",
            "resolution": res,
            "cell": [float(c) for c in grid.cell],
            "cells": list(grid.cells),
            "window_lower": [float(v) for v in grid.lower],
            "window_size": [float(v) for v in grid.size],
            "pinned_sides": list(grid.pinned),
            "calibration_factor": factor,
            "calibration_extrapolated": extrapolated,
            "young_used": info["young_used"],
            "materials": sorted(mat_names),
            "skin_sigma": float(sigma),
            "contact_solref": list(CONTACT_SOLREF),
            "kp": info["kp"],
            "max_contact_penetration": -min_dist,
            "seed": int(seed),
            "target": None if target is None else {"x": target.x, "y": target.y, "depth": target.depth,
                                                   "force": target.force, "speed": target.speed},
            "press_end": float(profile.meta.get("phases", {}).get("press", [0.0, times[int(np.argmin(tip_z))]])[1]),
        },
    )
    trace.check_finite()
    return trace


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
            "coarse surface vertices; press less deep (under ~50% of the thickness for very soft blocks), or use "
            "a finer resolution"
        )


def _material_under(obj: ObjectSpec, x: float, y: float) -> str | None:
    """Name of the material just under the surface at (x, y), None if outside."""
    mats = obj.materials()
    i = int(material_index_at(obj, np.array([[x, y, obj.height - 1e-6]]), [m.name for m in mats])[0])
    return mats[i].name if i >= 0 else None


def reference_press(*, young: float, poisson: float = 0.3, height: float = 0.02, radius: float = 0.008,
                    resolution: float = DEFAULT_RESOLUTION, timestep: float = DEFAULT_TIMESTEP,
                    depth: float = 0.004, speed: float = 0.01, window: float = DEFAULT_WINDOW,
                    calibrate: bool = True, damping: float = 0.0,
                    layers: tuple = (), inclusions: tuple = ()) -> PhysicsTrace:
    """One robot press at the centre of a ``window``-wide box of one material (calibration and benchmarks).

    Args: moduli Pa, lengths m, speed m/s, timestep s; layers/inclusions as in :class:`ObjectSpec`.
    """

    mat = Material("bulk", young=young, poisson=poisson, damping=damping)
    obj = ObjectSpec(name="block", shape="box", size=(window, window, height), position=(0.0, 0.0),
                     material=mat, layers=tuple(layers), inclusions=tuple(inclusions))
    scene = Scene(objects=(obj,), fingertip=FingertipSpec(radius=radius))
    target = PressTarget(x=0.0, y=0.0, depth=depth, speed=speed)
    profile = press_profile(target, height, radius=radius, timestep=timestep)
    return run_flex_press(scene, obj, target, profile, timestep=timestep, resolution=resolution,
                          window=window, calibrate=calibrate)
