"""The cases of the 3-D FE image reference (models/image_reference.json) and the scene each is for every rung.

Every case is a box block 30 mm thick, 80 x 80 mm (sides free, bonded to the table: at 40 mm from the press the
sides change the image by less than the mesh does, see benchmarks/image_reference.py), pressed at the centre of its
top by the default fingertip (8 mm sphere, 4x4 pad) 0.5, 1, 2, 3 and 4 mm deep. Families:

- ``block``: one material, 115 kPa, nu 0.3 / 0.45 / 0.49;
- ``wall``: two materials split by a vertical plane n . (x, y) = offset, n = (cos t, sin t), the second (named
  after the bar, e.g. 20|115 kPa: 115 kPa) on the far side; contrasts 20|115, 50|100, 10|200 kPa; offsets -6 to
  +6 mm; t = 0 (the wall along y, the stiffer side at +x for a positive contrast), 90 and 45 deg; nu 0.3 / 0.45 /
  0.49 for both materials (not every combination: :func:`image_cases` lists them);
- ``lump``: a hard box lump (2 MPa in 115 kPa, nu 0.45), 10 mm along x, 10 mm wide, 5 mm tall, its top 1 mm down,
  its near face 0, 2, 4 or 6 mm beside the press axis or centred under it;
- ``skin``: a soft skin (20 kPa) 0.5 or 1 mm thick on 200 kPa, nu 0.45.

About a third of the cases are ``report`` (held out from tuning), spread over families, offsets, contrasts and
orientations; the rest are ``tuning``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.world.scene import Inclusion, Layer, Material, ObjectSpec
from palpate.sim.reference.fe3d import BoxBlock, BoxLump, Wall

FAMILIES = ("block", "wall", "lump", "skin")
SPLITS = ("tuning", "report")
THICKNESS = 0.03
HALF = 0.04
DEPTHS = (0.0005, 0.001, 0.002, 0.003, 0.004)
#: Strip width of the column staircase that stands in for a rotated wall in a scene, m: fine near the press,
#: coarse beyond (the image does not see the wall's far reaches).
STAIR_NEAR, STAIR_FAR, STAIR_SWITCH = 0.00025, 0.002, 0.012


def material(young: float, poisson: float) -> Material:
    """A case material named by its modulus in kPa (e.g. '115kPa')."""
    return Material(f"{young / 1e3:g}kPa", young, poisson)


@dataclass(frozen=True)
class ImageCase:
    """One case of the image reference.

    Attributes:
        name: unique key (also in the cached file).
        family: one of FAMILIES.
        block: the 3-D FE's description (see :class:`palpate.sim.reference.fe3d.BoxBlock`), pressed at its centre.
        depths: indentations, m.
        split: "tuning" or "report".
    """

    name: str
    family: str
    block: BoxBlock
    depths: tuple[float, ...] = DEPTHS
    split: str = "tuning"

    def __post_init__(self) -> None:
        if self.family not in FAMILIES:
            raise ValidationError(f"ImageCase.family must be one of {FAMILIES}, got {self.family!r}")
        if self.split not in SPLITS:
            raise ValidationError(f"ImageCase.split must be one of {SPLITS}, got {self.split!r}")

    @property
    def press_point(self) -> tuple[float, float]:
        """Where every rung presses, (x, y) m in the world: the centre of the object's top (the FE's origin)."""
        return (0.0, 0.0)

    def object_spec(self) -> ObjectSpec:
        """The equivalent scene object: a box of the FE block's size centred on the press point, the wall as
        "column" inclusions (one filling the far side at t = 0 / 90 deg; a staircase of strips at other angles,
        STAIR_NEAR wide within STAIR_SWITCH of the press, STAIR_FAR beyond), the lump as a "box" inclusion, the
        skin as a layer."""
        b = self.block
        inclusions = wall_columns(b.wall, b.half_x, b.half_y, b.thickness) if b.wall is not None else []
        if b.lump is not None:
            lump = b.lump
            inclusions.append(Inclusion(lump.material, "box",
                                        (lump.near + lump.length / 2, 0.0, b.thickness - lump.depth - lump.height / 2),
                                        (lump.length, lump.width, lump.height)))
        return ObjectSpec(name=self.name, shape="box", size=(2 * b.half_x, 2 * b.half_y, b.thickness),
                          position=self.press_point, material=b.material,
                          layers=() if b.skin is None else (b.skin,), inclusions=tuple(inclusions))


def _strips(half: float) -> np.ndarray:
    near = np.arange(-STAIR_SWITCH, STAIR_SWITCH + 1e-12, STAIR_NEAR)
    far = np.arange(STAIR_SWITCH, half, STAIR_FAR)[1:]
    return np.unique(np.concatenate([[-half], -far[::-1], near, far, [half]]))


def wall_columns(wall: Wall, half_x: float, half_y: float, thickness: float) -> list[Inclusion]:
    """The wall's far side as "column" inclusions of a box object centred on the origin (see
    :meth:`ImageCase.object_spec`)."""
    c, s = wall.normal
    if wall.axis_aligned:
        half_along, pos = (half_x, c) if c != 0.0 else (half_y, s)
        edge = wall.offset / pos
        lo, hi = (edge, half_along) if pos > 0 else (-half_along, edge)
        if c != 0.0:
            return [Inclusion(wall.material, "column", ((lo + hi) / 2, 0.0, thickness / 2), (hi - lo, 2 * half_y))]
        return [Inclusion(wall.material, "column", (0.0, (lo + hi) / 2, thickness / 2), (2 * half_x, hi - lo))]
    out = []
    edges = _strips(half_x)
    for x0, x1 in zip(edges[:-1], edges[1:], strict=True):
        edge = (wall.offset - c * 0.5 * (x0 + x1)) / s
        lo, hi = (max(edge, -half_y), half_y) if s > 0 else (-half_y, min(edge, half_y))
        if hi - lo > 1e-9:
            out.append(Inclusion(wall.material, "column", ((x0 + x1) / 2, (lo + hi) / 2, thickness / 2),
                                 (x1 - x0, hi - lo)))
    return out


def reference_block(bulk: Material, **kw) -> BoxBlock:
    """The reference's block (30 mm thick, 80 x 80 mm) of ``bulk``; ``kw``: BoxBlock's wall, lump or skin."""
    return BoxBlock(bulk, THICKNESS, HALF, HALF, **kw)


def wall_case(near_kpa: float, far_kpa: float, poisson: float, angle_deg: float, offset_mm: float,
              split: str = "tuning") -> ImageCase:
    """A wall case (see the module docstring): ``near_kpa`` | ``far_kpa`` moduli, kPa; offset mm; angle deg."""
    near, far = material(near_kpa * 1e3, poisson), material(far_kpa * 1e3, poisson)
    name = f"wall_{near_kpa:g}-{far_kpa:g}kPa_t{angle_deg:g}_o{offset_mm:+g}mm_nu{poisson:g}"
    return ImageCase(name, "wall", reference_block(near, wall=Wall(far, math.radians(angle_deg), offset_mm * 1e-3)),
                     split=split)


def lump_case(near_mm: float | None, split: str = "tuning") -> ImageCase:
    """The hard lump with its near face ``near_mm`` beside the axis (None: centred under it)."""
    length = 0.01
    near = -length / 2 if near_mm is None else near_mm * 1e-3
    lump = BoxLump(material(2e6, 0.45), near, length, 0.01, 0.001, 0.005)
    label = "under" if near_mm is None else f"near{near_mm:g}mm"
    block = reference_block(material(115e3, 0.45), lump=lump)
    return ImageCase(f"lump_2000-115kPa_{label}", "lump", block, split=split)


def core_cases() -> list[ImageCase]:
    """The first subset: the plain block at nu 0.45 and the 20|115 kPa wall at t = 0, nu 0.45, offsets -4, -2, 0,
    1, 2, 4, 6 mm."""
    names = {"block_115kPa_nu0.45"} | {wall_case(20, 115, 0.45, 0, o).name for o in (-4, -2, 0, 1, 2, 4, 6)}
    return [c for c in image_cases() if c.name in names]


def image_cases() -> list[ImageCase]:
    """Every case of the reference (see the module docstring), names unique."""
    cases = [ImageCase(f"block_115kPa_nu{nu:g}", "block", reference_block(material(115e3, nu)), split=split)
             for nu, split in ((0.3, "tuning"), (0.45, "tuning"), (0.49, "report"))]
    report = {  # (near, far, nu, angle): offsets held out
        (20, 115, 0.45, 0): (-6, -1, 4), (50, 100, 0.45, 0): (1, -6), (10, 200, 0.45, 0): (-1, 6),
        (20, 115, 0.3, 0): (4,), (20, 115, 0.49, 0): (-2,), (20, 115, 0.45, 90): (2,), (10, 200, 0.45, 90): (0,),
        (20, 115, 0.45, 45): (-2,), (50, 100, 0.45, 45): (0,),
    }
    grid = {
        (20, 115, 0.45, 0): (-6, -4, -2, -1, 0, 1, 2, 4, 6), (50, 100, 0.45, 0): (-6, -2, 0, 1, 4),
        (10, 200, 0.45, 0): (-4, -1, 0, 2, 6), (20, 115, 0.3, 0): (-2, 0, 2, 4), (20, 115, 0.49, 0): (-4, -2, 0, 2),
        (20, 115, 0.45, 90): (-2, 0, 2), (10, 200, 0.45, 90): (0,), (20, 115, 0.45, 45): (-2, 0, 2),
        (50, 100, 0.45, 45): (0,),
    }
    for key, offsets in grid.items():
        near, far, nu, angle = key
        cases += [wall_case(near, far, nu, angle, o, "report" if o in report[key] else "tuning") for o in offsets]
    cases += [lump_case(n, split) for n, split in ((0, "tuning"), (2, "report"), (4, "tuning"), (6, "tuning"),
                                                    (None, "report"))]
    for skin_mm, split in ((0.5, "tuning"), (1.0, "report")):
        block = reference_block(material(200e3, 0.45), skin=Layer(material(20e3, 0.45), skin_mm * 1e-3))
        cases.append(ImageCase(f"skin_20-200kPa_{skin_mm:g}mm", "skin", block, split=split))
    return cases
