"""Depth-weighted effective modulus under a spherical contact: what a press feels of layers and inclusions.

The closed-form fidelities (``analytic``, ``rigid``) take one modulus per contact. Taking the material *at* the
surface point makes a 1.5 mm skin over a hard base, or a hard lump 1 mm down, invisible. Here the modulus is an
average over the volume the contact strains: springs in series down each column under the contact (compliances
add with depth), columns in parallel across the footprint (the rigid tip imposes one displacement on all):

    E*_eff(a) = sum_j u_j E*_j,     1 / E*_j = sum_k w_k / E*(p_jk)        (sum_j u_j = sum_k w_k = 1)

over sample points p_jk of column j at depth k under a contact of radius a (m), with E* = E / (1 - nu^2) of the
material at each point.

Depth weight: the vertical stress on the axis under a circular Hertz-like load, sigma_z / p = 1 - z^3 / (a^2 +
z^2)^(3/2), whose integral from 0 to z is W(z) = z + 2a - sqrt(a^2 + z^2) - a^2 / sqrt(a^2 + z^2) (W(inf) = 2a).
Each depth cell [z_k, z_k+1] gets W(z_k+1) - W(z_k) exactly; the cells are finer near the surface (z ~ s^2), where
the weight and thin skins are. The weight is cut off at z_max = min(cutoff * a, depth to the table) and normalised
over [0, z_max]: the table is rigid (no compliance below the object) and a homogeneous object of any thickness
keeps exactly its E* (the stiffening of a thin object by the rigid table is not modelled, as before).

Lateral weight: at depth z the stress has spread over a radius ~ sqrt(a^2 + z^2) (Boussinesq: the load of a
point spreads over ~ z at depth z), so column j is the line through the points sqrt(a^2 + z^2) * rho_j (unit-disc
node rho_j, rings x sectors) and its weight u_j follows a Hertz pressure profile (rho sqrt(1 - rho^2) d rho). So
an inclusion beside the axis counts in part, one 2 cm away at palpation depths not at all. Sample points outside
the object (near an edge) are left out and the rest renormalised. Parallel columns keep a press 5 mm inside the
edge of a hard column in soft foam hard (a series average over the footprint let the few soft columns at the
rim halve it).

Validity: a first-order (series-springs) approximation, the same idea as the weight-function models of thin-film
indentation: it orders layered and inclusion stiffness correctly and tends to the right limits (skin's E* for a
shallow press, base's for a deep one). On a 20 kPa, 4 mm layer over a 10x stiffer base (20 mm high) it gives
1.56 / 1.70 / 1.82 / 1.92x the soft bulk at 1 / 1.5 / 2 / 2.5 mm, where flex measures 1.56 / 1.78 / 1.98 / 2.04x
(within 10%; tests/test_effective_modulus.py, physics marker). It fails where the layers do not act
in series: a thin *stiff* skin over a soft base carries load by bending (a plate), so the real press is stiffer
than this average says; lateral coupling (a soft spot inside hard material is held up by its neighbours) is
ignored, as in the rigid fidelity's local kernel; under large indentation (d > ~0.3 R) the stress field is no
longer Hertz's; and the model is linear, so a soft skin thinner than the press is deep never bottoms out (a 5 mm
press over a hard lump 1 mm under 24 kPa foam feels ~1/5 of the lump's modulus, where a real skin would be
crushed and the lump felt). For those, use ``flex``.
"""

from __future__ import annotations

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.world.scene import ObjectSpec, material_index_at
from palpate.sim.hertz import hertz_depth_for_force, hertz_force

#: Lateral spread of a column with depth: its radius is sqrt(a^2 + (SPREAD z)^2) (see the module docstring).
SPREAD = 0.5
#: Depth cut-off of the weight, in contact radii (beyond it < 4% of the half-space weight, 1.5 a / z of 2a).
DEPTH_CUTOFF = 10.0


def depth_weight_integral(z: np.ndarray, a: np.ndarray) -> np.ndarray:
    """W(z) = integral_0^z (1 - t^3 / (a^2 + t^2)^1.5) dt, m, for contact radii a (m); W(inf) = 2 a."""
    z = np.asarray(z, dtype=float)
    a = np.asarray(a, dtype=float)
    h = np.sqrt(a * a + z * z)
    return z + 2.0 * a - h - a * a / np.maximum(h, 1e-300)


