"""The contact law of a press point whose material varies laterally (an inclusion, a haptic-material map, an edge
within reach): the object averaged around the press axis, solved by the axisymmetric FE on a coarse mesh.

The object's material at radius r and depth z from the press point is averaged over 16 azimuths, relative to the
depth's matrix (the material covering most of the disc the call samples at that depth): sectors stiffer than the
matrix enter by their geometric mean (a stiff island in a soft matrix is partly bypassed), sectors softer than it
by a power mean of exponent 1/2 (the stiff matrix carries load around a soft pocket, closer to sectors in
parallel); times the share of the ring inside (a sector past a free edge carries nothing), and the mean Poisson
ratio of the sectors inside. For an inclusion on the press axis (and a cylinder
pressed at its centre) this is exact; the coarse mesh (surface spacing a / 3.6 at the smallest tabulated depth,
growth 1.5 radially and 1.2 with depth) is run twice, on the averaged object and on the press point's column alone,
and its own error cancels in their ratio (see :func:`axisymmetric_law`); off the axis it is an approximation, checked
against a 3-D FE beside box lumps (benchmarks/fe_offaxis.py) but not part of the validity table (its lumps are on
the axis). Costs two factorisations per press point.

Most press points that see some lateral variation within reach barely feel it (an object's side 30 mm away at the
base, a lump 20 mm aside). For them the FE is replaced by first-order perturbation (:func:`lateral_effect`): the
force is homogeneous of degree one in the moduli, so a relative change x_i of element i's modulus changes it by
sum_i s_i x_i, s_i the element's share of the column's strain energy at that depth (one FE of the column, cached
per column stack). Where that estimate stays within :data:`FIRST_ORDER_LIMIT` at every depth, the law is the column
law times (1 + estimate); beyond it (a lump or an edge close by) the two factorisations run.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.world.scene import Material
from palpate.sim.contact.law import BASIS, ContactLaw
from palpate.sim.reference.fe import FEPress, fe_press, fe_presses
from palpate.sim.reference.sample import AxisymmetricSample

#: Mesh of the surrogate (see the module docstring).
REFINEMENT = 0.3
GROWTH = 1.5
DEPTH_GROWTH = 1.2
#: Tabulated depths, as fractions of the deepest (a from a fifth of the deepest contact radius up).
DEPTH_FRACTIONS = np.geomspace(1.0 / 24.0, 1.0, 12)
#: Azimuths of the average.
AZIMUTHS = 16
#: Stiffness left in a ring that is all void (keeps the FE non-singular).
VOID = 1e-4
#: Largest first-order lateral effect (relative force change at any tabulated depth) taken without the FE: first
#: order under-estimates a void (an edge) by up to ~2x and a stiffer lump by less, so the law stays within ~1.5%.
FIRST_ORDER_LIMIT = 0.03


#: Power of the ring mean of the sectors stiffer than the matrix (0: geometric), and of those softer than it, see
#: :func:`azimuthal_materials`.
RING_POWER = 0.0
SOFT_RING_POWER = 0.5
#: Rings (area-weighted) on which the matrix of each depth is sampled.
MATRIX_RINGS = 8


def _ring() -> np.ndarray:
    """(AZIMUTHS, 2) unit vectors at the middle of each azimuthal sector."""
    theta = (np.arange(AZIMUTHS) + 0.5) * 2.0 * np.pi / AZIMUTHS
    return np.stack([np.cos(theta), np.sin(theta)], axis=-1)


def _power_part(rel: np.ndarray, take: np.ndarray, count: np.ndarray, power: float) -> np.ndarray:
    """Per ring, the power mean of ``rel`` over the sectors in ``take``, the others counting as 1 (the matrix)."""
    if power == 0.0:
        return np.exp(np.sum(np.where(take, np.log(rel), 0.0), axis=1) / count)
    return np.maximum(1.0 + np.sum(np.where(take, rel**power - 1.0, 0.0), axis=1) / count, 0.0) ** (1.0 / power)


def matrix_moduli(lookup, depths: np.ndarray, reach: float) -> np.ndarray:
    """The matrix E (Pa) at each of ``depths`` (m): of the materials inside the object within ``reach`` m of the
    press axis at that depth, the one covering the most area (sampled on MATRIX_RINGS rings of AZIMUTHS sectors)."""
    radii = reach * (np.arange(MATRIX_RINGS) + 0.5) / MATRIX_RINGS
    offsets = (radii[:, None, None] * _ring()[None]).reshape(-1, 2)
    e, _, inside = lookup(np.tile(offsets, (len(depths), 1)), np.repeat(depths, len(offsets)))
    e = e.reshape(len(depths), -1)
    weight = np.where(inside.reshape(len(depths), -1), np.repeat(radii, AZIMUTHS)[None, :], 0.0)
    # each depth's area per modulus, all depths in one count; ties go to the softer, as a count per depth gives
    values, index = np.unique(e, return_inverse=True)
    rows = np.repeat(np.arange(len(depths)), e.shape[1])
    share = np.bincount(rows * len(values) + index.ravel(), weights=weight.ravel(),
                        minlength=len(depths) * len(values)).reshape(len(depths), len(values))
    return np.where(share.max(axis=1) > 0, values[np.argmax(share, axis=1)], e.max(axis=1))


def azimuthal_materials(lookup, power: float = RING_POWER, soft_power: float = SOFT_RING_POWER):
    """fn(r, z) -> (E, nu) averaging ``lookup`` (offsets (n, 2) m, depths (n,) m -> E, nu, inside) around the
    axis (see the module docstring); ``power``, ``soft_power``: of the ring's power means of E over the sectors
    stiffer and softer than the depth's matrix (1 arithmetic, 0 geometric, -1 harmonic;
    benchmarks/fe_offaxis_mixing.py compares them). The matrix is sampled out to the largest r of each call."""
    ring = _ring()

    def materials(r: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        r = np.asarray(r, dtype=float)
        z = np.asarray(z, dtype=float)
        offsets = (r[:, None, None] * ring[None, :, :]).reshape(-1, 2)
        e, nu, inside = lookup(offsets, np.repeat(z, AZIMUTHS))
        e = e.reshape(len(r), -1)
        nu = nu.reshape(len(r), -1)
        inside = inside.reshape(len(r), -1)
        frac = inside.mean(axis=1)
        cnt = np.maximum(inside.sum(axis=1), 1)
        # Each ring's mean is taken relative to its depth's matrix, so a uniform ring (layers, on-axis lumps, a
        # cylinder's centre) gives its own E exactly. The 3-D FE beside box lumps (benchmarks/fe_offaxis.py) put
        # the arithmetic mean (a Voigt-type upper bound) 36-58% too stiff next to a 20x stiffer lump 1 mm down, and
        # the geometric mean 34-41% too soft next to a 20x softer one: a stiff island in a soft matrix is bypassed,
        # a soft pocket in a stiff matrix is bridged.
        depths, row = np.unique(z, return_inverse=True)
        matrix = matrix_moduli(lookup, depths, float(np.max(r)) if r.size else 0.0)[row]
        rel = np.where(inside, e / matrix[:, None], 1.0)
        stiff = inside & (rel >= 1.0)
        mean = (matrix * _power_part(rel, stiff, cnt, power) * _power_part(rel, inside & ~stiff, cnt, soft_power))
        young = np.maximum(frac * mean, VOID * max(float(np.max(matrix)) if matrix.size else 1.0, 1.0))
        poisson = np.where(frac > 0, np.sum(np.where(inside, nu, 0.0), axis=1) / cnt, 0.3)
        return young, poisson

    return materials


def free_side(lookup, reach: float, breaks_r=()) -> float:
    """Radius, m, from which the object's top is absent all around the press axis (a narrow object's rim within
    ``reach`` m), ``inf`` if some azimuth has material out to ``reach``; ``lookup`` as in :mod:`.stack`.

    Sampled every reach / 256 and at ``breaks_r``: the last radius with material on some azimuth.
    """
    r = np.union1d(np.linspace(0.0, reach, 257), [b for b in breaks_r if 0.0 < b <= reach])
    offsets = (r[:, None, None] * _ring()[None]).reshape(-1, 2)
    _, _, inside = lookup(offsets, np.full(len(offsets), 1e-7))
    none = ~inside.reshape(len(r), AZIMUTHS).any(axis=1)
    if not none.any():
        return math.inf
    return float(r[max(int(np.argmax(none)) - 1, 0)])


def column_energy(column: AxisymmetricSample, tip_radius: float, max_depth: float, breaks_z=(),
                  meshes: dict | None = None) -> FEPress:
    """The column's coarse FE answer at the tabulated depths, for its element energy shares (see the module
    docstring); ``meshes``: the caller's kept FE meshes (:func:`palpate.sim.reference.fe.fe_presses`)."""
    return fe_press(column, tip_radius, max_depth * DEPTH_FRACTIONS, refinement=REFINEMENT, growth=GROWTH,
                    depth_growth=DEPTH_GROWTH, breaks_z=breaks_z, energy=True, meshes=meshes)


