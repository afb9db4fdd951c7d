"""The contact law of a press whose top changes material within its contact (a wall, a map boundary), read from
the surface solve.

The axisymmetric law (:mod:`palpate.sim.contact.stack`) averages the object around the press axis: beside a wall
its force is up to ~47% off the 3-D FE, where the surface solve (:mod:`.surface`, its wall coupling measured on the
3-D FE) stays within ~3% (docs/results.md, the image validity table). Here the press point's exact column law is
scaled, at each depth, by the surface solve's force against the same cells with that column everywhere (like
against like: the cells' own discretisation error cancels in the ratio, and a surface of one stack gives the
column law exactly). The pressure basis scales with the force: the ``analytic`` and ``rigid`` rungs keep their
axisymmetric image; the ``bem`` rung renders the real one.

Elsewhere (no change at the top within the contact, an edge or a buried change there, a material or layer the
surface solve does not hold) the axisymmetric law stands. A surface solve costs ~10 ms, an axisymmetric FE law
~100 ms.
"""

from __future__ import annotations

import math

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.world.scene import FingertipSpec, ObjectSpec
from palpate.sim.bem.kernel import Stack
from palpate.sim.bem.solve import CELL, ContactOutgrown, solve_fields
from palpate.sim.bem.surface import Surface, build_surface, column_stacks, uniform_surface
from palpate.sim.bem.wall import WallTable
from palpate.sim.contact.law import ContactLaw
from palpate.sim.contact.stack import object_law
from palpate.sim.limits import layer_refusal, poisson_refusal

#: Depths solved, as fractions of the deepest tabulated; the force ratio is held below the shallowest (where the
#: contact spans few cells) and interpolated in log depth between.
FRACTIONS = np.geomspace(1.0 / 8.0, 1.0, 8)


def surface_reach(tip_radius: float, max_depth: float) -> float:
    """Radius (m) of the surface a press ``max_depth`` m deep is solved on (as the ``bem`` rung's first try)."""
    return min(1.05 * math.sqrt(tip_radius * max_depth) + 2 * CELL, 0.995 * tip_radius)


def surface_columns(obj: ObjectSpec, x: float, y: float, surface_z: float, reach: float):
    """The columns under the surface cells within ``reach`` m of (x, y): (stack index per cell, the distinct
    stacks, whether each cell is on the object), as :func:`palpate.sim.bem.surface.column_stacks`."""
    span = int(math.ceil(reach / CELL))
    k = (np.arange(-span, span) + 0.5) * CELL
    gx, gy = np.meshgrid(k, k, indexing="ij")
    cells = np.column_stack([gx.ravel(), gy.ravel()])
    return column_stacks(obj, x, y, surface_z, cells[np.hypot(cells[:, 0], cells[:, 1]) <= reach])


def top_changes(stack_of: np.ndarray, stacks, on_object: np.ndarray) -> bool:
    """Whether every cell is on the object and their columns start with more than one material (a wall at the
    top, not a change buried under a shared top)."""
    tops = {(stacks[i].young[0], stacks[i].poisson[0]) for i in np.unique(stack_of)}
    return bool(on_object.all()) and len(tops) > 1


def may_change_at_top(obj: ObjectSpec, x: float, y: float, surface_z: float, reach: float) -> bool:
    """False when no inclusion reaching the top lies within ``reach`` m of (x, y) and no haptic-material map covers
    the object (then its top is one material there, and :func:`surface_columns` need not look)."""
    if obj.material_map is not None:
        return True
    for inc in obj.inclusions:
        cx, cy, cz = inc.center
        if inc.shape == "sphere":
            r = inc.size[0]
            if cz + r >= surface_z - 1e-7 and math.hypot(cx - x, cy - y) < reach + r:
                return True
            continue
        if inc.shape == "box" and cz + inc.size[2] / 2.0 < surface_z - 1e-7:
            continue  # buried: the top over it is the object's
        gap = math.hypot(max(abs(cx - x) - inc.size[0] / 2.0, 0.0), max(abs(cy - y) - inc.size[1] / 2.0, 0.0))
        if gap < reach:
            return True
    return False