def _lateral_nodes(rings: int, sectors: int) -> tuple[np.ndarray, np.ndarray]:
    """Unit-disc nodes (rings*sectors, 2) and their weights (sum 1) for a Hertz-like pressure profile."""
    edges = np.linspace(0.0, 1.0, rings + 1)
    rho = 0.5 * (edges[1:] + edges[:-1])
    # exact integral of rho sqrt(1 - rho^2) over each ring: -(1 - rho^2)^1.5 / 3
    ring_w = ((1.0 - edges[:-1] ** 2) ** 1.5 - (1.0 - edges[1:] ** 2) ** 1.5) / 3.0
    theta = (np.arange(sectors) + 0.5) * 2.0 * np.pi / sectors
    # stagger alternate rings so nodes do not line up radially (a thin inclusion is then hit by some ring)
    theta = theta[None, :] + (np.arange(rings)[:, None] % 2) * np.pi / sectors
    nodes = np.stack([rho[:, None] * np.cos(theta), rho[:, None] * np.sin(theta)], axis=-1).reshape(-1, 2)
    w = np.repeat(ring_w / sectors, sectors)
    return nodes, w / w.sum()


def effective_modulus_table(
    obj: ObjectSpec, x: float, y: float, surface_z: float, contact_radii: np.ndarray, *,
    n: int = 48, rings: int = 3, sectors: int = 8, cutoff: float = DEPTH_CUTOFF, spread: float = SPREAD,
) -> np.ndarray:
    """E*_eff, Pa, of pressing ``obj`` at (x, y) (m) with contact radius each of ``contact_radii`` (m).

    See the module docstring for the weights. Vectorised: one material look-up for every radius, depth and
    lateral point together. A radius of 0 gives the material's E* just under the surface.

    Args:
        obj: the pressed object (layers, inclusions, haptic-material map all count).
        x, y: press point, m; surface_z: height of the surface there, m (depths are measured down from it).
        contact_radii: (m,) contact radii, m, >= 0.
        n: depth cells; rings, sectors: lateral sample points per depth; cutoff: depth cut-off in radii.

    Returns:
        (m,) effective plane-strain moduli, Pa; exactly the material's E* where every sample is one material.
    """
    a = np.atleast_1d(np.asarray(contact_radii, dtype=float))
    if a.ndim != 1 or not np.all(np.isfinite(a)) or np.any(a < 0):
        raise ValidationError(f"effective_modulus: contact radii must be finite and >= 0 m, got {contact_radii!r}")
    if not (np.isfinite(surface_z) and surface_z > 0):
        raise ValidationError(f"effective_modulus: surface_z must be > 0 m (above the table), got {surface_z!r}")
    if n < 1 or rings < 1 or sectors < 1 or not cutoff > 0:
        raise ValidationError(f"effective_modulus: n, rings, sectors must be >= 1 and cutoff > 0; "
                              f"got {n}, {rings}, {sectors}, {cutoff}")
    palette = obj.materials()
    e_star = np.array([m.effective_modulus for m in palette])
    names = [m.name for m in palette]
    surface = material_index_at(obj, np.array([[x, y, surface_z - 1e-5]]), names)[0]
    if surface < 0:
        raise ValidationError(f"object {obj.name!r} has no material under ({x:.4f}, {y:.4f}) m; press on the object")

    z_max = np.minimum(cutoff * a, surface_z)  # (m,)
    s = np.linspace(0.0, 1.0, n + 1)
    z_edges = z_max[:, None] * s[None, :] ** 2  # (m, n+1): finer near the surface
    z_mid = 0.5 * (z_edges[:, 1:] + z_edges[:, :-1])
    w_depth = np.diff(depth_weight_integral(z_edges, a[:, None]), axis=1)  # (m, n)
    nodes, w_lat = _lateral_nodes(rings, sectors)
    b = np.sqrt(a[:, None] ** 2 + (spread * z_mid) ** 2)  # (m, n)
    xy = np.array([x, y]) + b[:, :, None, None] * nodes[None, None, :, :]  # (m, n, L, 2)
    zz = np.broadcast_to((surface_z - z_mid)[:, :, None, None], xy.shape[:-1] + (1,))
    pts = np.concatenate([xy, zz], axis=-1).reshape(-1, 3)
    idx = material_index_at(obj, pts, names).reshape(xy.shape[:-1])  # (m, n, L)

    inside = idx >= 0
    # series along each column (compliances add with depth), then parallel across columns (the rigid tip
    # imposes one displacement, so their stiffnesses add)
    w = w_depth[:, :, None] * inside  # (m, n, L)
    compliance = np.where(inside, 1.0 / e_star[np.maximum(idx, 0)], 0.0)
    col_w = w.sum(axis=1)  # (m, L)
    col_c = np.sum(w * compliance, axis=1)
    has = col_w > 0
    col_e = np.divide(col_w, col_c, out=np.zeros_like(col_w), where=has)
    lat = w_lat[None, :] * has
    total = lat.sum(axis=1)
    out = np.full(a.shape, e_star[surface])
    # a = 0 (no contact yet) has no weight: it feels the surface material, as does a column of one material
    some = total > 0
    out[some] = np.sum(lat * col_e, axis=1)[some] / total[some]
    uniform = np.all(np.where(inside, idx, surface) == surface, axis=(1, 2))
    out[uniform] = e_star[surface]
    if not np.all(np.isfinite(out) & (out > 0)):
        raise ValidationError(f"effective_modulus: non-finite modulus for {obj.name!r} at ({x:.4f}, {y:.4f}) m")
    return out


