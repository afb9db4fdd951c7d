"""Hertz contact of a rigid sphere on an elastic half-space: the closed forms every fidelity is checked against.

E* = E / (1 - nu^2) for a rigid indenter; F = 4/3 E* sqrt(R) d^1.5, contact radius a = sqrt(R d).
"""

from __future__ import annotations

import numpy as np

from palpate.core.errors import ValidationError


def effective_modulus_rigid(young: float, poisson: float) -> float:
    """E* of an elastic material under a rigid indenter, Pa: E / (1 - nu^2)."""
    return young / (1.0 - poisson**2)


def hertz_force(young_eff: float, radius: float, depth: np.ndarray) -> np.ndarray:
    """Hertz normal force, N, of a rigid sphere (radius m) pressed ``depth`` m into a half-space of E* Pa."""
    d = np.maximum(np.asarray(depth, dtype=float), 0.0)
    return 4.0 / 3.0 * young_eff * np.sqrt(radius) * d**1.5


def hertz_contact_radius(radius: float, depth: np.ndarray) -> np.ndarray:
    """Hertz contact radius a = sqrt(R d), m."""
    return np.sqrt(radius * np.maximum(np.asarray(depth, dtype=float), 0.0))


def hertz_depth_for_force(young_eff: float, radius: float, force: float) -> float:
    """Indentation, m, at which the Hertz force reaches ``force`` N (inverse of :func:`hertz_force`)."""
    if not (force > 0 and young_eff > 0 and radius > 0):
        raise ValidationError(f"hertz_depth_for_force needs force, E*, R > 0; got {force}, {young_eff}, {radius}")
    return float((3.0 * force / (4.0 * young_eff * np.sqrt(radius))) ** (2.0 / 3.0))
