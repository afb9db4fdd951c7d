"""The rigid rung's force: a press point's contact law mapped onto the tip's footprint on the object's real top
(cells of equal clearance feel the law's pressure at the radius of a flat top's; see :mod:`palpate.sim.rigid`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.world.scene import ObjectSpec
from palpate.sim.contact.law import ContactLaw
from palpate.sim.fingertip import cap_height
from palpate.sim.scene import surface_heights


@dataclass(frozen=True)
class FootprintCells:
    """Polar cells over the tip's footprint disc: ``points`` (n, 2) cell centres from the tip axis, m; ``area``
    (n,) exact cell areas, m^2."""

    points: np.ndarray
    area: np.ndarray


@dataclass(frozen=True)
class Footprint:
    """The tip's footprint on an object: ``radius`` (k,) the distinct equivalent radii of its cells (m; 1 m for a
    cell off the object), ``area`` (k,) their summed areas (m^2), ``first_contact`` the height (m) of the sphere's
    lowest point when it first touches."""

    radius: np.ndarray
    area: np.ndarray
    first_contact: float


def footprint_rings(radius: float, rings: int, sectors: int) -> FootprintCells:
    """Polar cells over the tip's footprint disc of ``radius`` m.

    Rings are concentric with the tip axis, where a press on a flat top starts, so small contacts are resolved
    by whole rings (a flat top gives one clearance per ring).
    """
    edges = np.linspace(0.0, radius, rings + 1)
    r = 0.5 * (edges[1:] + edges[:-1])
    theta = (np.arange(sectors) + 0.5) * 2.0 * np.pi / sectors
    pts = np.stack([np.outer(r, np.cos(theta)), np.outer(r, np.sin(theta))], axis=-1).reshape(-1, 2)
    area = np.repeat(np.pi * (edges[1:] ** 2 - edges[:-1] ** 2) / sectors, sectors)
    return FootprintCells(points=pts, area=area)


def equivalent_radius(clearance: np.ndarray, radius: float) -> np.ndarray:
    """Radius (m) at which a flat top has ``clearance`` (m) under a sphere of ``radius``; inf past the equator."""
    h = np.asarray(clearance, dtype=float)
    # clip before squaring: an infinite clearance (a pad cell beyond the tip's rim) would give inf - inf
    hc = np.minimum(h, radius)
    return np.where(h < radius, np.sqrt(np.maximum(2.0 * radius * hc - hc * hc, 0.0)), np.inf)


def law_pressure(law: ContactLaw, depth: np.ndarray, r_eq: np.ndarray, rows: np.ndarray | None = None,
                 weights: np.ndarray | None = None) -> np.ndarray:
    """The law's pressure (Pa) at radii r_eq (..., m) for indentations ``depth`` (n,) m: shape (n, ...).

    Beyond the law's deepest tabulated depth the pressure grows as a Hertz contact would (d^0.5 at fixed r / a),
    which only a runaway reaches (and the run then stops with its error). ``rows``: a boolean mask (n,) of the
    depths wanted; the others are left 0 (a table read at a few heights need not evaluate the rest). ``weights``
    (r_eq's last axis, e.g. a sensel's quadrature weights): return the pressure summed with them instead, (n, ...)
    without the last axis, without spreading the unwanted rows over every point: for r_eq of several axes (a
    sensel's points) bit for bit ``law_pressure(...) @ weights``; for one axis a BLAS product over fewer rows may
    round the last bit otherwise (the rigid press's force table keeps the whole product)."""
    d = np.maximum(np.asarray(depth, dtype=float), 0.0)
    over = d > law.max_depth
    basis = law.basis_at(np.minimum(d, law.max_depth))
    scale = np.ones_like(d)
    if over.any():
        scale[over] = np.sqrt(d[over] / law.max_depth)
    b, c = basis.radii * scale[:, None], basis.coeffs
    r_eq = np.asarray(r_eq, dtype=float)
    # each distinct radius once (a pad or footprint on a flat top repeats its radii by symmetry), and only the
    # (depth, radius) pairs inside the contact: each term evaluated as a dense sum over all pairs would be
    r_u, inverse = np.unique(r_eq.reshape(-1), return_inverse=True)
    rr = r_u**2
    b2 = b**2  # once per depth, not once per (depth, radius) pair
    hit = rr[None, :] < b2[:, -1][:, None]
    if rows is not None:
        hit &= np.asarray(rows, dtype=bool)[:, None]
    di, ri = np.nonzero(hit)
    out = np.zeros((len(d), rr.size))
    terms = c[di] * np.sqrt(np.maximum(b2[di] - rr[ri, None], 0.0))
    out[di, ri] = np.sum(terms, axis=-1) * scale[di]
    if weights is None:
        # C order, as a dense evaluation gives it: a BLAS product over it then sums in the same order
        return np.ascontiguousarray(out[:, inverse.reshape(-1)]).reshape((len(d),) + r_eq.shape)
    # only the rows some pair touched: the others sum to exactly 0 (every term 0.0); each wanted row is the same
    # dense row, summed by the same product, as the full table's
    touched = np.flatnonzero(hit.any(axis=1))
    summed = np.zeros((len(d),) + r_eq.shape[:-1])
    if touched.size:
        dense = np.ascontiguousarray(out[touched][:, inverse.reshape(-1)]).reshape((touched.size,) + r_eq.shape)
        summed[touched] = dense @ np.asarray(weights, dtype=float)
    return summed


def contact_geometry(obj: ObjectSpec, centre_xy: np.ndarray, tip, mesh=None, *, rings: int = 96, sectors: int = 24,
                     cells: FootprintCells | None = None) -> Footprint:
    """Footprint of a tip above ``centre_xy`` (m) on ``obj``. ``cells``: precomputed :func:`footprint_rings`."""
    cells = footprint_rings(tip.radius, rings, sectors) if cells is None else cells
    pts, areas = cells.points, cells.area
    gaps = surface_heights(obj, centre_xy[:2] + pts, mesh) - cap_height(tip, pts)
    # the rings' centres miss the axis, where a flat top is first touched
    g_ref = max(float(np.max(gaps)), float(surface_heights(obj, np.asarray(centre_xy[:2])[None, :], mesh)[0]))
    r_eq = equivalent_radius(g_ref - gaps, tip.radius)
    keys = np.round(np.where(np.isfinite(r_eq), r_eq, 1.0) / 1e-8).astype(np.int64)
    _, inverse = np.unique(keys, return_inverse=True)
    weight = np.bincount(inverse, weights=areas)
    r_u = np.bincount(inverse, weights=np.where(np.isfinite(r_eq), r_eq, 1.0) * areas) / weight
    return Footprint(radius=r_u, area=weight, first_contact=g_ref)


def rigid_depth_for_force(obj: ObjectSpec, centre_xy: np.ndarray, tip, law: ContactLaw, force: float,
                          mesh=None, tables: dict | None = None) -> float:
    """Indentation (m) at which the rigid fidelity's force (the law on the footprint above ``centre_xy``) reaches
    ``force`` N; the force target's depth, consistent with what :func:`run_rigid_press` will feel. ``tables``: a dict
    the caller keeps (a SimSource does) for the force against depth of each law and footprint, so that presses on
    one flat top (a training block's) tabulate it once; the answer is the same with it or without."""
    foot = contact_geometry(obj, np.asarray(centre_xy, dtype=float), tip, mesh)
    d, f = _force_against_depth(law, foot, tables)
    if not force <= f[-1]:
        raise ValidationError(f"a {force:.3g} N force target needs more than {law.max_depth * 1e3:.2f} mm on "
                              f"{obj.name!r} (the fidelity reaches {f[-1]:.3g} N there); lower the force target")
    return float(np.interp(force, f, d))


#: Force tables a ``tables`` dict of :func:`rigid_depth_for_force` keeps before it starts again (~6 kB each).
MAX_FORCE_TABLES = 256


def _force_against_depth(law: ContactLaw, foot: Footprint, tables: dict | None) -> tuple[np.ndarray, np.ndarray]:
    """(depths (401,) m, forces (401,) N) of ``law`` on ``foot``; kept in ``tables`` by everything they depend on:
    the law's arrays (laws of different press points are often equal, as on a flat top), the footprint's radii and
    areas."""
    key = None
    if tables is not None:
        key = (law.tip_radius, law.surface_modulus, law.contact_radius.tobytes(), law.depth.tobytes(),
               law.force.tobytes(), law.coeffs.tobytes(), law.coeffs.shape, foot.radius.tobytes(), foot.area.tobytes())
        hit = tables.get(key)
        if hit is not None:
            return hit
    d = law.max_depth * (np.arange(401) / 400.0) ** 2
    f = law_pressure(law, d, foot.radius) @ foot.area
    if tables is not None:
        if len(tables) >= MAX_FORCE_TABLES:
            tables.clear()
        d.flags.writeable = f.flags.writeable = False  # shared between presses
        tables[key] = (d, f)
    return d, f