def effective_modulus(obj: ObjectSpec, x: float, y: float, surface_z: float, contact_radius: float,
                      **kwargs) -> float:
    """E*_eff, Pa, at one contact radius (m); see :func:`effective_modulus_table`."""
    return float(effective_modulus_table(obj, x, y, surface_z, np.array([contact_radius]), **kwargs)[0])


def modulus_along_depth(obj: ObjectSpec, x: float, y: float, surface_z: float, tip_radius: float,
                        max_depth: float, samples: int = 24, **kwargs):
    """A per-press table of E*_eff against indentation, and its interpolator.

    The Hertz contact radius a = sqrt(R d) grows with the indentation d, so the modulus a press feels changes
    through it; tabulating at ``samples`` depths (uniform in a, where E*_eff changes fastest) costs one
    vectorised look-up per press.

    Returns:
        (depths (samples,) m, moduli (samples,) Pa, fn) with fn(depth m array) -> E*_eff Pa by interpolation
        in a (depths beyond the table take its last value).
    """
    if not (np.isfinite(max_depth) and max_depth > 0 and tip_radius > 0):
        raise ValidationError(f"modulus_along_depth: max_depth and tip_radius must be > 0 m, got {max_depth!r}, "
                              f"{tip_radius!r}")
    a_tab = np.linspace(0.0, np.sqrt(tip_radius * max_depth), samples)
    e_tab = effective_modulus_table(obj, x, y, surface_z, a_tab, **kwargs)

    def at(depth: np.ndarray) -> np.ndarray:
        a = np.sqrt(tip_radius * np.maximum(np.asarray(depth, dtype=float), 0.0))
        return np.interp(a, a_tab, e_tab)

    return a_tab**2 / tip_radius, e_tab, at


def depth_for_force(obj: ObjectSpec, x: float, y: float, surface_z: float, tip_radius: float,
                    force: float) -> float:
    """Indentation, m, at which a Hertz press with E*_eff(sqrt(R d)) reaches ``force`` N.

    On one material this is exactly the Hertz depth of its E*. Otherwise the force 4/3 E*_eff sqrt(R) d^1.5 is
    tabulated up to the softest material's Hertz depth (no press can need more) and its first crossing of
    ``force`` is found by bisection on the interpolated table (a fixed-point iteration can oscillate between a
    soft skin's depth and a hard base's).
    """
    softest = min(m.effective_modulus for m in obj.materials())
    d_max = hertz_depth_for_force(softest, tip_radius, force)
    depths, moduli, at = modulus_along_depth(obj, x, y, surface_z, tip_radius, d_max, samples=32)
    if np.all(moduli == moduli[0]):
        return hertz_depth_for_force(float(moduli[0]), tip_radius, force)
    lo, hi = 0.0, d_max
    if hertz_force(float(at(hi)), tip_radius, hi) < force:
        return d_max  # only where the softest material alone is felt at d_max: then it is the answer
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if hertz_force(float(at(mid)), tip_radius, mid) < force:
            lo = mid
        else:
            hi = mid
    return hi
