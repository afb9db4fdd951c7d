"""The `flex` fidelity's element: the stiffness of one trilinear hexahedral cell with selective reduced
integration, in MuJoCo's block layout (see :mod:`palpate.sim.flex.model` for why it replaces MuJoCo's own).

A cell is given by its 8 corners (node (bx, by, bz) with bz fastest, MuJoCo's order), so the same element serves
the axis-aligned cells of a box window and the distorted cells of a disc mapped onto a tensor grid (a cylinder,
:func:`palpate.sim.flex.grid.flex_grid`): the strains come from the isoparametric map's Jacobian at each point.
"""

from __future__ import annotations

import numpy as np

from palpate.core.errors import ValidationError

#: Corner offsets (8, 3) of the unit cell in MuJoCo's node order (z fastest, x slowest).
UNIT_CORNERS = np.array([[bx, by, bz] for bx in (0, 1) for by in (0, 1) for bz in (0, 1)], dtype=float)


def lame(young, poisson):
    """Lame parameters (lambda, mu), Pa, of Young's modulus (Pa) and Poisson ratio (arrays broadcast)."""
    young, poisson = np.asarray(young, dtype=float), np.asarray(poisson, dtype=float)
    return young * poisson / ((1 + poisson) * (1 - 2 * poisson)), young / (2 * (1 + poisson))


def box_corners(edges) -> np.ndarray:
    """Corners (..., 8, 3) of axis-aligned cells of edges ``edges`` (m, (..., 3)) with their lower corner at 0."""
    h = np.asarray(edges, dtype=float)
    return UNIT_CORNERS * h[..., None, :]


def _shape_gradients(s: float, t: float, u: float) -> np.ndarray:
    """(8, 3) derivatives of the trilinear shape functions by the local coordinates at (s, t, u) in [0, 1]^3."""
    p = np.where(UNIT_CORNERS > 0, [s, t, u], [1.0 - s, 1.0 - t, 1.0 - u])  # (8, 3) per-axis factors
    sign = 2.0 * UNIT_CORNERS - 1.0
    return np.stack([sign[:, 0] * p[:, 1] * p[:, 2], p[:, 0] * sign[:, 1] * p[:, 2],
                     p[:, 0] * p[:, 1] * sign[:, 2]], axis=1)


def _gradients(corners: np.ndarray, s: float, t: float, u: float) -> tuple[np.ndarray, np.ndarray]:
    """Shape-function gradients in space (n, 8, 3), 1/m, and the Jacobian determinant (n,), m^3, at (s, t, u)."""
    local = _shape_gradients(s, t, u)
    det, inv = _jacobian(corners, local)
    return np.einsum("aj,nji->nai", local, inv), det


