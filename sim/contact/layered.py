"""Surface compliance of an elastic layer stack on a rigid base, in the Hankel domain.

For axisymmetric fields u_r = U(z) J1(xi r), u_z = W(z) J0(xi r) with tractions tau_rz = T(z) J1, sigma_zz = S(z)
J0, Navier's equations in a homogeneous layer (Lame lambda, mu; z up) are y' = A y for y = (U, W, T, S):

    U' = T / mu + xi W,   W' = (S - lambda xi U) / (lambda + 2 mu),   S' = -xi T,
    T' = 4 mu (lambda + mu) / (lambda + 2 mu) xi^2 U + lambda / (lambda + 2 mu) xi S.

Scaled (s = xi z, tractions over mu xi) the matrix A_hat depends on nu only, with eigenvalues +-1 each of
multiplicity two, so exp(A_hat s) = c0 I + c1 A + c2 A^2 + c3 A^3 with c0 = cosh s - s sinh s / 2,
c1 = (3 sinh s - s cosh s) / 2, c2 = s sinh s / 2, c3 = (s cosh s - sinh s) / 2. The two solutions that satisfy
the base condition (bonded: U = W = 0; frictionless: W = T = 0) are carried up through every layer in steps of at
most 2 in s, re-orthonormalised after each step (only their span matters), so growing and decaying modes never
swamp each other; below 40 / xi from the surface the stack is replaced by a half-space of the material there (its
coupling to the surface is e^-80). At the surface (T = 0, S = -p) this gives the settlement -W = G(xi) p, written

    G(xi) = 2 H(xi) / (E*_top xi),

so H = 1 for a half-space of the top material, H -> 0 as xi -> 0 on a rigid base, H -> 1 as xi -> infinity.
"""

from __future__ import annotations

import numpy as np

from palpate.core.errors import ValidationError

#: Beyond this many 1/xi below the surface the stack no longer couples to the surface (e^-2x).
DECOUPLED = 40.0
#: Largest step in xi z between re-orthonormalisations.
STEP = 2.0


def scaled_matrix(poisson: float) -> np.ndarray:
    """A_hat (4, 4) of a layer with Poisson ratio ``poisson``: d/ds of (U, W, T / (mu xi), S / (mu xi))."""
    k = 2.0 * poisson / (1.0 - 2.0 * poisson)  # lambda / mu
    return np.array([
        [0.0, 1.0, 1.0, 0.0],
        [-k / (k + 2.0), 0.0, 0.0, 1.0 / (k + 2.0)],
        [4.0 * (k + 1.0) / (k + 2.0), 0.0, 0.0, k / (k + 2.0)],
        [0.0, 0.0, -1.0, 0.0],
    ])


def scaled_propagator(a_hat: np.ndarray, s: np.ndarray) -> np.ndarray:
    """e^-s exp(A_hat s), (n, 4, 4), for steps s (n,) >= 0 (the factor e^-s keeps it bounded; spans ignore it)."""
    s = np.asarray(s, dtype=float)[:, None, None]
    e2 = np.exp(-2.0 * s)
    ch = 0.5 * (1.0 + e2)  # cosh s e^-s
    sh = 0.5 * (1.0 - e2)  # sinh s e^-s
    a2 = a_hat @ a_hat
    a3 = a2 @ a_hat
    eye = np.eye(4)
    return ((ch - 0.5 * s * sh) * eye + 0.5 * (3.0 * sh - s * ch) * a_hat + 0.5 * s * sh * a2
            + 0.5 * (s * ch - sh) * a3)


def _growing_span(a_hat: np.ndarray) -> np.ndarray:
    """Orthonormal basis (4, 2) of the solutions growing upward (decaying into a half-space below)."""
    m = (a_hat - np.eye(4)) @ (a_hat - np.eye(4))
    _, _, vt = np.linalg.svd(m)
    return vt[-2:].T


