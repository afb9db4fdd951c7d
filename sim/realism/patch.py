"""The pad's pressure over the two-body contact patch: Hertz's shape on soft objects, more peaked on stiff ones.

Between a soft object and the finger, the object's deformation sets the pressure: Hertz's distribution,
p ~ (1 - r^2 / a^2)^(1/2). On a stiff object the indentation is all in the pulp, a thin soft layer bonded to the
bone, and a thin layer pressed by a flat concentrates the pressure at the centre: p ~ (1 - r^2 / a^2) for a
compressible layer (Winkler foundation) and p ~ (1 - r^2 / a^2)^2 for an incompressible bonded one (Johnson 1985,
Contact Mechanics, section 5.9). The exponent of a press is therefore taken between 1/2 and the pulp's own exponent
in proportion to the pulp's share of the approach, delta / (d + delta).

The distribution p(r) = F (k + 1) / (pi a^2) (1 - r^2 / a^2)^k carries the force F whatever the exponent k; its
mean over each sensel is integrated with Gauss-Legendre points per sensel (the Hertz case keeps the closed-form
integration of :func:`palpate.sim.analytic.hertz_sensel_pressure`, so a profile at k = 1/2 replays the simulation).
"""

from __future__ import annotations

import numpy as np

from palpate.sim.analytic import hertz_sensel_pressure
from palpate.sim.hertz import hertz_force

#: Hertz's exponent of the pressure distribution.
HERTZ_EXPONENT = 0.5
#: Gauss-Legendre points per sensel side (the distribution has a kink at the rim; 8 points keep the sensel means
#: within ~1% of a fine grid, well below the pad's noise).
_POINTS = 8


def press_exponent(pulp_exponent: float, object_depth: np.ndarray, compression: np.ndarray) -> np.ndarray:
    """The pressure exponent of each sample: 1/2 plus the pulp's share of the approach delta / (d + delta) of the way
    to ``pulp_exponent`` (depths in m, any shape; 1/2 where nothing is indented)."""
    d = np.maximum(np.asarray(object_depth, dtype=float), 0.0)
    delta = np.maximum(np.asarray(compression, dtype=float), 0.0)
    total = d + delta
    share = np.divide(delta, total, out=np.zeros_like(total), where=total > 0)
    return HERTZ_EXPONENT + (pulp_exponent - HERTZ_EXPONENT) * share


def patch_sensel_pressure(patch: np.ndarray, force: np.ndarray, exponent: np.ndarray, radius: float,
                          bounds: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """Mean pressure over each sensel, Pa, of the distribution F (k + 1) / (pi a^2) (1 - r^2 / a^2)^k.

    Args:
        patch: the patch's depth scale, m, shape (n,): its radius is a = sqrt(radius * patch) (> 0).
        force: the force the patch carries, N, shape (n,).
        exponent: k of each sample, shape (n,) (1/2: Hertz's distribution, integrated in closed form).
        radius: the fingertip's radius, m.
        bounds: sensel footprints (rows, cols, 4) as (x0, x1, y0, y1), m, in the pad plane.
        centre: the patch's centre in the pad plane, m, shape (2,).

    Returns:
        (n, rows, cols) mean pressure, Pa.
    """
    patch = np.asarray(patch, dtype=float)
    force = np.asarray(force, dtype=float)
    k = np.asarray(exponent, dtype=float)
    rows, cols = bounds.shape[:2]
    out = np.zeros((len(patch), rows, cols))
    hertz = k == HERTZ_EXPONENT
    if hertz.any():
        shape = hertz_sensel_pressure(patch[hertz], 1.0, radius, bounds, centre)
        out[hertz] = shape * (force[hertz] / hertz_force(1.0, radius, patch[hertz]))[:, None, None]
    if (~hertz).any():
        out[~hertz] = _quadrature(radius * patch[~hertz], force[~hertz], k[~hertz], bounds, centre)
    return out


def _quadrature(a2: np.ndarray, force: np.ndarray, k: np.ndarray, bounds: np.ndarray,
                centre: np.ndarray) -> np.ndarray:
    """Sensel means of F (k + 1) / (pi a^2) (1 - r^2 / a^2)^k by a tensor Gauss-Legendre rule on each sensel."""
    x, w = np.polynomial.legendre.leggauss(_POINTS)
    rect = bounds.reshape(-1, 4) - np.array([centre[0], centre[0], centre[1], centre[1]])
    # points (sensels, P, P) and the weights of a mean over each sensel (sum 1)
    px = 0.5 * (rect[:, 0, None] + rect[:, 1, None]) + 0.5 * (rect[:, 1, None] - rect[:, 0, None]) * x[None]
    py = 0.5 * (rect[:, 2, None] + rect[:, 3, None]) + 0.5 * (rect[:, 3, None] - rect[:, 2, None]) * x[None]
    r2 = (px[:, :, None] ** 2 + py[:, None, :] ** 2).reshape(len(rect), -1)
    weights = (np.outer(w, w) / 4.0).ravel()
    u = np.maximum(1.0 - r2[None] / a2[:, None, None], 0.0)
    mean_shape = (u ** k[:, None, None]) @ weights
    p0 = force * (k + 1.0) / (np.pi * a2)
    return (p0[:, None] * mean_shape).reshape(len(a2), *bounds.shape[:2])
