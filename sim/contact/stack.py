"""The contact law of a press point: what the tip feels of an object (layers, inclusions, a haptic-material map,
nearby edges) pressed at (x, y).

Where the object is laterally uniform within reach of the press (every depth one material across a disc of radius
1.5 a + depth, a the deepest contact radius), it is exactly its column of layers on the rigid table, and the law is
the layered solution (:mod:`.law`). Otherwise (an inclusion, a map boundary, an edge within reach) the object is
averaged around the press axis and solved axisymmetrically (:mod:`.axisymmetric`). Presses take
:func:`palpate.sim.bem.law.press_law`, which replaces that average by the surface solve's force where the top itself
changes material within the contact (a wall: the average is up to ~47% off there).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.world.scene import Layer, Material, ObjectSpec, material_index_at
from palpate.sim.contact.axisymmetric import (
    FIRST_ORDER_LIMIT,
    axisymmetric_law,
    column_energy,
    first_order_law,
    lateral_effect,
)
from palpate.sim.contact.law import ContactLaw, solve_contact_law
from palpate.sim.reference.sample import AxisymmetricSample

#: Reach of lateral variation: a disc of radius REACH_A * a + depth at each depth.
REACH_A = 1.5
#: The key under which a law cache keeps its FE meshes (:func:`palpate.sim.reference.fe.fe_presses`).
_MESHES = ("fe-meshes",)


def object_breaks(obj: ObjectSpec, surface_z: float) -> list[float]:
    """Depths below ``surface_z`` (m) where the object's material may change along a vertical line."""
    out, z = [], 0.0
    for layer in obj.layers:
        z += layer.thickness
        out.append(z)
    for inc in obj.inclusions:
        cz = inc.center[2]
        if inc.shape == "sphere":
            out += [surface_z - cz - inc.size[0], surface_z - cz + inc.size[0]]
        elif inc.shape == "box":
            out += [surface_z - (cz + inc.size[2] / 2.0), surface_z - (cz - inc.size[2] / 2.0)]
    return sorted(b for b in out if 0.0 < b < surface_z)


def object_radial_breaks(obj: ObjectSpec, x: float, y: float) -> list[float]:
    """Horizontal distances from (x, y) (m) where an inclusion's side may be met (nearest and farthest faces)."""
    out = []
    for inc in obj.inclusions:
        dx, dy = abs(inc.center[0] - x), abs(inc.center[1] - y)
        if inc.shape == "sphere":
            r = inc.size[0]
            dist = math.hypot(dx, dy)
            out += [abs(dist - r), dist + r]
        else:
            hx, hy = inc.size[0] / 2.0, inc.size[1] / 2.0
            near = math.hypot(max(dx - hx, 0.0), max(dy - hy, 0.0))
            if near == 0.0:
                near = min(hx - dx, hy - dy)
            out += [near, math.hypot(dx + hx, dy + hy)]
    return sorted(b for b in out if b > 0)


def object_lookup(obj: ObjectSpec, x: float, y: float, surface_z: float):
    """fn(offsets (n, 2) m from (x, y), depths (n,) m below ``surface_z``) -> (Young Pa, Poisson, inside mask)."""
    palette = obj.materials()
    names = [m.name for m in palette]
    young = np.array([m.young for m in palette] + [1.0])
    poisson = np.array([m.poisson for m in palette] + [0.3])

    def lookup(offsets: np.ndarray, depths: np.ndarray):
        pts = np.column_stack([x + offsets[:, 0], y + offsets[:, 1], surface_z - depths])
        idx = material_index_at(obj, pts, names)
        return young[idx], poisson[idx], idx >= 0

    return lookup


def sample_lookup(sample: AxisymmetricSample):
    """The same kind of lookup for an axisymmetric sample (its inclusion and free side included)."""

    def lookup(offsets: np.ndarray, depths: np.ndarray):
        r = np.hypot(offsets[:, 0], offsets[:, 1])
        e, nu = sample.materials_at(r, depths)
        return e, nu, r <= sample.radius

    return lookup


def sample_breaks(sample: AxisymmetricSample) -> list[float]:
    """Depths where an axisymmetric sample's material may change along a vertical line."""
    out = list(sample.interfaces())
    if sample.inclusion is not None:
        out += [sample.inclusion.depth, sample.inclusion.bottom]
    return sorted(b for b in out if 0.0 < b < sample.thickness)


def _depth_edges(thickness: float, breaks: list[float], step: float) -> np.ndarray:
    edges = sorted({0.0, thickness, *breaks})
    out = [0.0]
    for z0, z1 in zip(edges[:-1], edges[1:], strict=True):
        n = max(1, int(math.ceil((z1 - z0) / step)))
        out += list(z0 + (z1 - z0) * np.arange(1, n + 1) / n)
    return np.array(out)


