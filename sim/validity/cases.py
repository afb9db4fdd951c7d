"""The samples of the validity table and the scene each becomes for the fidelities.

Families (all under the 8 mm tip of the default fingertip, on a table bonded to the sample's bottom):
- ``thickness``: one material, 200 kPa, nu 0.3 / 0.45 / 0.49, 2 to 100 mm thick, pressed 0.2 to 4 mm (at most 60%
  of the thickness);
- ``skin``: a soft skin (20 kPa) on a 200 kPa base or a stiff one (2 MPa) on 100 kPa, 1 / 2 / 4 mm thick, 30 mm in
  all;
- ``lump``: a 5 mm-radius sphere on the press axis, hard (2 MPa) or soft (10 kPa), its top 1 to 6 mm down in a
  30 mm, 100 kPa block;
- ``edge``: a 20 mm-thick cylinder pressed at its centre, its free side 6 to 25 mm from the press.
Moduli only scale the forces of every fidelity (each is linear elastic), so one modulus per family suffices.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from palpate.core.world.scene import Inclusion, Layer, Material, ObjectSpec
from palpate.sim.reference.sample import AxisInclusion, AxisymmetricSample

TIP_RADIUS = 0.008
FAMILIES = ("thickness", "skin", "lump", "edge")


@dataclass(frozen=True)
class ValidityCase:
    """One sample of the validity table.

    Attributes:
        name: unique key (also in the cached reference file).
        family: one of FAMILIES.
        sample: the axisymmetric sample (the FE reference's input).
        depths: indentations at which every fidelity is compared, m.
    """

    name: str
    family: str
    sample: AxisymmetricSample
    depths: tuple[float, ...]

    def feature(self, depth: float) -> float:
        """The family's dimensionless position of a press ``depth`` m deep (contact radius a = sqrt(R d)):
        thickness / a, skin thickness / a, lump depth / a, or edge distance / a."""
        a = math.sqrt(TIP_RADIUS * depth)
        s = self.sample
        if self.family == "thickness":
            return s.thickness / a
        if self.family == "skin":
            return s.layers[0].thickness / a
        if self.family == "lump":
            return s.inclusion.depth / a
        return s.radius / a

    def describe(self) -> str:
        """One line for tables."""
        return f"{self.name}: {self.sample.describe()}"


def _depths(limit: float, choices=(0.2, 0.5, 1.0, 2.0, 4.0)) -> tuple[float, ...]:
    return tuple(d * 1e-3 for d in choices if d * 1e-3 <= limit + 1e-12)


def validity_cases() -> list[ValidityCase]:
    """Every sample of the table (see the module docstring)."""
    out = []
    for nu in (0.3, 0.45, 0.49):
        for h_mm in (2, 5, 10, 20, 50, 100):
            h = h_mm * 1e-3
            out.append(ValidityCase(f"thick_{h_mm}mm_nu{nu}", "thickness",
                                    AxisymmetricSample(Material("m", 2e5, nu), h), _depths(0.6 * h)))
    soft, stiff = Material("skin_soft", 2e4, 0.3), Material("skin_stiff", 2e6, 0.4)
    for t_mm in (1, 2, 4):
        t = t_mm * 1e-3
        out.append(ValidityCase(f"skin_soft_{t_mm}mm", "skin", AxisymmetricSample(
            Material("base", 2e5, 0.45), 0.03, layers=(Layer(soft, t),)), _depths(0.004)))
        out.append(ValidityCase(f"skin_stiff_{t_mm}mm", "skin", AxisymmetricSample(
            Material("base", 1e5, 0.45), 0.03, layers=(Layer(stiff, t),)), _depths(0.004)))
    hard, soft_lump = Material("lump_hard", 2e6, 0.4), Material("lump_soft", 1e4, 0.3)
    for kind, mat, tops in (("hard", hard, (1, 3, 6)), ("soft", soft_lump, (1, 3))):
        for top in tops:
            out.append(ValidityCase(f"lump_{kind}_{top}mm", "lump", AxisymmetricSample(
                Material("bulk", 1e5, 0.45), 0.03, inclusion=AxisInclusion(mat, "sphere", top * 1e-3, 0.005)),
                _depths(0.004)))
    for r_mm in (6, 10, 15, 25):
        out.append(ValidityCase(f"edge_{r_mm}mm", "edge", AxisymmetricSample(
            Material("m", 2e5, 0.45), 0.02, radius=r_mm * 1e-3), _depths(0.003, (0.5, 1.0, 2.0, 3.0))))
    return out


def quick_cases() -> list[ValidityCase]:
    """The CI subset: nu 0.45 thicknesses, one case per other family and side."""
    keep = {"thick_2mm_nu0.45", "thick_5mm_nu0.45", "thick_10mm_nu0.45", "thick_20mm_nu0.45", "thick_100mm_nu0.45",
            "thick_20mm_nu0.49", "skin_soft_2mm", "skin_stiff_2mm", "lump_hard_1mm", "lump_soft_3mm", "edge_10mm"}
    return [c for c in validity_cases() if c.name in keep]


def case_object(case: ValidityCase) -> ObjectSpec:
    """The scene object of a case, pressed at (0, 0): wide enough that no side is within reach (except the edge
    family's cylinder, whose side is the point)."""
    s = case.sample
    if case.family == "edge":
        return ObjectSpec(case.name, "cylinder", (s.radius, s.thickness), (0.0, 0.0), s.bulk)
    width = max(0.2, 4.0 * (s.thickness + 0.02))
    inclusions = ()
    if s.inclusion is not None:
        inc = s.inclusion
        centre_z = s.thickness - inc.depth - inc.radius
        inclusions = (Inclusion(inc.material, "sphere", (0.0, 0.0, centre_z), (inc.radius,)),)
    return ObjectSpec(case.name, "box", (width, width, s.thickness), (0.0, 0.0), s.bulk, layers=s.layers,
                      inclusions=inclusions)


def contact_radii(depths) -> np.ndarray:
    """Hertz contact radius sqrt(R d) of the table's tip at ``depths`` (m), m."""
    return np.sqrt(TIP_RADIUS * np.asarray(depths, dtype=float))
