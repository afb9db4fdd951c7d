"""Boundary templates made by the bem rung (see :mod:`palpate.core.boundary.templates`): the default fingertip
pressed into a block split by a wall, at every depth, angle 0-45 deg, offset and contrast of a grid.

The block is the image reference's (30 mm thick, 80 x 80 mm, bonded to the table) so that the templates and the
3-D FE the reading is checked against describe the same object; only the wall differs from case to case.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from palpate.core.boundary.templates import REFERENCE_MODULUS, Pad, templates_document
from palpate.core.world.scene import FingertipSpec
from palpate.sim.bem.wall import WallTable
from palpate.sim.validity.image_cases import ImageCase, material, reference_block, wall_case
from palpate.sim.validity.image_measure import rung_image

#: The grid the shipped file holds.
DEPTHS = (0.0005, 0.001, 0.0015, 0.002, 0.0025, 0.003, 0.0035, 0.004, 0.005)
ANGLES_DEG = (0.0, 15.0, 30.0, 45.0)
OFFSETS = tuple(np.round(np.arange(-7.0, 7.01, 0.5) * 1e-3, 6))
CONTRASTS = (1.5, 2.5, 4.0, 6.0, 10.0, 20.0)
POISSON = 0.45


def _image(case: ImageCase, depths: tuple[float, ...], tip: FingertipSpec, walls: WallTable) -> np.ndarray:
    image, _ = rung_image(dataclasses.replace(case, depths=depths), "bem", tip, walls)
    return image.pressure


def make_templates(tip: FingertipSpec, walls: WallTable, *, depths=DEPTHS, angles_deg=ANGLES_DEG, offsets=OFFSETS,
                   contrasts=CONTRASTS, poisson: float = POISSON, progress=None) -> dict:
    """The templates document for ``tip`` (see :func:`palpate.core.boundary.templates.templates_document`).

    ``progress``, when given, is called with each finished wall case (e.g. a tqdm bar's ``update``).
    """
    soft_kpa = REFERENCE_MODULUS / 1e3
    block = reference_block(material(REFERENCE_MODULUS, poisson))
    plain = _image(ImageCase("plain", "block", block), depths, tip, walls)
    wall = np.zeros((len(depths), len(angles_deg), len(offsets), len(contrasts), tip.rows, tip.cols))
    for a, angle in enumerate(angles_deg):
        for o, offset in enumerate(offsets):
            for c, contrast in enumerate(contrasts):
                case = wall_case(soft_kpa, soft_kpa * contrast, poisson, angle, offset * 1e3)
                wall[:, a, o, c] = _image(case, depths, tip, walls)
                if progress is not None:
                    progress(1)
    return templates_document(Pad.of(tip), poisson, depths, angles_deg, offsets, contrasts, wall, plain,
                              "bem rung on the image reference's block (sim/bem/templates.py)")