def column_stack(lookup, thickness: float, breaks: list[float], base: str = "bonded") -> AxisymmetricSample:
    """The layers along the press axis, on a rigid base ``thickness`` m down."""
    edges = sorted({0.0, thickness, *breaks})
    mid = 0.5 * (np.array(edges[1:]) + np.array(edges[:-1]))
    young, poisson, inside = lookup(np.zeros((len(mid), 2)), mid)
    if not np.all(inside):
        raise ValidationError("contact law: no material under the press point")
    merged: list[list[float]] = []
    for z0, z1, e, nu in zip(edges[:-1], edges[1:], young, poisson, strict=True):
        if merged and merged[-1][2] == e and merged[-1][3] == nu:
            merged[-1][1] = z1
        else:
            merged.append([z0, z1, float(e), float(nu)])
    mats = [Material(f"layer{i}", young=e, poisson=nu) for i, (_, _, e, nu) in enumerate(merged)]
    layers = tuple(Layer(m, z1 - z0) for m, (z0, z1, _, _) in zip(mats[:-1], merged[:-1], strict=True))
    return AxisymmetricSample(bulk=mats[-1], thickness=thickness, layers=layers, base=base)


@dataclass(frozen=True)
class ReachProbe:
    """The material sampled where a press reaches (whether it varies decides the law's path, and its fingerprint
    keys the cached law).

    Attributes:
        young, poisson: E (Pa) and nu at each probe point: rings of 16 points out to REACH_A a + depth, at the
            middle of each depth slice.
        inside: whether each probe point is inside the object (off it counts as a change: an edge).
        axis_young, axis_poisson: E and nu on the press axis at each probe point's depth.
    """

    young: np.ndarray
    poisson: np.ndarray
    inside: np.ndarray
    axis_young: np.ndarray
    axis_poisson: np.ndarray

    def varies(self) -> bool:
        """True if some probe point is off the object or not the axis' material at its depth."""
        same = self.inside & (self.young == self.axis_young) & (self.poisson == self.axis_poisson)
        return not bool(np.all(same))

    def fingerprint(self) -> bytes:
        """The sampled field as bytes: two press points whose surroundings sample alike share a cached law."""
        return b"".join(np.ascontiguousarray(a).tobytes() for a in (self.young, self.poisson, self.inside))


def reach_probe(lookup, thickness: float, breaks: list[float], contact_radius: float) -> ReachProbe:
    """Sample ``lookup`` over the disc of radius REACH_A a + depth around the press axis, at every depth slice."""
    step = max(contact_radius / 2.0, thickness / 40.0)
    edges = _depth_edges(thickness, breaks, step)
    mid = 0.5 * (edges[1:] + edges[:-1])
    rho = np.linspace(0.0, 1.0, 7)[1:]
    theta = np.arange(16) * np.pi / 8.0
    unit = (rho[:, None, None] * np.stack([np.cos(theta), np.sin(theta)], axis=-1)[None]).reshape(-1, 2)
    radius = REACH_A * contact_radius + mid
    offsets = (radius[:, None, None] * unit[None]).reshape(-1, 2)
    young, poisson, inside = lookup(offsets, np.repeat(mid, len(unit)))
    axis_e, axis_nu, _ = lookup(np.zeros((len(mid), 2)), mid)
    return ReachProbe(np.asarray(young, float), np.asarray(poisson, float), np.asarray(inside, bool),
                      np.repeat(axis_e, len(unit)), np.repeat(axis_nu, len(unit)))


