"""``analytic`` fidelity: the contact law of the press point in closed form, the tip following the profile exactly.

The force, contact radius and surface pressure against indentation come from the press point's
:class:`~palpate.sim.contact.law.ContactLaw` (:func:`palpate.sim.bem.law.press_law`): the exact sphere on the
object's layer stack on the rigid table (finite thickness and layers exactly: Sneddon's sphere on a thick block,
the bonded-layer stiffening on a thin one); where the top changes material within the contact (a wall), that
column law scaled to the surface solve's force; where the material varies otherwise within reach of the press (an
inclusion, a nearby edge), the object averaged around the press axis and solved axisymmetrically. Each sensel
reports the mean of the law's pressure p(r) = sum_k c_k sqrt(b_k^2 - r^2) over its square footprint, each Hertz
profile integrated over the footprint in closed form (four corner integrals of the spherical cap).

Validity: quasi-static (damping ignored), flat surface under the tip (the object's own curvature is ignored),
linear elasticity (small strain: the law is refused beyond 0.75 tip radii deep); off-axis inclusions and edges are
averaged around the axis; the image is axisymmetric (over a wall only ``bem`` renders which side carries more).
The measured error against the FE reference per situation is the validity table (``palpate bench``,
models/validity_table.json) that ``auto`` reads. No MuJoCo is needed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.world.scene import Material, ObjectSpec, Scene, material_at
from palpate.sim.bem.law import press_law
from palpate.sim.blas import one_blas_thread
from palpate.sim.contact.law import ContactLaw
from palpate.sim.controller import PressProfile
from palpate.sim.fingertip import sensel_bounds
from palpate.sim.limits import check_holds
from palpate.sim.stability import check_depth, check_resolves_press, law_depth
from palpate.sim.trace import PhysicsTrace


def _quadrant_inside(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Integral of sqrt(1 - u^2 - v^2) over [0, x] x [0, y] for x, y >= 0 with x^2 + y^2 <= 1 (the corner on or
    inside the unit circle): the inner integral in v in closed form, the outer one by parts."""
    z = np.sqrt(np.maximum(1.0 - x * x - y * y, 0.0))
    return (x * y * z / 3.0 + y * (3.0 - y * y) / 6.0 * np.arctan2(x, z) + x * (3.0 - x * x) / 6.0 * np.arctan2(y, z)
            - np.arctan2(x * y, z) / 3.0)


