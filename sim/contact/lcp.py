"""Frictionless contact of a rigid indenter on a discretised elastic surface: the linear complementarity problem

    p >= 0,   C p >= g,   p . (C p - g) = 0,

for cell pressures p (Pa), a symmetric positive definite compliance C (m/Pa) and the gap g (m) the surface must
close (the indentation less the indenter's profile). Solved by an active-set iteration (Murty's) that starts from a
given guess, so a sequence of growing indentations reuses each answer's contact set and settles in one or two
factorisations per indentation.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import LinAlgError, cho_factor, cho_solve

from palpate.core.errors import ValidationError


def solve_contact(compliance: np.ndarray, gap: np.ndarray, active: np.ndarray | None = None,
                  max_iter: int = 200) -> tuple[np.ndarray, np.ndarray]:
    """Cell pressures (Pa) of the contact and its active set (bool), see the module docstring.

    Args:
        compliance: (n, n) symmetric positive definite, m/Pa; single precision halves the cost of the gathers and
            factorisations (the answer then holds about 6 digits).
        gap: (n,) m; cells with gap <= 0 can still come into contact if pressing elsewhere lifts them less.
        active: a starting guess of the cells in contact (default: those with a positive gap).
        max_iter: factorisations allowed before giving up.

    Raises:
        ValidationError: the active set does not settle within ``max_iter`` iterations, or the compliance of the
            cells in contact is not positive definite.
    """
    gap = np.asarray(gap, dtype=float)
    n = len(gap)
    if not np.any(gap > 0):
        return np.zeros(n), np.zeros(n, dtype=bool)
    active = (gap > 0) if active is None else np.asarray(active, dtype=bool).copy()
    if not active.any():
        active[int(np.argmax(gap))] = True
    # penetration of free cells is judged relative to the deepest gap, so round-off cannot cycle the set
    slack = max(1e-10, 100.0 * float(np.finfo(compliance.dtype).eps)) * float(gap.max())
    for _ in range(max_iter):
        idx = np.flatnonzero(active)
        p = np.zeros(n, dtype=compliance.dtype)
        # row-then-column takes and a full product (p is zero off the set) copy far less than np.ix_ and a
        # column slice would
        try:
            factor = cho_factor(compliance[idx][:, idx], overwrite_a=True, check_finite=False)
        except LinAlgError:
            raise ValidationError(f"contact: the compliance of the {len(idx)} cells in contact is not positive "
                                  "definite (a surface model outside what it holds); use another fidelity") from None
        p[idx] = cho_solve(factor, gap[idx].astype(compliance.dtype), check_finite=False)
        negative = p < 0
        penetrating = (~active) & (compliance @ p < gap - slack)
        if not negative.any() and not penetrating.any():
            return p.astype(float), active
        active = (active & ~negative) | penetrating
        if not active.any():
            active[int(np.argmax(gap))] = True
    raise ValidationError("contact: the active set did not settle; refine the surface (smaller cells or elements)")