def _jacobian(corners: np.ndarray, local: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Determinant (n,) and inverse (n, 3, 3) of the isoparametric map's Jacobian, given the local gradients."""
    jac = np.einsum("nai,aj->nij", corners, local)  # d x_i / d xi_j
    det = np.linalg.det(jac)
    if np.any(det <= 0):
        raise ValidationError("flex: a cell of the window is inverted or degenerate (Jacobian <= 0)")
    return det, np.linalg.inv(jac)


def _blocks(grad: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per unit Lame parameter at one point, (n, 3m, 3m) each for m shape functions of gradients ``grad`` (n, m, 3):
    the volumetric (div u)^2 and 2 e:e energies' Hessians, dof 3 function + axis."""
    n, m = grad.shape[:2]
    div = grad.reshape(n, 3 * m)  # d(div u) / d u_(a, p) = dN_a / dx_p
    vol = div[:, :, None] * div[:, None, :]
    # 2 e(a,p):e(b,q) = delta_pq (g_a . g_b) + g_a[q] g_b[p]
    dots = np.einsum("nai,nbi->nab", grad, grad)
    ee = np.einsum("nab,pq->napbq", dots, np.eye(3)) + np.einsum("naq,nbp->napbq", grad, grad)
    return vol, ee.reshape(n, 3 * m, 3 * m)


def hex_bases(corners) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Stiffness of hexahedral cells with corners ``corners`` (m; (8, 3) or (n, 8, 3), MuJoCo's node order) per unit
    Lame parameter, in MuJoCo's layout and sign (-K): (volumetric at 2x2x2 points, volumetric at the centre,
    2 e:e at 2x2x2 points), each (24, 24) or (n, 24, 24), N/m per Pa.

    Raises:
        ValidationError: an inverted or degenerate cell.
    """
    c = np.asarray(corners, dtype=float)
    single = c.ndim == 2
    c = c.reshape(-1, 8, 3)
    xg, wg = np.polynomial.legendre.leggauss(2)
    xg, wg = (xg + 1.0) / 2.0, wg / 2.0
    vol_full = np.zeros((len(c), 24, 24))
    ee = np.zeros((len(c), 24, 24))
    for a in range(2):
        for b in range(2):
            for k in range(2):
                grad, det = _gradients(c, xg[a], xg[b], xg[k])
                vol, e = _blocks(grad)
                w = (wg[a] * wg[b] * wg[k] * det)[:, None, None]
                vol_full -= w * vol
                ee -= w * e
    grad, det = _gradients(c, 0.5, 0.5, 0.5)
    vol_centre = -det[:, None, None] * _blocks(grad)[0]
    out = (vol_full, vol_centre, ee)
    return tuple(o[0] for o in out) if single else out


def hex_volumes(corners) -> np.ndarray:
    """Volumes (n,), m^3, of hexahedral cells with corners (n, 8, 3) (2x2x2 points: exact for a trilinear map)."""
    c = np.asarray(corners, dtype=float).reshape(-1, 8, 3)
    xg, wg = np.polynomial.legendre.leggauss(2)
    xg, wg = (xg + 1.0) / 2.0, wg / 2.0
    return sum(wg[a] * wg[b] * wg[k] * _gradients(c, xg[a], xg[b], xg[k])[1]
               for a in range(2) for b in range(2) for k in range(2))


def bending_ee(corners) -> np.ndarray:
    """The 2 e:e part (per unit mu, N/m per Pa; (n, 24, 24), MuJoCo's layout and sign -K) of hexahedral cells with
    corners (n, 8, 3) (m) enriched with Wilson's incompatible modes (a bubble 1 - xi^2 per axis and displacement
    component, in Taylor's form: their gradients by the centre's Jacobian, so a distorted cell still passes the
    patch test), condensed out of each cell.

    A trilinear cell cannot bend: under a bending moment it shears, so a thin cell (a skin a fifth of a cell
    thick) is several times too stiff in bending (shear locking). The bubbles give it curvature. Only the mu part is
    enriched: with the bubbles in the lambda part too the cell locks again as nu -> 0.5 (the volumetric term stays
    at the centre point, :func:`hex_bases`).
    """
    c = np.asarray(corners, dtype=float).reshape(-1, 8, 3)
    xg, wg = np.polynomial.legendre.leggauss(2)
    xg, wg = (xg + 1.0) / 2.0, wg / 2.0
    det0, inv0 = _jacobian(c, _shape_gradients(0.5, 0.5, 0.5))
    k = np.zeros((len(c), 33, 33))
    for a in range(2):
        for b in range(2):
            for e in range(2):
                grad, det = _gradients(c, xg[a], xg[b], xg[e])
                # d(1 - xi_i^2) / d s_j with xi = 2 s - 1 is -4 xi_i delta_ij
                xi = 2.0 * np.array([xg[a], xg[b], xg[e]]) - 1.0
                bubble = np.einsum("ij,njk->nik", np.diag(-4.0 * xi), inv0) * (det0 / det)[:, None, None]
                k += (wg[a] * wg[b] * wg[e] * det)[:, None, None] * _blocks(np.concatenate([grad, bubble], axis=1))[1]
    kuu, kua, kaa = k[:, :24, :24], k[:, :24, 24:], k[:, 24:, 24:]
    return -(kuu - kua @ np.linalg.solve(kaa, np.swapaxes(kua, 1, 2)))
