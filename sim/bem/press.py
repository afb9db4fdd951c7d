"""``bem`` fidelity: the press's contact solved on the surface as boundary elements, the tip following the profile.

The surface around the press point is cut into square cells, each with the layer stack under it
(:mod:`.surface`); at a ladder of indentations the frictionless contact of the exact sphere is solved for the cell
pressures (:mod:`.solve`), each warm-started from the last; the force is their sum and each sensel the mean over
its footprint. Between the solved indentations, the neighbouring solutions are stretched as a growing contact is
(:func:`between`) and blended.

Unlike ``analytic``, whose image is axisymmetric, the image follows where the material is:
over a wall the harder side carries more, a lump beside the axis tilts the image. Validity: quasi-static, flat top,
linear elasticity, frictionless; the compliance between two different columns is a local-compliance mean (see
:mod:`.surface`), measured against the 3-D FE reference in the validity table.
"""

from __future__ import annotations

import math

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.world.scene import ObjectSpec, Scene
from palpate.sim.analytic import local_material
from palpate.sim.bem.solve import CELL, ContactOutgrown, on_grid, solve_fields
from palpate.sim.bem.surface import Surface, build_surface
from palpate.sim.bem.wall import WallTable
from palpate.sim.contact.stack import object_law
from palpate.sim.controller import PressProfile
from palpate.sim.limits import check_holds
from palpate.sim.stability import check_depth, check_resolves_press, law_depth
from palpate.sim.trace import PhysicsTrace

#: Indentations solved per press.
LADDER = 10


def law_scaled(force: np.ndarray, pressure: np.ndarray, depth: np.ndarray, law) -> tuple[np.ndarray, np.ndarray]:
    """The surface solve's force (N, (m,)) and sensel pressures (Pa, (m, ...)) at ``depth`` (m, (m,)) rescaled at
    each depth to the contact law's force there: the image keeps its shape, the force is the law's (a buried change,
    :attr:`.surface.Surface.buried`, where the axisymmetric law holds the force and the surface the image)."""
    target = law.force_at(depth)
    scale = np.divide(target, force, out=np.zeros_like(target), where=force > 0)
    return np.where(force > 0, target, 0.0), pressure * scale.reshape((-1,) + (1,) * (pressure.ndim - 1))


def force_from_law(surface: Surface, force: np.ndarray, pressure: np.ndarray, depth: np.ndarray,
                   law_for) -> tuple[np.ndarray, np.ndarray]:
    """The surface solve's force and sensel pressures at ``depth`` (m), as :func:`law_scaled` makes them where the
    surface's change is buried (a lump under a shared top: the force is the press point's law's, ``law_for()``,
    asked only then), as solved elsewhere."""
    if not surface.buried:
        return force, pressure
    return law_scaled(force, pressure, depth, law_for())


def between(surface: Surface, nodes: np.ndarray, fields: np.ndarray, depth: np.ndarray) -> tuple[np.ndarray,
                                                                                                 np.ndarray]:
    """Force (N) and sensel pressures (Pa, (m, rows * cols)) at any ``depth`` (m, (m,)) from the fields solved at
    ``nodes`` (m, increasing, > 0): each neighbouring solution stretched as a contact grows (positions by s, pressure
    by s, s = sqrt(d / node), the force by s^3, as Hertz's do exactly), the two blended linearly in sqrt(d).

    A contact's edge thus moves continuously across the sensels between solved depths, which interpolating each
    sensel's value cannot do where the contact first reaches it."""
    from scipy.ndimage import map_coordinates

    cell = surface.cell
    at, lo, shape = on_grid(surface)
    grids = np.zeros((len(nodes),) + shape)
    grids[:, at[:, 0], at[:, 1]] = fields
    d = np.clip(np.asarray(depth, dtype=float), 0.0, nodes[-1])
    root = np.sqrt(nodes)
    hi = np.clip(np.searchsorted(nodes, d), 0, len(nodes) - 1)
    below = np.maximum(hi - 1, 0)
    weight = np.where(hi > below, (np.sqrt(d) - root[below]) / np.maximum(root[hi] - root[below], 1e-30), 1.0)
    node_force = fields.sum(axis=1) * cell * cell
    force = np.zeros(len(d))
    sensels = np.zeros((len(d), surface.overlap.shape[0]))
    pressed = np.flatnonzero(d > 0)
    if not len(pressed):
        return force, sensels
    # every (depth, neighbouring node) stretch in one call: the node is an exact integer coordinate of the stacked
    # grids, so the interpolation along it only picks that node's plane
    k = np.stack([below[pressed], hi[pressed]], axis=1)  # (p, 2)
    w = np.stack([1.0 - weight[pressed], weight[pressed]], axis=1)
    s = np.sqrt(d[pressed, None] / nodes[k])
    planar = surface.centres[None, None, :, :] / (s[..., None, None] * cell) - 0.5 - lo  # (p, 2, n, 2)
    coords = np.stack([np.broadcast_to(k[..., None], planar.shape[:3]), planar[..., 0], planar[..., 1]])
    values = map_coordinates(grids, coords.reshape(3, -1), order=1, mode="constant", cval=0.0)
    blend = np.einsum("pj,pjn->pn", w * s, values.reshape(planar.shape[:3]))
    force[pressed] = np.sum(w * s**3 * node_force[k], axis=1)
    sensels[pressed] = blend @ surface.overlap.T
    return force, sensels