def _quadrant(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Integral of sqrt(1 - u^2 - v^2) over the unit disc's part of [0, x] x [0, y], odd in x and in y: a
    rectangle's integral is four of these at its corners."""
    ax, ay = np.minimum(np.abs(x), 1.0), np.minimum(np.abs(y), 1.0)
    # beyond the circle at height ay the columns are whole half-chords: (pi / 4) (1 - u^2) du
    inner = np.minimum(ax, np.sqrt(np.maximum(1.0 - ay * ay, 0.0)))
    rest = 0.25 * np.pi * ((ax - ax**3 / 3.0) - (inner - inner**3 / 3.0))
    return np.sign(x) * np.sign(y) * (_quadrant_inside(inner, ay) + rest)


def _rect_integrals(a: np.ndarray, x0: np.ndarray, x1: np.ndarray, y0: np.ndarray, y1: np.ndarray) -> np.ndarray:
    """Integral of sqrt(a^2 - x^2 - y^2) over rectangles [x0, x1] x [y0, y1] cut by the disc r < a (a > 0), all
    (P,), m^3: exact (closed form)."""
    u0, u1, v0, v1 = x0 / a, x1 / a, y0 / a, y1 / a
    return a**3 * (_quadrant(u1, v1) - _quadrant(u0, v1) - _quadrant(u1, v0) + _quadrant(u0, v0))


@dataclass(frozen=True)
class PadSets:
    """A pad's sensels about a fixed contact centre: ``area`` (S,) m^2 per sensel, ``uniq`` (U, 4) the rectangles
    integrated (x0, x1, y0, y1 relative to the centre, m), ``inverse`` (S,) which of them each sensel is."""

    area: np.ndarray
    uniq: np.ndarray
    inverse: np.ndarray


def pad_sets(bounds: np.ndarray, centre: np.ndarray | None = None, share_symmetric: bool = True) -> PadSets:
    """The rectangles :func:`hertz_sensel_pressure` integrates for sensel footprints ``bounds`` (rows, cols, 4), m,
    about a fixed ``centre`` (2,) m (default the axis): one per set of mirror images with ``share_symmetric``."""
    rect = bounds.reshape(-1, 4)
    area = (rect[:, 1] - rect[:, 0]) * (rect[:, 3] - rect[:, 2])
    c = np.zeros(2) if centre is None else np.asarray(centre, dtype=float)
    rel = rect - np.array([c[0], c[0], c[1], c[1]])
    if not share_symmetric:
        return PadSets(area, rel, np.arange(len(rel)))
    # mirror each rectangle into x0 + x1 >= 0, y0 + y1 >= 0, then order the two axes: mirror images about the
    # centre collapse onto one key
    xs = np.where((rel[:, :1] + rel[:, 1:2]) < 0, -rel[:, 1::-1], rel[:, :2])
    ys = np.where((rel[:, 2:3] + rel[:, 3:4]) < 0, -rel[:, 3:1:-1], rel[:, 2:])
    swap = (xs[:, 0] > ys[:, 0]) | ((xs[:, 0] == ys[:, 0]) & (xs[:, 1] > ys[:, 1]))
    canon = np.where(swap[:, None], np.hstack([ys, xs]), np.hstack([xs, ys]))
    keys: dict[tuple, int] = {}
    inverse = np.array([keys.setdefault(tuple(row), len(keys)) for row in np.round(canon, 12).tolist()])
    uniq = canon[[int(np.argmax(inverse == u)) for u in range(len(keys))]]
    return PadSets(area, uniq, inverse)


def hertz_sensel_pressure(
    depth: np.ndarray, young_eff: float, radius: float, bounds: np.ndarray, centre: np.ndarray | None = None,
    share_symmetric: bool = True, pad: PadSets | None = None,
) -> np.ndarray:
    """Mean Hertz pressure over each sensel, Pa.

    Args:
        depth: indentations, m, shape (n,).
        young_eff: E*, Pa, one value or one per depth (n,).
        radius: tip radius, m.
        bounds: sensel footprints (rows, cols, 4) as (x0, x1, y0, y1), m, in the pad plane.
        centre: contact centre in the pad plane, m, shape (n, 2), or (2,) for a fixed centre; default the axis.
        share_symmetric: with a fixed centre, integrate once per set of sensels that are mirror images of
            each other about the centre (the pressure is radially symmetric), e.g. 3 of 16 for a centred pad.
        pad: :func:`pad_sets` of ``bounds`` and the fixed ``centre``, when the caller keeps it (presses of one pad).

    Returns:
        (n, rows, cols) mean pressure, Pa (0 where not in contact).
    """
    d = np.maximum(np.atleast_1d(np.asarray(depth, dtype=float)), 0.0)
    n = d.shape[0]
    rows, cols = bounds.shape[:2]
    a_all = np.sqrt(radius * d)
    fixed = centre is None or np.asarray(centre).shape == (2,)
    if fixed:
        if pad is None:
            pad = pad_sets(bounds, centre, share_symmetric)
        area, inverse, uniq = pad.area, pad.inverse, pad.uniq
        gap_x = np.maximum(np.maximum(uniq[:, 0], -uniq[:, 1]), 0.0)
        gap_y = np.maximum(np.maximum(uniq[:, 2], -uniq[:, 3]), 0.0)
        hit = (gap_x**2 + gap_y**2)[None, :] < a_all[:, None] ** 2  # (n, U)
        vals = np.zeros(hit.shape)
        if hit.any():
            ti, ui = np.nonzero(hit)
            vals[hit] = _rect_integrals(a_all[ti], uniq[ui, 0], uniq[ui, 1], uniq[ui, 2], uniq[ui, 3])
        integral = vals[:, inverse.reshape(-1)]
    else:
        rect = bounds.reshape(-1, 4)
        area = (rect[:, 1] - rect[:, 0]) * (rect[:, 3] - rect[:, 2])
        c = np.asarray(centre, dtype=float)
        if c.shape != (n, 2):
            raise ValidationError(f"hertz_sensel_pressure: centre must have shape (2,) or ({n}, 2), got {c.shape}")
        rel = rect[None, :, :] - np.stack([c[:, 0], c[:, 0], c[:, 1], c[:, 1]], axis=-1)[:, None, :]
        gap_x = np.maximum(np.maximum(rel[..., 0], -rel[..., 1]), 0.0)
        gap_y = np.maximum(np.maximum(rel[..., 2], -rel[..., 3]), 0.0)
        hit = gap_x**2 + gap_y**2 < a_all[:, None] ** 2
        integral = np.zeros(hit.shape)
        if hit.any():
            ak = np.broadcast_to(a_all[:, None], hit.shape)[hit]
            r = rel[hit]
            integral[hit] = _rect_integrals(ak, r[:, 0], r[:, 1], r[:, 2], r[:, 3])
    ye = np.asarray(young_eff, dtype=float)
    if ye.ndim:
        if ye.shape != (n,):
            raise ValidationError(f"hertz_sensel_pressure: young_eff must be one value or shape ({n},), got {ye.shape}")
        ye = ye[:, None]
    # p = p0 sqrt(1 - r^2/a^2) = (2 E* / (pi R)) sqrt(a^2 - r^2) for Hertz (p0 = 2 E* a / (pi R))
    out = 2.0 * ye / (np.pi * radius) * integral / area[None, :]
    return out.reshape(n, rows, cols)


def law_sensel_pressure(law: ContactLaw, depth: np.ndarray, bounds: np.ndarray, centre: np.ndarray | None = None,
                        pad: PadSets | None = None) -> np.ndarray:
    """Mean pressure (Pa) of ``law``'s contact over each sensel at indentations ``depth`` (m), (n, rows, cols):
    the sum of the law's Hertz profiles, each integrated by :func:`hertz_sensel_pressure` (``pad``: its
    :func:`pad_sets` for a fixed ``centre``, when the caller keeps them)."""
    d = np.maximum(np.atleast_1d(np.asarray(depth, dtype=float)), 0.0)
    basis = law.basis_at(d)
    radii, coeffs = basis.radii, basis.coeffs
    radius = law.tip_radius
    n, k_max = radii.shape
    # c sqrt(b^2 - r^2) is a Hertz profile of a tip of radius R at depth b^2 / R with E* = c pi R / 2: every
    # profile of every depth in one call (profile-major), summed profile by profile as separate calls would be
    c = None if centre is None or np.asarray(centre).shape == (2,) else np.tile(np.asarray(centre, float), (k_max, 1))
    every = hertz_sensel_pressure((radii**2 / radius).T.reshape(-1), (coeffs * np.pi * radius / 2.0).T.reshape(-1),
                                  radius, bounds, centre if c is None else c,
                                  pad=pad if c is None else None)
    every = every.reshape((k_max, n) + bounds.shape[:2])
    out = np.zeros((n,) + bounds.shape[:2])
    for k in range(k_max):
        out += every[k]
    return np.maximum(out, 0.0)


def material_under(obj: ObjectSpec, x: float, y: float, surface_z: float) -> Material | None:
    """The material just under the surface at (x, y) m, top at ``surface_z`` m: the one a tip presses first (None
    outside the object)."""
    return material_at(obj, np.array([[x, y, surface_z - 1e-6]]))[0]


def local_material(obj: ObjectSpec, x: float, y: float, surface_z: float) -> Material:
    """Material just under the surface at (x, y): the one the tip presses first."""
    mat = material_under(obj, x, y, surface_z)
    if mat is None:
        raise ValidationError(f"object {obj.name!r} has no material under ({x:.4f}, {y:.4f}) m; press on the object")
    return mat


@dataclass(frozen=True)
class AnalyticSamples:
    """One analytic press up to its sensel pressures: sample times ``t`` (n,) s, indentations ``depth`` (n,) m, tip
    positions ``pos`` (n, 3) m, its contact ``law``, the material at the surface, the contact centre in the pad plane
    (2,) m, the pad's sensel footprints ``bounds`` (rows, cols, 4) m and their :class:`PadSets`, the sampling rate
    (Hz) and the surface height (m)."""

    t: np.ndarray
    depth: np.ndarray
    pos: np.ndarray
    law: ContactLaw
    material: Material
    centre: np.ndarray
    bounds: np.ndarray
    pad: PadSets
    rate: float
    surface_z: float


def run_analytic_press(
    scene: Scene, obj: ObjectSpec, profile: PressProfile, *, rate: float | None = None,
    law: ContactLaw | None = None, pads: dict | None = None,
) -> PhysicsTrace:
    """The press-and-release under the contact law, sampled at ``rate`` Hz (sensors interpolate between samples).

    Args:
        scene: the scene (fingertip geometry).
        obj: the pressed object (the trace names the material at the surface).
        profile: the press trajectory; the tip follows it exactly.
        rate: sampling rate of the trace, Hz; by default the taxel rate, so every taxel frame falls on an
            exactly integrated sample (the pose sensor interpolates position, smooth at this rate); the deepest
            point of the profile is sampled as well.
        law: the press point's contact law (computed here when not given; a SimSource caches it).
        pads: a dict the caller keeps (a SimSource does) for the pad's sensel footprints and their symmetric sets,
            by fingertip and contact centre: the presses of one pad share them.

    Raises:
        ValidationError: a press deeper than 0.75 tip radii, or too short for the sampling rate.
    """
    s = analytic_samples(scene, obj, profile, rate=rate, law=law, pads=pads)
    pressure = law_sensel_pressure(s.law, s.depth, s.bounds, s.centre, pad=s.pad)
    return analytic_trace(s, pressure)


def analytic_samples(
    scene: Scene, obj: ObjectSpec, profile: PressProfile, *, rate: float | None = None,
    law: ContactLaw | None = None, pads: dict | None = None,
) -> AnalyticSamples:
    """:func:`run_analytic_press` up to the sensel pressures (same arguments and refusals): a batch of presses
    integrates the pressures of many at once (:mod:`palpate.sim.batch`)."""
    rate = scene.taxels.rate if rate is None else rate
    if not (np.isfinite(rate) and rate > 0):
        raise ValidationError(f"run_analytic_press: rate must be > 0 Hz, got {rate!r}")

    # a press shorter than two samples would be missed: zero force, silently (the sensor could not see it either)
    check_resolves_press(profile, 1.0 / rate, f" (analytic, sampled at the {rate:g} Hz taxel rate)", min_steps=2,
                         knobs="a slower or deeper press, or a higher taxel rate")
    tip = scene.fingertip
    radius = tip.radius
    if abs(profile.meta.get("radius", radius) - radius) > 1e-12:
        raise ValidationError(
            f"press profile was made for a tip radius {profile.meta.get('radius')} m, the scene's is {radius} m"
        )
    check_depth(profile, radius, " (analytic)")
    check_holds("analytic", obj, profile, " (analytic)")
    mat = local_material(obj, profile.x, profile.y, profile.surface_z)
    grid = profile.t[0] + np.arange(max(int(np.floor(profile.duration * rate)) + 1, 2)) / rate
    # the deepest point too, so the trace's peak is the press's (a taxel frame between samples interpolates)
    t = np.union1d(grid, [float(profile.t[int(np.argmin(profile.z))])])
    z = profile.at(t)
    depth = np.maximum(profile.surface_z + radius - z, 0.0)
    if law is None:
        with one_blas_thread():  # its FE solves (an inclusion, an edge within reach): see palpate.sim.blas
            law = press_law(obj, profile.x, profile.y, profile.surface_z, tip, law_depth(profile))
    normal = np.asarray(profile.meta.get("normal", (0.0, 0.0, 1.0)), dtype=float)
    # the contact is where the sphere faces the surface: at -R n in the tip frame, projected on the pad plane
    centre = -radius * normal[:2]
    contact = np.array([profile.x, profile.y, profile.surface_z])
    pos = contact[None, :] + normal[None, :] * (z - profile.surface_z)[:, None]
    key = (tip, float(centre[0]), float(centre[1]))
    found = None if pads is None else pads.get(key)
    if found is None:
        bounds = sensel_bounds(tip)
        found = (bounds, pad_sets(bounds, centre))
        if pads is not None:
            pads[key] = found
    return AnalyticSamples(t, depth, pos, law, mat, centre, found[0], found[1], float(rate),
                           profile.surface_z)


def analytic_trace(s: AnalyticSamples, pressure: np.ndarray) -> PhysicsTrace:
    """The trace of an analytic press from its samples and its sensel pressures (n, rows, cols), Pa."""
    quat = np.tile([1.0, 0.0, 0.0, 0.0], (len(s.t), 1))
    trace = PhysicsTrace(
        t=s.t, tip_position=s.pos, tip_quaternion=quat, sensel_pressure=pressure,
        force=s.law.force_at(s.depth), indentation=s.depth, surface_z=s.surface_z,
        material=s.material.name,
        meta={"fidelity": "analytic", "rate": s.rate, "young_eff_surface": float(s.material.effective_modulus),
              "contact_law_max_depth": s.law.max_depth},
    )
    trace.check_finite()
    return trace
