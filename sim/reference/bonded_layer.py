"""The published thin-layer correction the FE reference is checked against (Dimitriadis et al. 2002).

A paraboloid of radius R indents an elastic layer of thickness h on a rigid base by d; with chi = sqrt(R d) / h,

    F = F_Hertz [1 - 2 a0 / pi chi + 4 a0^2 / pi^2 chi^2 - 8 / pi^3 (a0^3 + 4 pi^2 / 15 b0) chi^3
                 + 16 a0 / pi^4 (a0^3 + 3 pi^2 / 5 b0) chi^4]

with, for a layer bonded to the base, a0 = -(1.2876 - 1.4678 nu + 1.3442 nu^2) / (1 - nu),
b0 = (0.6387 - 1.0277 nu + 1.5164 nu^2) / (1 - nu), and for a layer free to slide on it a0 = -0.347 (3 - 2 nu) /
(1 - nu), b0 = 0.056 (5 - 2 nu) / (1 - nu) (E. K. Dimitriadis, F. Horkay, J. Maresca, B. Kachar, R. S. Chadwick,
"Determination of elastic moduli of thin layers of soft material using the atomic force microscope", Biophys. J.
82 (2002) 2798-2810, eqs. 13-16). An asymptotic series: valid for chi up to ~1.
"""

from __future__ import annotations

import math

import numpy as np

from palpate.core.errors import ValidationError


def dimitriadis_factor(chi: np.ndarray, poisson: float, base: str = "bonded") -> np.ndarray:
    """F / F_Hertz of a paraboloid on a layer on a rigid base, for chi = contact radius / thickness."""
    nu = float(poisson)
    if base == "bonded":
        a0 = -(1.2876 - 1.4678 * nu + 1.3442 * nu**2) / (1.0 - nu)
        b0 = (0.6387 - 1.0277 * nu + 1.5164 * nu**2) / (1.0 - nu)
    elif base == "frictionless":
        a0 = -0.347 * (3.0 - 2.0 * nu) / (1.0 - nu)
        b0 = 0.056 * (5.0 - 2.0 * nu) / (1.0 - nu)
    else:
        raise ValidationError(f"dimitriadis_factor: base must be 'bonded' or 'frictionless', got {base!r}")
    x = np.asarray(chi, dtype=float)
    pi = math.pi
    return (1.0 - 2.0 * a0 / pi * x + 4.0 * a0**2 / pi**2 * x**2
            - 8.0 / pi**3 * (a0**3 + 4.0 * pi**2 / 15.0 * b0) * x**3
            + 16.0 * a0 / pi**4 * (a0**3 + 3.0 * pi**2 / 5.0 * b0) * x**4)
