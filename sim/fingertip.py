"""Geometry of the sensel pad on the spherical fingertip.

The pad (rows x cols square sensels, one Tekscan Grip pad by default) is glued to the bottom of the tip sphere.
Sensels are described by their footprint in the pad plane (x, y relative to the tip axis, row 0 at +y), which is
their vertical projection onto the lower hemisphere; pressure is averaged over that projected area, the way a
thin flexible pad bent over a fingertip reports force over its nominal area. The projection needs the whole pad
inside the sphere's footprint, which :func:`sensel_bounds` checks.
"""

from __future__ import annotations

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.world.scene import FingertipSpec


def sensel_bounds(tip: FingertipSpec) -> np.ndarray:
    """Sensel footprints in the pad plane, m: array (rows, cols, 4) of (x0, x1, y0, y1) relative to the tip axis.

    Raises ValidationError if the pad does not fit under the sphere (its corners must lie within the radius).
    """
    c = tip.sensel_centres()
    h = tip.sensel_size / 2.0
    half_x = (tip.cols - 1) / 2.0 * tip.pitch + h
    half_y = (tip.rows - 1) / 2.0 * tip.pitch + h
    if np.hypot(half_x, half_y) >= tip.radius * 1.42 or max(half_x, half_y) >= tip.radius:
        raise ValidationError(
            f"FingertipSpec: a {tip.rows}x{tip.cols} pad with pitch {tip.pitch} m does not fit under a tip of "
            f"radius {tip.radius} m; reduce pitch or sensel_size, or increase radius"
        )
    return np.stack([c[..., 0] - h, c[..., 0] + h, c[..., 1] - h, c[..., 1] + h], axis=-1)


# Gauss-Legendre rules are constants; computing one costs an eigenvalue problem, more than a whole analytic press
_GAUSS = {n: np.polynomial.legendre.leggauss(n) for n in range(1, 17)}


def gauss_points(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Legendre nodes and weights on [0, 1] (n points, exact for polynomials of degree 2n-1)."""
    x, w = _GAUSS[n] if n in _GAUSS else np.polynomial.legendre.leggauss(n)
    return (x + 1.0) / 2.0, w / 2.0


def sensel_quadrature(tip: FingertipSpec, order: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """Tensor Gauss-Legendre points over every sensel footprint.

    Returns:
        points (rows, cols, order*order, 2), m, in the pad plane; weights (order*order,) summing to 1, so that
        ``(f(points) * weights).sum(-1)`` is the mean of f over each sensel.
    """
    if order < 1:
        raise ValidationError(f"sensel_quadrature: order must be >= 1, got {order}")
    b = sensel_bounds(tip)
    s, w = gauss_points(order)
    gx = b[..., 0:1] + (b[..., 1:2] - b[..., 0:1]) * s  # (r, c, order)
    gy = b[..., 2:3] + (b[..., 3:4] - b[..., 2:3]) * s
    px = np.repeat(gx[..., :, None], order, axis=-1)
    py = np.repeat(gy[..., None, :], order, axis=-2)
    pts = np.stack([px.reshape(*b.shape[:2], -1), py.reshape(*b.shape[:2], -1)], axis=-1)
    return pts, np.outer(w, w).reshape(-1)


def cap_height(tip: FingertipSpec, xy: np.ndarray) -> np.ndarray:
    """Height of the sphere's lower surface above its lowest point at pad-plane points xy (..., 2), m.

    Points outside the sphere's footprint get +inf (never in contact).
    """
    r2 = np.sum(np.asarray(xy, dtype=float) ** 2, axis=-1)
    out = np.full(r2.shape, np.inf)
    inside = r2 < tip.radius**2
    out[inside] = tip.radius - np.sqrt(tip.radius**2 - r2[inside])
    return out


def sensel_sites(tip: FingertipSpec) -> np.ndarray:
    """Sensel centres on the sphere, (rows, cols, 3), m, in the tip frame (origin at the sphere centre)."""
    c = tip.sensel_centres()
    z = -np.sqrt(np.maximum(tip.radius**2 - np.sum(c**2, axis=-1), 0.0))
    return np.concatenate([c, z[..., None]], axis=-1)