def surface_kernel(xi: np.ndarray, thickness: np.ndarray, young: np.ndarray, poisson: np.ndarray,
                   base: str = "bonded") -> np.ndarray:
    """H(xi) of a stack (top layer first) on a rigid base; see the module docstring.

    Args:
        xi: Hankel wavenumbers, 1/m, (n,) > 0.
        thickness, young, poisson: per layer, m, Pa, -, top first.
        base: "bonded" or "frictionless".

    Returns:
        (n,) H, dimensionless.
    """
    xi = np.asarray(xi, dtype=float)
    h = np.asarray(thickness, dtype=float)
    e = np.asarray(young, dtype=float)
    nu = np.asarray(poisson, dtype=float)
    if base not in ("bonded", "frictionless"):
        raise ValidationError(f"surface_kernel: base must be 'bonded' or 'frictionless', got {base!r}")
    if not (h.shape == e.shape == nu.shape and h.ndim == 1 and len(h)):
        raise ValidationError("surface_kernel: thickness, young and poisson need one value per layer")
    if np.any(h <= 0) or np.any(e <= 0) or np.any((nu < 0) | (nu >= 0.5)) or np.any(xi <= 0):
        raise ValidationError("surface_kernel: layers need thickness > 0, young > 0, 0 <= poisson < 0.5; xi > 0")
    mu = e / (2.0 * (1.0 + nu))
    mats = [scaled_matrix(v) for v in nu]
    top_of = np.concatenate([[0.0], np.cumsum(h)])  # depth of each layer's top; the base at top_of[-1]
    n = len(xi)
    limit = DECOUPLED / xi  # depth below which nothing couples
    # start: at the base, or (where the base is too deep to matter) a half-space of the layer at depth `limit`
    start_layer = np.searchsorted(top_of[1:], np.minimum(limit, top_of[-1]), side="left")
    start_layer = np.minimum(start_layer, len(h) - 1)
    deep = limit < top_of[-1]
    y = np.zeros((n, 4, 2))
    # rows in dimensional-traction form: (U, W, T / xi, S / xi); a layer's scaled form divides T, S by its mu
    if base == "bonded":
        y[:, 2, 0] = 1.0
        y[:, 3, 1] = 1.0
    else:
        y[:, 0, 0] = 1.0
        y[:, 3, 1] = 1.0
    for i in range(len(h)):
        if deep.any():
            span = _growing_span(mats[i]).copy()
            span[2:] *= mu[i]
            y[deep & (start_layer == i)] = span
    start_depth = np.where(deep, limit, top_of[-1])
    for i in range(len(h) - 1, -1, -1):
        # the part of layer i above each wavenumber's starting depth
        lo = np.minimum(top_of[i + 1], start_depth)
        span_z = np.maximum(lo - top_of[i], 0.0)
        s_total = xi * span_z
        steps = int(np.ceil(np.max(s_total) / STEP)) if np.any(s_total > 0) else 0
        if steps == 0:
            continue
        scale = np.array([1.0, 1.0, mu[i], mu[i]])
        for _ in range(steps):
            s = np.minimum(s_total, STEP)
            s_total = s_total - s
            active = s > 0
            if not active.any():
                break
            p = scaled_propagator(mats[i], s[active])
            ya = y[active] / scale[None, :, None]
            ya = (p @ ya) * scale[None, :, None]
            q, _ = np.linalg.qr(ya)
            y[active] = q
    # surface: T = 0, S / xi = -p / xi; settlement -W per unit p is W-row . inv(TS rows) . (0, 1/xi)
    ts = y[:, 2:, :]
    w_row = y[:, 1, :]
    sol = np.linalg.solve(ts, np.broadcast_to(np.array([0.0, 1.0]), (n, 2))[..., None])[..., 0]
    settle_xi = np.einsum("nk,nk->n", w_row, sol)  # = G xi
    e_star_top = e[0] / (1.0 - nu[0] ** 2)
    return 0.5 * e_star_top * settle_xi