def run_bem_press(scene: Scene, obj: ObjectSpec, profile: PressProfile, *, rate: float | None = None,
                  cell: float = CELL, ladder: int = LADDER, walls: WallTable | None = None,
                  law_for=None) -> PhysicsTrace:
    """The press-and-release solved on the surface, sampled at ``rate`` Hz (default the taxel rate).

    Args:
        scene: the scene (fingertip and pad geometry).
        obj: the pressed object.
        profile: the press trajectory; the tip follows it exactly (quasi-static).
        rate: sampling rate of the trace, Hz.
        cell: boundary-element side, m.
        ladder: indentations solved between 0 and the deepest; the rest are interpolated.
        walls: the wall table (read from models/ when a wall is met and none is given; a SimSource passes its own).
        law_for: ``law_for(max_depth m)`` -> the press point's contact law, asked only where the material changes
            under a shared top layer (:func:`law_scaled`); default :func:`palpate.sim.contact.stack.object_law`
            solved here (a SimSource passes its cached laws).

    Raises:
        ValidationError: a press deeper than 0.75 tip radii or than the rung holds (:mod:`palpate.sim.limits`), too
            short for the rate, or off the object.
    """
    rate = scene.taxels.rate if rate is None else rate
    if not (np.isfinite(rate) and rate > 0):
        raise ValidationError(f"run_bem_press: rate must be > 0 Hz, got {rate!r}")
    if not (math.isfinite(cell) and cell > 0 and ladder >= 2):
        raise ValidationError(f"run_bem_press: need cell > 0 m and ladder >= 2, got {cell!r}, {ladder!r}")
    check_resolves_press(profile, 1.0 / rate, f" (bem, sampled at the {rate:g} Hz taxel rate)", min_steps=2,
                         knobs="a slower or deeper press, or a higher taxel rate")
    tip = scene.fingertip
    radius = tip.radius
    check_depth(profile, radius, " (bem)")
    check_holds("bem", obj, profile, " (bem)")
    mat = local_material(obj, profile.x, profile.y, profile.surface_z)
    grid = profile.t[0] + np.arange(max(int(np.floor(profile.duration * rate)) + 1, 2)) / rate
    t = np.union1d(grid, [float(profile.t[int(np.argmin(profile.z))])])
    z = profile.at(t)
    depth = np.maximum(profile.surface_z + radius - z, 0.0)
    d_max = float(depth.max())
    force = np.zeros(len(t))
    pressure = np.zeros((len(t), tip.rows, tip.cols))
    mixing = "none"
    if d_max > 0:
        nodes = d_max * (np.arange(1, ladder + 1) / ladder) ** 2
        # cells beyond the contact carry nothing; the pad's corners past it need no cells. A stiff top spreads
        # the contact wider than Hertz's radius: the surface grows until the contact fits inside it
        reach = min(1.05 * math.sqrt(radius * d_max) + 2 * cell, 0.995 * radius)
        while True:
            surface = build_surface(obj, profile.x, profile.y, profile.surface_z, tip, reach, cell,
                                    math.sqrt(radius * d_max), walls)
            try:
                fields = solve_fields(surface, radius, nodes)
                break
            except ContactOutgrown:
                if reach >= 0.995 * radius:
                    raise ValidationError(f"bem: the contact outgrows the tip's footprint ({reach * 1e3:.1f} mm) "
                                          "at this depth; press shallower or use fidelity 'rigid'") from None
                reach = min(1.3 * reach, 0.995 * radius)
        mixing = surface.mixing
        # the release retraces the press (quasi-static elasticity): each distinct depth is computed once
        unique, back = np.unique(np.round(depth, 12), return_inverse=True)
        deepest = max(law_depth(profile), d_max)
        f_u, p_u = force_from_law(surface, *between(surface, nodes, fields, unique), unique,
                                  lambda: law_for(deepest) if law_for is not None
                                  else object_law(obj, profile.x, profile.y, profile.surface_z, radius, deepest))
        force = f_u[back]
        pressure = p_u[back].reshape(len(t), tip.rows, tip.cols)
    normal = np.asarray(profile.meta.get("normal", (0.0, 0.0, 1.0)), dtype=float)
    contact = np.array([profile.x, profile.y, profile.surface_z])
    pos = contact[None, :] + normal[None, :] * (z - profile.surface_z)[:, None]
    trace = PhysicsTrace(
        t=t, tip_position=pos, tip_quaternion=np.tile([1.0, 0.0, 0.0, 0.0], (len(t), 1)),
        sensel_pressure=pressure, force=force, indentation=depth, surface_z=profile.surface_z, material=mat.name,
        meta={"fidelity": "bem", "rate": float(rate), "cell": float(cell), "ladder": int(ladder), "mixing": mixing,
              "force_from_law": bool(d_max > 0 and surface.buried),
              "young_eff_surface": float(mat.effective_modulus)},
    )
    trace.check_finite()
    return trace