def surface_law(obj: ObjectSpec, x: float, y: float, surface_z: float, tip: FingertipSpec, max_depth: float,
                column: ContactLaw, walls: WallTable | None = None, columns=None,
                cache: dict | None = None) -> ContactLaw | None:
    """The law of a press at (x, y) (m) up to ``max_depth`` m from the surface solve (module docstring), or None
    where it does not apply. ``column``: the press point's column law (laterally uniform) up to ``max_depth``;
    ``columns``: :func:`surface_columns` at :func:`surface_reach`, when the caller has them; ``cache``: a dict the
    caller keeps, where the uniform reference solve is kept (:func:`uniform_forces`)."""
    if poisson_refusal(obj, "bem") or layer_refusal(obj, "bem"):
        return None
    radius = tip.radius
    reach = surface_reach(radius, max_depth)
    depths = max_depth * FRACTIONS
    axis = None
    while True:
        if columns is None:
            columns = surface_columns(obj, x, y, surface_z, reach)
        if not top_changes(*columns):
            return None  # an edge within reach, or one material at the top
        try:
            surface = build_surface(obj, x, y, surface_z, tip, reach, CELL, math.sqrt(radius * max_depth), walls)
            if surface.buried:
                return None
            real = solve_fields(surface, radius, depths).sum(axis=1)
            if axis is None:
                # the column the column law has: the one on the axis itself (a cell beside it may lie across a wall)
                _, axis, _ = column_stacks(obj, x, y, surface_z, np.zeros((1, 2)))
            own = uniform_forces(surface, axis[0], reach, radius, depths, cache)
            break
        except ContactOutgrown:
            if reach >= 0.995 * radius:
                return None
            reach, columns = min(1.3 * reach, 0.995 * radius), None
        except ValidationError:  # a wall outside the wall table
            return None
    if not (np.all(real > 0) and np.all(own > 0)):
        return None
    ratio = real / own
    scale = np.interp(np.log(np.maximum(column.depth, depths[0])), np.log(depths), ratio)
    force = column.force * scale
    if np.any(np.diff(force) <= 0):
        return None
    return ContactLaw(tip_radius=column.tip_radius, contact_radius=column.contact_radius, depth=column.depth,
                      force=force, coeffs=column.coeffs * scale[:, None], surface_modulus=column.surface_modulus)


def uniform_forces(surface: Surface, stack: Stack, reach: float, tip_radius: float, depths: np.ndarray,
                   cache: dict | None = None) -> np.ndarray:
    """The summed cell pressures (Pa, (n,)) of ``surface``'s cells all over ``stack`` (:func:`uniform_surface`, built
    with ``reach`` m) pressed ``depths`` m: the reference a surface law is a ratio to. Kept in ``cache`` by all it
    depends on (the stack, the cells' side and centres, the reach, the tip and the depths): walls on one material,
    away from the object's edges, share it."""
    key = ("uniform", stack, surface.cell, reach, tip_radius, surface.centres.tobytes(), depths.tobytes())
    hit = cache.get(key) if cache is not None else None
    if hit is None:
        hit = solve_fields(uniform_surface(surface, stack, reach), tip_radius, depths).sum(axis=1)
        hit.setflags(write=False)
        if cache is not None:
            cache[key] = hit
    return hit


def press_law(obj: ObjectSpec, x: float, y: float, surface_z: float, tip: FingertipSpec, max_depth: float,
              cache: dict | None = None, walls: WallTable | None = None) -> ContactLaw:
    """The contact law of ``obj`` pressed at (x, y) (m) with its top at ``surface_z`` (m), up to ``max_depth`` m:
    :func:`surface_law` where the top changes within the contact, else
    :func:`palpate.sim.contact.stack.object_law`. ``cache``: a dict the caller keeps (shared with object_law's;
    press points 0.1 mm apart with the same materials around share a law)."""
    reach = surface_reach(tip.radius, max_depth)
    if not may_change_at_top(obj, x, y, surface_z, reach):
        return object_law(obj, x, y, surface_z, tip.radius, max_depth, cache=cache)
    stack_of, stacks, on_object = surface_columns(obj, x, y, surface_z, reach)
    if top_changes(stack_of, stacks, on_object):
        column = object_law(obj, x, y, surface_z, tip.radius, max_depth, cache=cache, lateral=False)
        # what the surface solve sees: every cell's column (the press point's among them)
        key = ("surface", tip.radius, obj.name, round(x / 1e-4), round(y / 1e-4), round(surface_z / 1e-6),
               stack_of.tobytes(), stacks)
        hit = cache.get(key) if cache is not None else None
        if hit is not None and hit.max_depth >= max_depth:
            return hit
        law = surface_law(obj, x, y, surface_z, tip, max_depth, column, walls, (stack_of, stacks, on_object), cache)
        if law is not None:
            if cache is not None:
                if len(cache) > 512:  # as object_law's: a long run pressing everywhere must not grow without bound
                    cache.clear()
                cache[key] = law
            return law
    return object_law(obj, x, y, surface_z, tip.radius, max_depth, cache=cache)
