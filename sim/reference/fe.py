"""Axisymmetric finite-element solution of a rigid sphere pressed into an :class:`AxisymmetricSample`.

Method (quasi-static, linear elasticity, frictionless contact, displacement control):
- biquadratic (Q2, 9-node) elements on a graded tensor mesh of the (r, z) half-plane (:mod:`.mesh`), axisymmetric
  strain (e_rr, e_zz, e_tt = u_r / r, g_rz) weighted by r; full integration: Q2 does not lock at nu = 0.49 (the
  thick-block force stays within 1% of Sneddon's there as at nu = 0.3);
- boundary conditions: u_r = 0 on the axis; the base bonded (u = 0) or frictionless (u_z = 0); the side at the
  sample's radius free, or, for a wide sample, a roller (u_r = 0) at 12 thicknesses plus 60 contact radii;
- contact: the surface pressure is piecewise linear in r (hats on the top vertices); the stiffness matrix is
  factorised once and the surface compliance G (vertex settlement per unit hat pressure) condensed from it. At each
  indentation d the active set is the contiguous disc of k hats whose settlement equals the sphere's gap
  d - (R - sqrt(R^2 - r^2)) (exact sphere, not a paraboloid); k is the smallest disc with no penetration outside;
- the force is 2 pi times the integral of the pressure; the contact radius is where p^2, extrapolated linearly
  from the last two loaded hats, vanishes.

Its accuracy is shown by mesh refinement (``refinement``; benchmarks/fe_reference.py) and against Hertz/Sneddon
for a thick block and the bonded-layer correction (:mod:`.bonded_layer`) for thin layers (tests/test_fe_reference.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from palpate.core.errors import ValidationError
from palpate.sim.reference.fe_mesh import FEMesh, build_mesh
from palpate.sim.reference.mesh import sample_grids
from palpate.sim.reference.sample import AxisymmetricSample

#: Surface spacing h0 as a fraction of the smallest contact radius asked for, at refinement 1.
H0_OVER_A = 1.0 / 12.0
#: The refined region first reaches 1.3 x 1.15 sqrt(R d) (a half-space's contact with room); where the contact is
#: wider (a thin bonded layer), it is widened by WIDENING, up to MAX_WIDENINGS times.
WIDENING = 1.5
MAX_WIDENINGS = 4
#: Meshes a caller's ``meshes`` dict keeps at most (:func:`fe_presses`).
MAX_MESHES = 4


@dataclass(frozen=True)
class FEPress:
    """The reference's answer at each indentation.

    Attributes:
        depth: indentations, m, (n,).
        force: normal force, N, (n,).
        contact_radius: m, (n,).
        r: radii of the surface pressure samples, m, (m,).
        pressure: surface pressure at ``r`` for each indentation, Pa, (n, m).
        dofs: degrees of freedom of the mesh; h0: its surface spacing, m.
        element_r, element_depth: each element's centroid (radius, depth below the surface), m, (e,).
        element_energy: share of the strain energy each element holds at each indentation (rows sum to 1), (n, e):
            a material change of relative size x in element i changes the force by about x * share_i (first order:
            the force is homogeneous of degree one in the moduli, and its derivative in element i's modulus is that
            element's energy share).
    """

    depth: np.ndarray
    force: np.ndarray
    contact_radius: np.ndarray
    r: np.ndarray
    pressure: np.ndarray
    dofs: int
    h0: float
    element_r: np.ndarray
    element_depth: np.ndarray
    element_energy: np.ndarray


@dataclass(frozen=True)
class HatDisc:
    """The loaded hats of one indentation: every hat's pressure, Pa, and how many (from the axis) carry load."""

    pressure: np.ndarray
    loaded: int


def fe_press(sample: AxisymmetricSample, tip_radius: float, depths, *, refinement: float = 1.0,
             growth: float = 1.15, depth_growth: float = 1.10, materials=None, breaks_r=(), breaks_z=(),
             energy: bool = False, free_side: float = math.inf, meshes: dict | None = None) -> FEPress:
    """Force, contact radius and surface pressure of a rigid sphere pressed ``depths`` (m) into ``sample``.

    Args:
        sample: the sample.
        tip_radius: sphere radius, m.
        depths: indentations, m, each in (0, 0.9 tip_radius).
        refinement: mesh density: the surface spacing is (smallest contact radius / 12) / refinement.
        growth, depth_growth: spacing growth per cell away from the contact, radially and with depth (smaller is
            finer).
        materials: optional fn(r m, depth m) -> (Young Pa, Poisson) replacing the sample's own material field
            (the sample then only gives the thickness, base and width); breaks_r, breaks_z: extra mesh lines, m.
        energy: also return each element's strain-energy share at each depth (else ``element_energy`` is empty).
        free_side: radius, m, past which the top surface is absent (a free side that ``materials`` fills with a
            near-void so the mesh can run on): the sphere cannot touch it there. It is also a mesh line.
        meshes: a dict the caller keeps (see :func:`fe_presses`).
    """
    return fe_presses(sample, tip_radius, depths, [materials], refinement=refinement, growth=growth,
                      depth_growth=depth_growth, breaks_r=breaks_r, breaks_z=breaks_z, energy=energy,
                      free_side=free_side, meshes=meshes)[0]


def fe_presses(sample: AxisymmetricSample, tip_radius: float, depths, fields, *, refinement: float = 1.0,
               growth: float = 1.15, depth_growth: float = 1.10, breaks_r=(), breaks_z=(), energy: bool = False,
               free_side: float = math.inf, meshes: dict | None = None) -> list[FEPress]:
    """:func:`fe_press` for each material field of ``fields`` (each as its ``materials``; None: the sample's own),
    all on one mesh: two fields compared like against like (their discretisation errors cancel in a ratio), and
    the mesh, its basis and the stiffness's geometric parts built once. Where the contact of any field reaches the
    refined region's edge, the region is widened for all.

    ``meshes``: a dict the caller keeps across calls: a mesh is kept in it by what it is made of (its nodes, width,
    base and hats' reach) and a later call on the same geometry, whatever its materials, takes it instead of
    building it again (samples of one size pressed alike, e.g. a run's training blocks); at most MAX_MESHES kept."""
    d = np.sort(np.atleast_1d(np.asarray(depths, dtype=float)))
    if not (tip_radius > 0 and np.all(np.isfinite(d)) and d.size and d[0] > 0 and d[-1] < 0.9 * tip_radius):
        raise ValidationError(f"fe_press: depths must lie in (0, {0.9 * tip_radius}) m, got {depths!r}")
    if not refinement > 0:
        raise ValidationError(f"fe_press: refinement must be > 0, got {refinement!r}")
    a_min = math.sqrt(tip_radius * d[0])
    a_max = math.sqrt(tip_radius * d[-1]) * 1.15  # a sphere's contact is a little wider than the paraboloid's
    h0 = a_min * H0_OVER_A / refinement
    reach = a_max
    for _ in range(MAX_WIDENINGS + 1):
        try:
            return _solve(sample, tip_radius, d, reach, h0, list(fields), growth=growth, depth_growth=depth_growth,
                          breaks_r=breaks_r, breaks_z=breaks_z, energy=energy, free_side=free_side,
                          meshes=meshes)
        except _EdgeReached as exc:
            if exc.at_rim:
                break
            # on a thin bonded layer the contact is wider than a half-space's (1.35 sqrt(R d) on 2 mm at nu 0.45):
            # the fine region is widened until it holds the contact
            reach *= WIDENING
    raise ValidationError(f"fe_press: the contact on {sample.describe()} reached the edge of the refined region "
                          f"({1.3 * reach * 1e3:.2f} mm) at depths up to {d[-1] * 1e3:.2f} mm; press less deep")


class _EdgeReached(ValidationError):
    """The contact disc reached the last surface vertex of the refined region (``at_rim``: the sample's own rim,
    so a wider refined region cannot help)."""

    def __init__(self, message: str, at_rim: bool = False):
        super().__init__(message)
        self.at_rim = at_rim


def _solve(sample: AxisymmetricSample, tip_radius: float, d: np.ndarray, a_max: float, h0: float, fields: list, *,
           growth: float, depth_growth: float, breaks_r, breaks_z, energy: bool, free_side: float,
           meshes: dict | None = None) -> list[FEPress]:
    """:func:`fe_presses` on a mesh refined (spacing ``h0``, m) out to 1.3 ``a_max`` (m); _EdgeReached if the
    contact reaches the end of that region."""
    wide = not math.isfinite(sample.radius)
    width = 12.0 * sample.thickness + 60.0 * a_max if wide else sample.radius
    breaks_r, breaks_z = list(breaks_r), list(breaks_z) + list(sample.interfaces())
    if math.isfinite(free_side):
        breaks_r.append(free_side)
    if sample.inclusion is not None:
        inc = sample.inclusion
        breaks_r.append(inc.radius)
        breaks_z += [inc.depth, inc.bottom]
    grid = sample_grids(sample.thickness, width, a_max, h0, breaks_r, breaks_z, growth=growth,
                        depth_growth=depth_growth)
    # what build_mesh reads of the sample is its base alone
    key = (sample.base, wide, float(width), float(1.3 * a_max), grid.r.tobytes(), grid.depth.tobytes())
    mesh = None if meshes is None else meshes.get(key)
    if mesh is None:
        mesh = build_mesh(sample, grid.r, grid.depth, width, wide, 1.3 * a_max)
        if meshes is not None:
            if len(meshes) >= MAX_MESHES:  # a few kept: a mesh holds megabytes
                meshes.clear()
            meshes[key] = mesh
    r_top = mesh.r_top
    weights = -mesh.loads.sum(axis=0)  # integral of each hat times r dr
    # beyond the sphere's equator the surface can never be touched
    gap0 = np.where(r_top < tip_radius, tip_radius - np.sqrt(np.maximum(tip_radius**2 - r_top**2, 0.0)), np.inf)
    # nor past a free side: a void's surface there would hold the contact disc open out to it, with tension in
    # between (found on a cylinder 6 mm wide pressed 3 mm: -13% force)
    gap0[r_top > free_side * (1.0 + 1e-9)] = np.inf
    at_rim = bool(r_top[-1] >= grid.r[-1] - 1e-12)
    return [_solve_field(mesh, sample, materials, d, gap0, weights, energy, at_rim, h0) for materials in fields]


def _solve_field(mesh: FEMesh, sample: AxisymmetricSample, materials, d: np.ndarray, gap0: np.ndarray,
                 weights: np.ndarray, energy: bool, at_rim: bool, h0: float) -> FEPress:
    """One material field (``materials`` as :func:`fe_press`'s) pressed ``d`` (m) on ``mesh``."""
    from scipy.sparse.linalg import splu

    young, poisson = (materials or sample.materials_at)(mesh.centroid_r, mesh.centroid_depth)
    lam = young * poisson / ((1 + poisson) * (1 - 2 * poisson))
    mu = young / (2 * (1 + poisson))
    r_top = mesh.r_top
    local = mesh.local_stiffness(lam, mu)  # the stiffness's and the energies'
    stiffness, recovery = mesh.stiffness(lam, mu, local)
    # minimum degree on A^T + A: the matrix is symmetric, and this ordering halves the factor's fill (COLAMD's)
    lu = splu(stiffness, permc_spec="MMD_AT_PLUS_A")
    settle = lu.solve(mesh.loads)  # (free, hats) displacement per unit hat pressure
    compliance = -settle[mesh.vertex]  # downward settlement of each top vertex per unit hat pressure
    forces, radii, pressures = [], [], []
    for depth in d:
        disc = contact_disc(compliance, depth - gap0, depth)
        if disc.loaded >= len(r_top) - 1:
            raise _EdgeReached("fe_press: the contact reached the edge of the refined region", at_rim=at_rim)
        forces.append(2.0 * math.pi * float(weights @ disc.pressure))
        radii.append(_edge(r_top, disc.pressure, disc.loaded))
        pressures.append(disc.pressure)
    shares = []
    n = len(mesh.at)
    for p in pressures if energy else ():
        u = np.zeros(n)
        u[mesh.free] = settle @ p
        share = np.maximum(mesh.element_energy(local, u, recovery), 0.0)
        shares.append(share / max(float(share.sum()), 1e-300))
    return FEPress(depth=d, force=np.array(forces), contact_radius=np.array(radii), r=r_top,
                   pressure=np.array(pressures), dofs=int(n), h0=float(h0), element_r=mesh.centroid_r,
                   element_depth=mesh.centroid_depth,
                   element_energy=np.array(shares) if shares else np.zeros((0, len(mesh.centroid_r))))


def contact_disc(compliance: np.ndarray, gap: np.ndarray, depth: float) -> HatDisc:
    """Hat pressures (Pa) and the number k of loaded hats: the smallest disc of hats whose settlement equals the
    sphere's ``gap`` (m) with no penetration outside it."""
    n = len(gap)

    def solve(k: int) -> np.ndarray:
        p = np.zeros(n)
        p[:k] = np.linalg.solve(compliance[:k, :k], gap[:k])
        return p

    def penetrates(p: np.ndarray, k: int) -> bool:
        return bool(np.any(compliance[k:] @ p < gap[k:] - 1e-12 * depth))

    k = max(int(np.sum(gap > 0)), 1)
    p = solve(k)
    while penetrates(p, k) and k < n - 1:
        k += 1
        p = solve(k)
    while k > 1:
        q = solve(k - 1)
        if penetrates(q, k - 1):
            break
        k, p = k - 1, q
    return HatDisc(pressure=p, loaded=k)


def _edge(r: np.ndarray, p: np.ndarray, k: int) -> float:
    """Contact radius: where p^2, linear through the last two loaded hats, reaches 0 (at most one spacing out)."""
    if k < 2 or p[k - 1] <= 0:
        return float(r[k - 1])
    y0, y1 = p[k - 2] ** 2, p[k - 1] ** 2
    h = r[k] - r[k - 1]
    if y0 <= y1:
        return float(r[k - 1] + h)
    return float(min(r[k - 1] + y1 / (y0 - y1) * (r[k - 1] - r[k - 2]), r[k - 1] + h))