def lateral_effect(lookup, column_lookup, energy: FEPress) -> np.ndarray:
    """First-order relative force change, at each of ``energy``'s depths, that the lateral variation of
    ``lookup`` makes against the press point's column ``column_lookup`` (both as in :mod:`.stack`); ``energy``
    from :func:`column_energy`."""
    used = energy.element_energy.max(axis=0) > 1e-9
    r, z = energy.element_r[used], energy.element_depth[used]
    e_avg, _ = azimuthal_materials(lookup)(r, z)
    e_col = column_lookup(np.zeros((len(r), 2)), z)[0]
    return energy.element_energy[:, used] @ (e_avg / e_col - 1.0)


def first_order_law(column: ContactLaw, energy: FEPress, effect: np.ndarray) -> ContactLaw:
    """The column law with its force (and pressure, in proportion) times 1 + ``effect`` (at ``energy``'s depths,
    interpolated in log depth, held beyond)."""
    scale = 1.0 + np.interp(np.log(np.maximum(column.depth, energy.depth[0])), np.log(energy.depth), effect)
    return replace(column, force=column.force * scale, coeffs=column.coeffs * scale[:, None])


def _fit_coeffs(fe) -> np.ndarray:
    """Pressure basis coefficients (n, BASIS) of an FE answer's surface pressures, one row per depth."""
    rows = []
    for a, p in zip(fe.contact_radius, fe.pressure, strict=True):
        b = a * np.arange(1, BASIS + 1) / BASIS
        design = np.sqrt(np.maximum(b[None, :] ** 2 - fe.r[:, None] ** 2, 0.0))
        coef = np.linalg.lstsq(design, p, rcond=None)[0]
        if np.any(coef < 0):
            # with few FE nodes inside a small contact the plain fit is rank-deficient, and its huge cancelling
            # coefficients put garbage between the nodes (1e17 Pa on a sensel while the force stays right): the
            # profiles are kept non-negative instead (a pressure falling from the axis, as a contact's does)
            from scipy.optimize import nnls  # rarely needed; importing scipy.optimize costs ~0.1 s

            coef = nnls(design, p)[0]
        rows.append(coef)
    return np.array(rows)


