"""The `flex` mesh correction for plates: a stiff skin's kappa, measured on calibration plates.

The block's mesh correction (:mod:`palpate.sim.flex.calibration`) is measured on homogeneous blocks, where the press
loads a field concentrated within about a cell. A stiff skin spreads its load over a few bending lengths, which the
5 mm cells resolve nearly as the continuum does, so the block's kappa over-corrects it, the more so the thicker
the skin, while the plate window's coarse outer cells stiffen the spread load again, more as it spreads with depth
(docs/results.md has the measurements). Neither is the block's, so a press over a stiff top layer
multiplies the block's kappa by q = kappa_plate / kappa_block, measured here:

    q(a / cell, nu_skin, nu_base, t, E_skin / E_base, H) = (F_flex / F_law) / kappa_block

on calibration plates (PLATE_SKIN_POISSONS x PLATE_BASE_POISSONS x PLATE_RATIOS x PLATE_SKINS x PLATE_HEIGHTS, none
of them a validity-table stack), each meshed exactly as the shipped plate window meshes it, pressed by flex
uncorrected, against the exact layered contact law of the same stack (within 0.5% of the FE reference on the table's
skins), over the free table's kappa_block at the press's contact radius, the Poisson ratio of the skin and the
stack's height (what the press reads). q carries the block table's ripple in a / cell inverted (a plate's
uncorrected force is smooth where a block's ripples), so it is tabulated on the same dense a / cell grid.

Interpolation (chosen in the earlier 90 mm window, not rechosen, on calibration stacks like skin_stiff_2mm, 1.75 mm
of 12x on 25 and 40 mm and 2.25 mm of 30x on 20 mm, not on the validity cases): linear in a / cell, log skin
thickness, log modulus ratio and log height, clamped at the table's ends; linear in the skin's Poisson ratio and in
log(K / G) of the base's (the plate window's pinned sides confine the base, more the less compressible it is; chosen
over linear in nu on four stacks of bases at nu 0.4-0.48, docs/results.md). Below its first ratio (2x) q is
that row's: the plate window's own difference from the free table's block (0.12-0.19 from 1 on bases of nu 0.3 and
0.45, 0.38-0.40 on nu 0.49), which going to q = 1 at ratio 1 put 11% into a 1.3x skin on a base of nu 0.49 (chosen
on three skins of 1.2-1.5x, docs/results.md).

models/flex_plate_calibration.json holds the table for one cell size; ``benchmarks/flex_plate.py --calibrate``
remeasures it (:func:`palpate.sim.flex.calibrate.measure_plate_calibration`); it depends on the block table, so it
is remeasured whenever that one is.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.files import number_array
from palpate.core.world.resources import models_dir
from palpate.core.world.scene import ObjectSpec
from palpate.sim.validity.reference import read_document

#: The shipped table.
PLATE_CALIBRATION_PATH = models_dir() / "flex_plate_calibration.json"
PLATE_FORMAT = "palpate-flex-plate-calibration"
PLATE_FORMAT_VERSION = 2
#: The calibration plates: skin / base Young's modulus ratios, skin thicknesses (m) and stack heights (m); none is
#: a validity-table stack (20x; 1, 2, 4 mm; 30 mm). The stiffest is 70x because a 0.7 mm skin of 100x on 60 mm
#: diverges in flex (the tip sinks between the surface vertices).
PLATE_RATIOS = (2.0, 6.0, 25.0, 70.0)
PLATE_SKINS = (0.0007, 0.00125, 0.0025, 0.0045)
PLATE_HEIGHTS = (0.012, 0.025, 0.06)
#: The calibration plates' Poisson ratios of the skin and of the base.
PLATE_SKIN_POISSONS = (0.3, 0.4)
PLATE_BASE_POISSONS = (0.3, 0.45, 0.49)
#: A plate sample's default Poisson ratios (the validity table's stiff skins'), and the base's modulus, Pa (flex and
#: the law are linear, so only the ratio matters).
SKIN_POISSON = 0.4
BASE_POISSON = 0.45
BASE_YOUNG = 1.0e5


@dataclass(frozen=True)
class PlateTable:
    """A loaded plate calibration.

    Attributes:
        cell_over_radius: cell edge / tip radius it was measured with.
        contact_over_cell: (c,) a / cell, increasing.
        skin_poisson: (p,) the skin's Poisson ratio, increasing.
        base_poisson: (b,) the base's Poisson ratio, increasing.
        modulus_ratio: (m,) E_skin / E_base, increasing, > 1.
        skin: (s,) skin thicknesses, m, increasing.
        height: (h,) stack heights, m, increasing.
        factor: (p, b, m, s, h, c) q.
        measured_to: (p, b, m, s, h) the largest a / cell each plate was pressed to (beyond it its row is held).
    """

    cell_over_radius: float
    contact_over_cell: np.ndarray
    skin_poisson: np.ndarray
    base_poisson: np.ndarray
    modulus_ratio: np.ndarray
    skin: np.ndarray
    height: np.ndarray
    factor: np.ndarray
    measured_to: np.ndarray


def load_plate_calibration(path: Path | str = PLATE_CALIBRATION_PATH) -> PlateTable:
    """Read and validate a plate calibration file (bounded JSON, see :func:`palpate.core.files.read_json`).

    Raises:
        ValidationError: missing, too large, not JSON, another format or version, a bad or inconsistent key,
            naming the file and the key.
    """
    path = Path(path)
    raw = read_document(path, "flex plate calibration", PLATE_FORMAT, PLATE_FORMAT_VERSION,
                        "regenerate it with `.venv/bin/python benchmarks/flex_plate.py --calibrate`")
    arrays = {key: number_array(raw.get(key), f"{path}: {key}", ndim, max_size=100_000) for key, ndim in (
        ("cell_over_radius", 0), ("contact_over_cell", 1), ("skin_poisson", 1), ("base_poisson", 1),
        ("modulus_ratio", 1), ("skin", 1), ("height", 1), ("factor", 6), ("measured_to", 5))}
    axes = ("skin_poisson", "base_poisson", "modulus_ratio", "skin", "height")
    shape = tuple(len(arrays[k]) for k in axes)
    if arrays["factor"].shape != shape + (len(arrays["contact_over_cell"]),) or arrays["measured_to"].shape != shape:
        raise ValidationError(f"{path}: factor must be skin_poisson x base_poisson x modulus_ratio x skin x height x "
                              "contact_over_cell and measured_to the same without contact_over_cell")
    increasing = all(np.all(np.diff(arrays[k]) > 0) for k in ("contact_over_cell",) + axes)
    poissons = np.concatenate([arrays["skin_poisson"], arrays["base_poisson"]])
    if not (increasing and arrays["cell_over_radius"] > 0 and arrays["modulus_ratio"][0] > 1.0
            and arrays["skin"][0] > 0 and arrays["height"][0] > 0 and np.all(arrays["factor"] > 0)
            and np.all(arrays["measured_to"] > 0) and np.all((poissons > -1.0) & (poissons < 0.5))):
        raise ValidationError(f"{path}: needs increasing contact_over_cell, Poisson ratios (in (-1, 0.5)), "
                              "modulus_ratio (> 1), skin and height (> 0 m), cell_over_radius > 0 and factors > 0")
    return PlateTable(cell_over_radius=float(arrays["cell_over_radius"]), **{k: arrays[k] for k in (
        ("contact_over_cell",) + axes + ("factor", "measured_to"))})


@dataclass(frozen=True)
class PlateSkin:
    """The stiff top layer a plate correction is read for: its thickness (m), E_skin / E_below, and the Poisson
    ratios of the skin and of the layer below it."""

    thickness: float
    modulus_ratio: float
    skin_poisson: float
    base_poisson: float


def plate_skin(obj: ObjectSpec) -> PlateSkin | None:
    """``obj``'s top layer if it is stiffer than what lies under it (the plate the table was measured on), else
    None (no layer, a soft top, or a stiff layer under a soft one: the table holds no such stack)."""
    if not obj.layers:
        return None
    below = obj.layers[1].material if len(obj.layers) > 1 else obj.material
    top = obj.layers[0]
    if top.material.young <= below.young:
        return None
    return PlateSkin(thickness=float(top.thickness), modulus_ratio=float(top.material.young / below.young),
                     skin_poisson=float(top.material.poisson), base_poisson=float(below.poisson))


def _weights(x: float, nodes: np.ndarray) -> np.ndarray:
    """Linear interpolation weights (n,) at ``x`` on increasing ``nodes``, clamped at the ends."""
    return np.array([np.interp(x, nodes, row) for row in np.eye(len(nodes))])


def bulk_over_shear(poisson):
    """K / G = 2 (1 + nu) / (3 (1 - 2 nu)) of a Poisson ratio (or an array of them)."""
    nu = np.asarray(poisson, dtype=float)
    return 2.0 * (1.0 + nu) / (3.0 * (1.0 - 2.0 * nu))


@dataclass(frozen=True)
class PlateCurve:
    """q against a / cell for one press (its skin, stack height and cells fixed).

    Attributes:
        contact_over_cell: (c,) a / cell.
        factor: (c,) q.
        reach: the largest a / cell measured (interpolated like the factor).
        outside: the cell size is over 5% from the table's, or the stack lies outside the table's thicknesses,
            heights, stiffest ratio or Poisson ratios (its end values are used).
    """

    contact_over_cell: np.ndarray
    factor: np.ndarray
    reach: float
    outside: bool

    def at(self, contact_over_cell: float) -> float:
        """q at contact radius / cell ``contact_over_cell`` (held at the table's ends)."""
        return float(np.interp(contact_over_cell, self.contact_over_cell, self.factor))

    def extrapolated(self, contact_over_cell: float) -> bool:
        """Whether q at ``contact_over_cell`` is read outside what was measured."""
        return bool(self.outside or contact_over_cell > self.reach * 1.05)


def plate_curve(table: PlateTable, skin: PlateSkin, height: float, cell_over_radius: float) -> PlateCurve:
    """q for a press on ``skin`` over a stack ``height`` m tall with cells of ``cell_over_radius`` tip radii,
    reduced once per press to a curve in a / cell (see the module docstring for the interpolation)."""
    if not (skin.thickness > 0 and skin.modulus_ratio > 1.0 and height > 0 and cell_over_radius > 0
            and -1.0 < skin.skin_poisson < 0.5 and -1.0 < skin.base_poisson < 0.5):
        raise ValidationError(f"flex: a plate needs a skin > 0 m, stiffer than its base, a height > 0 m and cells "
                              f"> 0, got {skin!r}, {height!r}, {cell_over_radius!r}")
    w_p = _weights(skin.skin_poisson, table.skin_poisson)
    w_b = _weights(float(np.log(bulk_over_shear(skin.base_poisson))), np.log(bulk_over_shear(table.base_poisson)))
    factor = np.einsum("p,b,pbmshc->mshc", w_p, w_b, table.factor)
    reach = np.einsum("p,b,pbmsh->msh", w_p, w_b, table.measured_to)
    # below the first ratio its row holds: the plate window's own difference from the free table's block
    w_m = _weights(float(np.log(skin.modulus_ratio)), np.log(table.modulus_ratio))
    w_s = _weights(float(np.log(skin.thickness)), np.log(table.skin))
    w_h = _weights(float(np.log(height)), np.log(table.height))
    reach_at = float(np.einsum("m,s,h,msh->", w_m, w_s, w_h, reach))
    outside = (abs(table.cell_over_radius / cell_over_radius - 1.0) > 0.05
               or skin.modulus_ratio > table.modulus_ratio[-1] * 1.05
               or not table.skin[0] * 0.95 <= skin.thickness <= table.skin[-1] * 1.05
               or not table.height[0] * 0.95 <= height <= table.height[-1] * 1.05
               or not table.skin_poisson[0] - 0.01 <= skin.skin_poisson <= table.skin_poisson[-1] + 0.01
               or not table.base_poisson[0] - 0.01 <= skin.base_poisson <= table.base_poisson[-1] + 0.01)
    return PlateCurve(contact_over_cell=table.contact_over_cell,
                      factor=np.einsum("m,s,h,mshc->c", w_m, w_s, w_h, factor), reach=reach_at, outside=bool(outside))
