"""Frictionless contact of a rigid sphere on a layer stack: the force-indentation law of ``analytic`` and ``rigid``.

Axisymmetric contact of radius a, written with Sneddon's auxiliary function g(t) on [0, a] (the pressure's Hankel
transform is the cosine transform of g; p(r) = -int_r^a g'(t) / sqrt(t^2 - r^2) dt; F = 2 pi int_0^a g dt),
turns the mixed boundary value problem on the stack's surface compliance G = 2 H(xi) / (E* xi)
(:mod:`.layered`) into a Fredholm equation of the second kind:

    g(t) + int_0^a K(t, s) g(s) ds = E* / pi (d - D(t)),
    K(t, s) = (M(t - s) + M(t + s)) / pi,    M(x) = int_0^inf (H(xi) - 1) cos(xi x) dxi,

where D(t) = (t / 2) ln((R + t) / (R - t)) is the exact sphere's profile term (t^2 / R for a paraboloid). The
pressure stays bounded at the contact edge where g(a) = 0, which fixes d(a). On a half-space (H = 1) this is
Sneddon's sphere (Hertz for small a / R); on a layer on a rigid base, the exact linear-elastic answer the
bonded-layer series (Dimitriadis et al. 2002) approximates. Nystrom with Gauss-Legendre nodes on [0, a], dense
enough to resolve the top layer's thickness; M by Gauss-Legendre panels over xi, tabulated in x once per stack.

The pressure of a contact is kept as a sum of Hertz profiles p(r) = sum_k c_k sqrt(b_k^2 - r^2)_+ with b_k = a k /
K (its g is sum_k c_k (b_k^2 - t^2)_+ / 2, fitted to the solved g), so that sensel means integrate exactly
(:func:`palpate.sim.analytic.hertz_sensel_pressure`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from palpate.core.errors import ValidationError
from palpate.sim.contact.layered import surface_kernel
from palpate.sim.reference.sample import AxisymmetricSample

#: Hertz profiles in the pressure basis.
BASIS = 8
#: Contact radii tabulated per law.
RADII = 40


@dataclass(frozen=True)
class PressureBasis:
    """A contact's pressure as a sum of Hertz profiles p(r) = sum_k c_k sqrt(b_k^2 - r^2)_+ at n indentations.

    Attributes:
        radii: the profiles' radii b, m, (n, K).
        coeffs: their coefficients c, Pa/m, (n, K).
    """

    radii: np.ndarray
    coeffs: np.ndarray


@dataclass(frozen=True)
class KernelTable:
    """M(x) of a stack tabulated on a grid of x (both (m,); x in m, M in 1/m), with the top layer's E*, Pa."""

    x: np.ndarray
    m: np.ndarray
    surface_modulus: float


@dataclass(frozen=True)
class StackArrays:
    """A laterally uniform stack per layer, top first, bulk last: thickness m, Young modulus Pa, Poisson ratio."""

    thickness: np.ndarray
    young: np.ndarray
    poisson: np.ndarray


