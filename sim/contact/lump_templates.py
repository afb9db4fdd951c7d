"""Lump templates made by the closed-form contact law (see :mod:`palpate.core.boundary.lump_templates`): the default
fingertip pressed on the axis of a 40 mm sample bonded to the table, the top material over a deeper layer or with an
on-axis sphere or cylinder of another, at every contrast, top depth and radius of a grid.
"""

from __future__ import annotations

import numpy as np

from palpate.core.boundary.lump_templates import lump_templates_document
from palpate.core.boundary.templates import Pad
from palpate.core.world.scene import FingertipSpec, Layer, Material
from palpate.sim.analytic import law_sensel_pressure
from palpate.sim.contact.stack import sample_law
from palpate.sim.fingertip import sensel_bounds
from palpate.sim.reference.sample import AxisInclusion, AxisymmetricSample

#: The grid the shipped file holds: indentations and tops, m; deep over top modulus; inclusion radii, m.
DEPTHS = tuple(np.round(np.arange(0.5, 5.51, 0.5) * 1e-3, 6))
TOPS = tuple(np.round(np.arange(0.5, 8.01, 0.5) * 1e-3, 6))
CONTRASTS = (1 / 32, 1 / 16, 1 / 8, 1 / 4, 1 / 2, 2.0, 4.0, 8.0, 16.0, 32.0)
RADII = (5e-3, 8e-3, 12e-3, 18e-3)
POISSON = 0.4
#: The sample's thickness, m (the scenes' blocks are 40 mm tall).
THICKNESS = 0.04
#: The top material's modulus, Pa (the ratios do not depend on it).
MODULUS = 1e5


def shapes_and_radii(radii=RADII) -> tuple[tuple[str, ...], tuple[float, ...]]:
    """The templates' shapes and radii: a layer, then spheres and cylinders of each radius."""
    return (("layer",) + ("sphere",) * len(radii) + ("cylinder",) * len(radii), (0.0,) + tuple(radii) * 2)


def _sample(top: Material, deep: Material, t: float, shape: str, radius: float) -> AxisymmetricSample:
    if shape == "layer":
        return AxisymmetricSample(bulk=deep, thickness=THICKNESS, layers=(Layer(top, t),))
    height = min(2.0 * radius, THICKNESS - t - 1e-3)
    if shape == "sphere" and t + 2.0 * radius > THICKNESS - 1e-3:
        shape = "cylinder"  # a sphere that would reach the base: its upper part
    return AxisymmetricSample(bulk=top, thickness=THICKNESS, inclusion=AxisInclusion(deep, shape, t, radius, height))


def pad_sum(sample: AxisymmetricSample, tip: FingertipSpec, depths) -> np.ndarray:
    """The pad's summed sensel pressure (Pa) at ``depths`` (m) on ``sample``'s axis."""
    depths = np.asarray(depths, dtype=float)
    law = sample_law(sample, tip.radius, min(1.02 * depths[-1], 0.75 * tip.radius))
    return law_sensel_pressure(law, depths, sensel_bounds(tip)).reshape(len(depths), -1).sum(axis=1)


def contrast_block(tip: FingertipSpec, contrast: float, *, depths=DEPTHS, tops=TOPS, radii=RADII,
                   poisson: float = POISSON) -> np.ndarray:
    """The log ratios (K, T, D) of one contrast (see :class:`~palpate.core.boundary.lump_templates.LumpTemplates`)."""
    top, deep = Material("top", MODULUS, poisson), Material("deep", MODULUS * contrast, poisson)
    plain = pad_sum(AxisymmetricSample(bulk=top, thickness=THICKNESS), tip, depths)
    shapes, rs = shapes_and_radii(radii)
    out = np.zeros((len(shapes), len(tops), len(depths)))
    for k, (shape, r) in enumerate(zip(shapes, rs, strict=True)):
        for j, t in enumerate(tops):
            out[k, j] = np.log(pad_sum(_sample(top, deep, float(t), shape, r), tip, depths) / plain)
    return out


def make_lump_templates(tip: FingertipSpec, blocks: list[np.ndarray], *, depths=DEPTHS, tops=TOPS,
                        contrasts=CONTRASTS, radii=RADII, poisson: float = POISSON) -> dict:
    """The lump templates document from :func:`contrast_block` of each of ``contrasts``, in their order."""
    shapes, rs = shapes_and_radii(radii)
    log_ratio = np.stack(blocks, axis=1)
    return lump_templates_document(Pad.of(tip), poisson, depths, tops, contrasts, shapes, rs, log_ratio,
                                   "closed-form contact law on a 40 mm sample's axis (sim/contact/lump_templates.py)")