def point_law(lookup, thickness: float, breaks: list[float], tip_radius: float, max_depth: float, *,
              base: str = "bonded", breaks_r=(), cache: dict | None = None, place=None,
              lateral: bool = True) -> ContactLaw:
    """The contact law at a press point given its material ``lookup`` (see the module docstring).

    ``cache`` (a dict the caller keeps, e.g. one per SimSource) reuses laws: layered ones by their stack (any
    press point with the same column), axisymmetric ones by ``place`` (a hashable naming the press point).
    ``lateral=False`` takes the column's layers only, whatever varies around (for a caller that cannot wait for
    the axisymmetric solve, e.g. a servo emulator answering in real time).
    """
    a_deep = 1.2 * math.sqrt(tip_radius * max_depth)
    probe = reach_probe(lookup, thickness, breaks, a_deep) if lateral else None
    lateral = probe is not None and probe.varies()
    if not lateral:
        stack = column_stack(lookup, thickness, breaks, base)
        key = ("layered", tip_radius, _signature(stack))
    else:
        # the place names the point; the probe tells objects apart that share a name and place but not materials
        # (a bench pressing blocks of several moduli, a calibration trying moduli)
        key = ("axisymmetric", tip_radius, place, probe.fingerprint()) if place is not None else None
    if cache is not None and key is not None:
        hit = cache.get(key)
        if hit is not None and hit.max_depth >= max_depth:
            return hit
    if not lateral:
        law = solve_contact_law(stack, tip_radius, max_depth)
    else:
        e, nu, _ = lookup(np.zeros((1, 2)), np.array([1e-7]))
        surface = Material("surface", young=float(e[0]), poisson=float(nu[0]))
        column = point_law(lookup, thickness, breaks, tip_radius, max_depth, base=base, cache=cache, lateral=False)

        def column_lookup(offsets: np.ndarray, depths: np.ndarray):
            young, poisson, _ = lookup(np.zeros_like(offsets), depths)  # the axis' material, everywhere
            return young, poisson, np.ones(len(depths), dtype=bool)

        energy = _column_energy(lookup, thickness, breaks, tip_radius, max_depth, base, cache)
        effect = lateral_effect(lookup, column_lookup, energy)
        if np.max(np.abs(effect)) <= FIRST_ORDER_LIMIT:
            law = first_order_law(column, energy, effect)
        else:
            law = axisymmetric_law(lookup, thickness, tip_radius, max_depth, base=base, breaks_z=breaks,
                                   breaks_r=breaks_r, surface=surface, column=column, column_lookup=column_lookup)
    if cache is not None and key is not None:
        if len(cache) > 512:  # a long run pressing everywhere must not grow without bound
            cache.clear()
        cache[key] = law
    return law


def _column_energy(lookup, thickness: float, breaks: list[float], tip_radius: float, max_depth: float, base: str,
                   cache: dict | None):
    """The press point column's FE energy shares (:func:`.axisymmetric.column_energy`), cached by its stack.

    Linear elasticity: moduli all scaled by one factor leave the energy shares as they are and scale the forces and
    pressures by it, so stacks alike but for that factor (blocks of two materials of one Poisson ratio) share one
    FE: the kept answer's shares, its forces and pressures scaled (shares equal to ~1e-15, as two solves give)."""
    stack = column_stack(lookup, thickness, breaks, base)
    top = stack.layers[0].material.young if stack.layers else stack.bulk.young
    key = ("energy", tip_radius, round(max_depth, 7), _signature(stack, top))  # its shares depend on the depths
    hit = cache.get(key) if cache is not None else None
    if hit is not None:
        energy, young = hit
        if young == top:
            return energy
        return replace(energy, force=energy.force * (top / young), pressure=energy.pressure * (top / young))
    # the FE meshes too: columns of one geometry (a run's training blocks) share one
    meshes = cache.setdefault(_MESHES, {}) if cache is not None else None
    energy = column_energy(stack, tip_radius, max_depth, breaks, meshes)
    if cache is not None:
        cache[key] = (energy, top)
    return energy


def _signature(stack: AxisymmetricSample, unit: float = 1.0) -> tuple:
    """The stack as a key, moduli in ``unit`` Pa (the top's modulus: stacks alike up to one factor share a key)."""
    return (stack.base, round(stack.thickness, 9), stack.bulk.young / unit, stack.bulk.poisson,
            tuple((round(la.thickness, 9), la.material.young / unit, la.material.poisson) for la in stack.layers))


def object_law(obj: ObjectSpec, x: float, y: float, surface_z: float, tip_radius: float,
               max_depth: float, cache: dict | None = None, lateral: bool = True) -> ContactLaw:
    """The contact law of ``obj`` pressed at (x, y) (m) with its top at ``surface_z`` (m), up to ``max_depth`` m;
    the object's bottom is bonded to the table (as the flex fidelity pins it). ``cache``: see :func:`point_law`
    (press points 0.1 mm apart share an axisymmetric law)."""
    place = (obj.name, round(x / 1e-4), round(y / 1e-4), round(surface_z / 1e-6))
    return point_law(object_lookup(obj, x, y, surface_z), surface_z, object_breaks(obj, surface_z), tip_radius,
                     max_depth, breaks_r=object_radial_breaks(obj, x, y), cache=cache, place=place, lateral=lateral)


def sample_law(sample: AxisymmetricSample, tip_radius: float, max_depth: float) -> ContactLaw:
    """The contact law the closed-form fidelities use for an axisymmetric sample."""
    breaks_r = [sample.inclusion.radius] if sample.inclusion is not None else []
    if math.isfinite(sample.radius):
        breaks_r.append(sample.radius)
    return point_law(sample_lookup(sample), sample.thickness, sample_breaks(sample), tip_radius, max_depth,
                     base=sample.base, breaks_r=breaks_r)