@dataclass(frozen=True)
class ContactLaw:
    """Force, contact radius and pressure of a rigid sphere against indentation on one stack.

    Attributes:
        tip_radius: sphere radius, m.
        contact_radius: tabulated contact radii a, m, (m,) increasing from 0.
        depth: indentation d(a), m, (m,).
        force: F(a), N, (m,).
        coeffs: pressure basis coefficients c_k(a), Pa/m, (m, BASIS): p(r) = sum_k c_k sqrt((a k / K)^2 - r^2)_+.
        surface_modulus: E* of the top material, Pa.
    """

    tip_radius: float
    contact_radius: np.ndarray
    depth: np.ndarray
    force: np.ndarray
    coeffs: np.ndarray
    surface_modulus: float

    @property
    def max_depth(self) -> float:
        """Deepest tabulated indentation, m."""
        return float(self.depth[-1])

    def force_at(self, depth) -> np.ndarray:
        """Normal force, N, at indentations ``depth`` (m); 0 out of contact. Interpolated in d^1.5, so that a
        Hertz-like law is exact between samples."""
        d = np.maximum(np.asarray(depth, dtype=float), 0.0)
        self._check_range(d)
        return np.interp(d**1.5, self.depth**1.5, self.force)

    def contact_radius_at(self, depth) -> np.ndarray:
        """Contact radius, m, at indentations ``depth`` (m) (interpolated in sqrt(d))."""
        d = np.maximum(np.asarray(depth, dtype=float), 0.0)
        self._check_range(d)
        return np.interp(np.sqrt(d), np.sqrt(self.depth), self.contact_radius)

    def stiffness_at(self, depth) -> np.ndarray:
        """dF/dd, N/m, at indentations ``depth`` (m)."""
        d = np.maximum(np.asarray(depth, dtype=float), 0.0)
        self._check_range(d)
        slope = np.gradient(self.force, self.depth)
        return np.interp(d, self.depth, slope)

    def depth_for_force(self, force: float) -> float:
        """Indentation, m, at which the force reaches ``force`` N (the law's inverse)."""
        if not (np.isfinite(force) and force > 0):
            raise ValidationError(f"depth_for_force: force must be > 0 N, got {force!r}")
        if force > self.force[-1]:
            raise ValidationError(f"depth_for_force: {force:.3g} N needs more than the tabulated "
                                  f"{self.max_depth * 1e3:.2f} mm (the law reaches {self.force[-1]:.3g} N there)")
        return float(np.interp(force, self.force, self.depth**1.5) ** (2.0 / 3.0))

    def basis_at(self, depth) -> PressureBasis:
        """Pressure basis at indentations ``depth`` (n,) m: radii b (n, K), m, and coefficients c (n, K), Pa/m."""
        a = self.contact_radius_at(depth)
        c = np.stack([np.interp(a, self.contact_radius, self.coeffs[:, k]) for k in range(self.coeffs.shape[1])],
                     axis=-1)
        b = a[..., None] * (np.arange(1, self.coeffs.shape[1] + 1) / self.coeffs.shape[1])
        return PressureBasis(radii=b, coeffs=c)

    def pressure_at(self, r, depth: float) -> np.ndarray:
        """Surface pressure, Pa, at radii ``r`` (m) for one indentation ``depth`` (m)."""
        basis = self.basis_at(np.array([depth]))
        rr = np.asarray(r, dtype=float)[..., None]
        return np.sum(basis.coeffs[0] * np.sqrt(np.maximum(basis.radii[0] ** 2 - rr**2, 0.0)), axis=-1)

    def _check_range(self, d: np.ndarray) -> None:
        if d.size and float(np.max(d)) > self.max_depth * (1 + 1e-9):
            raise ValidationError(f"contact law: indentation {float(np.max(d)) * 1e3:.3f} mm is beyond the tabulated "
                                  f"{self.max_depth * 1e3:.3f} mm")


def sphere_profile_term(t: np.ndarray, tip_radius: float) -> np.ndarray:
    """D(t) = (t / 2) ln((R + t) / (R - t)), m: the sphere's term in the Fredholm equation (t < R)."""
    t = np.asarray(t, dtype=float)
    return 0.5 * t * np.log((tip_radius + t) / (tip_radius - t))


def _kernel_table(stack: AxisymmetricSample, x_max: float) -> KernelTable:
    """M(x) on a grid of x in [0, x_max] (m) and the top layer's E* (Pa)."""
    layers = stack_arrays(stack)
    thick, young, poisson = layers.thickness, layers.young, layers.poisson
    t_top = float(thick[0]) if len(thick) > 1 else float(stack.thickness)
    t_min = float(np.min(thick))
    xi_max = 20.0 / t_top
    w_osc = math.pi / (2.0 * max(x_max, 1e-9))
    edges = [0.0]
    while edges[-1] < xi_max:
        edges.append(edges[-1] + min(w_osc, 0.3 * (edges[-1] + 1.0 / stack.thickness), 0.5 / t_min + edges[-1]))
    edges = np.array(edges)
    xg, wg = np.polynomial.legendre.leggauss(8)
    half = 0.5 * np.diff(edges)[:, None]
    xi = (0.5 * (edges[1:] + edges[:-1]))[:, None] + half * xg[None, :]
    w = (half * wg[None, :]).ravel()
    xi = xi.ravel()
    h = surface_kernel(xi, thick, young, poisson, stack.base)
    n_x = int(np.clip(np.ceil(12.0 * x_max / min(t_top, x_max)), 200, 1200))
    x = np.linspace(0.0, x_max, n_x)
    m = np.empty(n_x)
    for start in range(0, n_x, 64):
        m[start:start + 64] = np.cos(np.outer(x[start:start + 64], xi)) @ ((h - 1.0) * w)
    e_top = young[0] / (1.0 - poisson[0] ** 2)
    return KernelTable(x=x, m=m, surface_modulus=e_top)


