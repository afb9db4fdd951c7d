"""The contact law of a press point whose material varies laterally (an inclusion, a haptic-material map, an edge
within reach): the object averaged around the press axis, solved by the axisymmetric FE on a coarse mesh.

The object's material at radius r and depth z from the press point is averaged over 16 azimuths: the geometric
mean of E over the points inside the object, times the fraction inside (a free edge within reach softens the ring
it cuts; a void carries nothing), and the mean Poisson ratio. For an inclusion on the press axis (and a cylinder
pressed at its centre) this is exact, and the coarse mesh (surface spacing a / 3.6 at the smallest tabulated depth,
growth 1.3) stays within ~2.5% of the converged reference (benchmarks/validity.py); off the axis it is an
approximation whose error the validity table states. Costs one factorisation per press point (~0.3-0.7 s).
"""

from __future__ import annotations

import math

import numpy as np

from palpate.core.world.scene import Material
from palpate.sim.contact.law import BASIS, ContactLaw
from palpate.sim.reference.fe import fe_press
from palpate.sim.reference.sample import AxisymmetricSample

#: Mesh of the surrogate (see the module docstring).
REFINEMENT = 0.3
GROWTH = 1.3
#: Tabulated depths, as fractions of the deepest (a from a fifth of the deepest contact radius up).
DEPTH_FRACTIONS = np.geomspace(1.0 / 24.0, 1.0, 12)
#: Azimuths of the average.
AZIMUTHS = 16
#: Stiffness left in a ring that is all void (keeps the FE non-singular).
VOID = 1e-4


def azimuthal_materials(lookup):
    """fn(r, z) -> (E, nu) averaging ``lookup`` (offsets (n, 2) m, depths (n,) m -> E, nu, inside) around the
    axis (see the module docstring)."""
    theta = (np.arange(AZIMUTHS) + 0.5) * 2.0 * np.pi / AZIMUTHS
    ring = np.stack([np.cos(theta), np.sin(theta)], axis=-1)

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
        log_e = np.sum(np.where(inside, np.log(e), 0.0), axis=1) / cnt
        e_max = float(np.max(np.where(inside, e, 0.0)))
        young = np.where(frac > 0, np.exp(log_e) * np.maximum(frac, VOID), VOID * max(e_max, 1.0))
        poisson = np.where(frac > 0, np.sum(np.where(inside, nu, 0.0), axis=1) / cnt, 0.3)
        return young, poisson

    return materials


def axisymmetric_law(lookup, thickness: float, tip_radius: float, max_depth: float, *, base: str = "bonded",
                     breaks_z=(), breaks_r=(), surface: Material) -> ContactLaw:
    """The contact law of the azimuthally averaged object (``lookup`` as in :mod:`.stack`) on a rigid base
    ``thickness`` m down, tabulated up to ``max_depth`` m; ``surface`` is the material under the press point."""
    depths = max_depth * DEPTH_FRACTIONS
    sample = AxisymmetricSample(bulk=surface, thickness=thickness, base=base)
    fe = fe_press(sample, tip_radius, depths, refinement=REFINEMENT, growth=GROWTH,
                  materials=azimuthal_materials(lookup), breaks_z=breaks_z, breaks_r=breaks_r)
    coeffs = [np.zeros(BASIS)]
    for a, p in zip(fe.contact_radius, fe.pressure, strict=True):
        b = a * np.arange(1, BASIS + 1) / BASIS
        design = np.sqrt(np.maximum(b[None, :] ** 2 - fe.r[:, None] ** 2, 0.0))
        c, *_ = np.linalg.lstsq(design, p, rcond=None)
        coeffs.append(c)
    coeffs[0] = coeffs[1]  # a contact shrinking to a point keeps its shape (Hertz's c is constant in a)
    coeffs = np.array(coeffs)
    a_tab = np.concatenate([[0.0], fe.contact_radius])
    force = np.concatenate([[0.0], fe.force])
    # the pressure basis integrates to the force (2 pi sum c_k b_k^3 / 3): rescale its small fitting error away
    b3 = (a_tab[:, None] * np.arange(1, BASIS + 1) / BASIS) ** 3
    integral = 2.0 * math.pi / 3.0 * np.sum(coeffs * b3, axis=1)
    coeffs = coeffs * np.divide(force, integral, out=np.ones_like(force), where=integral > 0)[:, None]
    return ContactLaw(tip_radius=float(tip_radius), contact_radius=a_tab, depth=np.concatenate([[0.0], depths]),
                      force=force, coeffs=coeffs, surface_modulus=float(surface.effective_modulus))