def axisymmetric_law(lookup, thickness: float, tip_radius: float, max_depth: float, *, base: str = "bonded",
                     breaks_z=(), breaks_r=(), surface: Material, column: ContactLaw,
                     column_lookup) -> ContactLaw:
    """The contact law of the azimuthally averaged object (``lookup`` as in :mod:`.stack`) on a rigid base
    ``thickness`` m down, tabulated up to ``max_depth`` m; ``surface`` is the material under the press point.

    The coarse mesh's own error is cancelled: the same mesh also solves the press point's column alone
    (``column_lookup``, laterally uniform), and the law is the exact column law ``column`` corrected by the ratio
    (force) and the difference (pressure basis) of the two coarse answers. So a lateral variation
    that changes nothing gives the column law exactly, and the lateral effect is measured like against like.
    """
    depths = max_depth * DEPTH_FRACTIONS
    sample = AxisymmetricSample(bulk=surface, thickness=thickness, base=base)
    # a rim within the contact's reach is the sample's free side: a mesh line, and no surface to touch past it
    rim = free_side(lookup, 1.3 * 1.15 * math.sqrt(tip_radius * max_depth), breaks_r)
    solve = dict(refinement=REFINEMENT, growth=GROWTH, depth_growth=DEPTH_GROWTH, breaks_z=breaks_z,
                 breaks_r=breaks_r, free_side=rim)
    fe, uniform = fe_presses(sample, tip_radius, depths,
                             [azimuthal_materials(lookup), azimuthal_materials(column_lookup)], **solve)
    force = column.force_at(depths) * fe.force / uniform.force
    # the coarse contact radii move in steps of the mesh spacing, so their ratio is noisy: keep the column's radius
    # and let the pressure basis (below) carry how the lateral variation reshapes the contact
    radius = column.contact_radius_at(depths)
    coeffs = column.basis_at(depths).coeffs + _fit_coeffs(fe) - _fit_coeffs(uniform)
    coeffs = np.vstack([coeffs[:1], coeffs])  # a contact shrinking to a point keeps its shape
    a_tab = np.concatenate([[0.0], radius])
    force = np.concatenate([[0.0], force])
    # the pressure basis integrates to the force (2 pi sum c_k b_k^3 / 3): rescale its small fitting error away
    b3 = (a_tab[:, None] * np.arange(1, BASIS + 1) / BASIS) ** 3
    integral = 2.0 * math.pi / 3.0 * np.sum(coeffs * b3, axis=1)
    coeffs = coeffs * np.divide(force, integral, out=np.ones_like(force), where=integral > 0)[:, None]
    if np.any(np.diff(force) <= 0) or np.any(np.diff(a_tab) < 0):
        raise ValidationError("contact law: the axisymmetric solution is not monotonic; the material varies too "
                              "fast under the press for it (use fidelity 'flex')")
    return ContactLaw(tip_radius=float(tip_radius), contact_radius=a_tab, depth=np.concatenate([[0.0], depths]),
                      force=force, coeffs=coeffs, surface_modulus=float(surface.effective_modulus))
