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


def sneddon_sphere_depth(contact_radius: np.ndarray, radius: float) -> np.ndarray:
    """Indentation, m, of a rigid *sphere* (not a paraboloid) of ``radius`` m at contact radius a (m), on a
    half-space (Sneddon 1965): d = (a / 2) ln((R + a) / (R - a)); it tends to Hertz's a^2 / R for a << R."""
    a = np.asarray(contact_radius, dtype=float)
    return 0.5 * a * np.log((radius + a) / (radius - a))


def sneddon_sphere_force(young_eff: float, radius: float, contact_radius: np.ndarray) -> np.ndarray:
    """Force, N, of a rigid sphere at contact radius a (m) on a half-space of E* Pa (Sneddon 1965):
    F = E* / 2 ((a^2 + R^2) ln((R + a) / (R - a)) - 2 a R)."""
    a = np.asarray(contact_radius, dtype=float)
    return 0.5 * young_eff * ((a**2 + radius**2) * np.log((radius + a) / (radius - a)) - 2.0 * a * radius)


def sneddon_sphere_contact_radius(radius: float, depth: np.ndarray) -> np.ndarray:
    """Contact radius, m, of a rigid sphere pressed ``depth`` m into a half-space (inverse of
    :func:`sneddon_sphere_depth`, by Newton from the Hertz radius; depth must stay below ~0.9 R)."""
    d = np.maximum(np.asarray(depth, dtype=float), 0.0)
    a = np.sqrt(radius * d)
    for _ in range(30):
        f = sneddon_sphere_depth(a, radius) - d
        # d'(a) = ln((R + a) / (R - a)) / 2 + a R / (R^2 - a^2)
        df = 0.5 * np.log((radius + a) / (radius - a)) + a * radius / (radius**2 - a**2)
        a = np.clip(a - np.divide(f, df, out=np.zeros_like(f), where=df > 0), 0.0, 0.999 * radius)
    return a


def sneddon_sphere_force_at_depth(young_eff: float, radius: float, depth: np.ndarray) -> np.ndarray:
    """Force, N, of a rigid sphere pressed ``depth`` m into a half-space of E* Pa (exact sphere geometry)."""
    return sneddon_sphere_force(young_eff, radius, sneddon_sphere_contact_radius(radius, depth))
