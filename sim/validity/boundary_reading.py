"""The per-press boundary reading (:mod:`palpate.core.boundary.reading`) against the 3-D FE image reference: each
wall and block case's FE image turned into 8-bit counts by the default taxel model (seeded noise), read, and
compared with the case's true wall.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from palpate.core.boundary.reading import NoiseModel, read_boundary
from palpate.core.boundary.templates import BoundaryTemplates
from palpate.core.session.boundaries import noise_of
from palpate.core.world.scene import TaxelSensorSpec
from palpate.sim.sensors import taxel_counts
from palpate.sim.validity.image_cases import image_cases
from palpate.sim.validity.image_reference import ImageReference, reference_image

#: Depths the reading is checked at, m (the reference's deeper presses: the contact spans the pad).
DEPTHS = (0.002, 0.003, 0.004)


@dataclass(frozen=True)
class ReadingCheck:
    """One reading of one FE case at one depth and noise seed.

    Attributes: case, family ("wall" or "block"), split, depth (m), seed; the truth (angle rad, offset m, contrast;
    NaN for a block); the reading's p_boundary, angle, angle_sd, offset, offset_sd and contrast.
    """

    case: str
    family: str
    split: str
    depth: float
    seed: int
    angle: float
    offset: float
    contrast: float
    p_boundary: float
    read_angle: float
    angle_sd: float
    read_offset: float
    offset_sd: float
    read_contrast: float

    @property
    def side_right(self) -> bool:
        """The reading's normal points to the harder side (within 90 deg of the true normal)."""
        return math.cos(self.read_angle - self.angle) > 0

    @property
    def angle_error(self) -> float:
        """Absolute angle between read and true normals, rad (0 to pi)."""
        return abs(math.remainder(self.read_angle - self.angle, 2 * math.pi))

    @property
    def position_error(self) -> float:
        """Distance of the read wall from the true one at the press axis and along the true normal, m: the read
        line's signed distance from the axis, projected on the true normal, against the true offset."""
        cos = math.cos(self.read_angle - self.angle)
        if cos <= 0:
            return math.inf
        return abs(self.read_offset / cos - self.offset)


def check_readings(reference: ImageReference, templates: BoundaryTemplates, *, seeds=range(4), depths=DEPTHS,
                   spec: TaxelSensorSpec | None = None, noise: NoiseModel | None = None,
                   splits=("tuning", "report")) -> list[ReadingCheck]:
    """Read every wall and block case of ``reference`` at ``depths`` with each noise seed."""
    spec = spec or TaxelSensorSpec()
    noise = noise or noise_of(spec)
    out = []
    for case in image_cases():
        if case.family not in ("wall", "block") or case.split not in splits:
            continue
        image = reference_image(reference, case)
        wall = case.block.wall
        truth = ((wall.angle, wall.offset, wall.material.young / case.block.material.young) if wall is not None
                 else (math.nan, math.nan, 1.0))
        for depth in depths:
            k = int(np.argmin(np.abs(image.depth - depth)))
            for seed in seeds:
                counts = taxel_counts(image.pressure[k], spec, np.random.default_rng(seed)).astype(float)
                r = read_boundary(counts, float(image.depth[k]), templates, noise)
                out.append(ReadingCheck(case.name, case.family, case.split, float(image.depth[k]), seed, *truth,
                                        r.p_boundary, r.angle, r.angle_sd, r.offset, r.offset_sd, r.contrast))
    return out