def stack_arrays(stack: AxisymmetricSample) -> StackArrays:
    """Per-layer thickness m, Young modulus Pa and Poisson ratio of a laterally uniform stack, top first, bulk
    last."""
    if stack.inclusion is not None:
        raise ValidationError("contact law: the layered solution needs a laterally uniform stack; homogenise the "
                              "inclusion first (palpate.sim.contact.stack)")
    thick = [la.thickness for la in stack.layers]
    young = [la.material.young for la in stack.layers]
    poisson = [la.material.poisson for la in stack.layers]
    rest = stack.thickness - sum(thick)
    if rest > 1e-12 * stack.thickness:
        thick.append(rest)
        young.append(stack.bulk.young)
        poisson.append(stack.bulk.poisson)
    return StackArrays(thickness=np.array(thick), young=np.array(young), poisson=np.array(poisson))


def solve_contact_law(stack: AxisymmetricSample, tip_radius: float, max_depth: float, *,
                      radii: int = RADII) -> ContactLaw:
    """Tabulate the contact law of a sphere of ``tip_radius`` (m) on ``stack`` up to ``max_depth`` (m).

    Raises:
        ValidationError: a press deeper than 0.75 tip radii (the sphere's contact would near its equator).
    """
    if not (tip_radius > 0 and np.isfinite(max_depth) and 0 < max_depth <= 0.75 * tip_radius * (1 + 1e-9)):
        raise ValidationError(f"contact law: max_depth must lie in (0, 0.75 R) = (0, {0.75 * tip_radius:.4g}) m, got "
                              f"{max_depth!r}")
    a_top = min(0.97 * tip_radius, 1.6 * math.sqrt(tip_radius * max_depth))
    kernel = _kernel_table(stack, 2.0 * a_top)
    x, m_tab, e_top = kernel.x, kernel.m, kernel.surface_modulus
    t_top = float(stack_arrays(stack).thickness[0])
    a_grid = a_top * (np.arange(1, radii + 1) / radii) ** 1.0
    depth, force, coeffs = [0.0], [0.0], [np.zeros(BASIS)]
    rules: dict[int, tuple[np.ndarray, np.ndarray]] = {}  # one eigenproblem per node count, not per radius
    for a in a_grid:
        n = int(np.clip(np.ceil(6.0 * a / t_top), 24, 240))
        if n not in rules:
            rules[n] = np.polynomial.legendre.leggauss(n)
        xg, wg = rules[n]
        t = 0.5 * a * (xg + 1.0)
        w = 0.5 * a * wg
        kern = (np.interp(np.abs(t[:, None] - t[None, :]), x, m_tab) + np.interp(t[:, None] + t[None, :], x, m_tab))
        kern /= math.pi
        system = np.eye(n) + kern * w[None, :]
        rhs = np.stack([np.ones(n), sphere_profile_term(t, tip_radius)], axis=1) * (e_top / math.pi)
        g1, g2 = np.linalg.solve(system, rhs).T
        # g at t = a from the equation itself (Nystrom interpolation)
        k_a = (np.interp(np.abs(a - t), x, m_tab) + np.interp(a + t, x, m_tab)) / math.pi
        g1_a = e_top / math.pi - (k_a * w) @ g1
        g2_a = e_top / math.pi * sphere_profile_term(a, tip_radius) - (k_a * w) @ g2
        d = g2_a / g1_a
        g = d * g1 - g2
        depth.append(float(d))
        force.append(float(2.0 * math.pi * (w @ g)))
        coeffs.append(_fit_basis(t, g, a))
        if d >= max_depth * 1.02 and len(depth) > 8:
            break
    depth, force = np.array(depth), np.array(force)
    if depth[-1] < max_depth or np.any(np.diff(depth) <= 0) or np.any(np.diff(force) <= 0):
        raise ValidationError(f"contact law: the solution on {stack.describe()} did not cover {max_depth * 1e3:.2f} mm "
                              "monotonically; press less deep")
    a_tab = np.concatenate([[0.0], a_grid[: len(depth) - 1]])
    coeffs[0] = coeffs[1]  # a contact shrinking to a point keeps its shape (Hertz's c is constant in a)
    return ContactLaw(tip_radius=float(tip_radius), contact_radius=a_tab, depth=depth, force=force,
                      coeffs=np.array(coeffs), surface_modulus=float(e_top))


def _fit_basis(t: np.ndarray, g: np.ndarray, a: float) -> np.ndarray:
    """Coefficients c_k with sum_k c_k (b_k^2 - t^2)_+ / 2 ~ g(t), b_k = a k / K (least squares; the total force
    is matched exactly)."""
    b = a * np.arange(1, BASIS + 1) / BASIS
    design = 0.5 * np.maximum(b[None, :] ** 2 - t[:, None] ** 2, 0.0)
    coef, *_ = np.linalg.lstsq(design, g, rcond=None)
    return coef
