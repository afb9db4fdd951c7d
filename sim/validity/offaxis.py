"""The contact law beside a box lump, against the 3-D FE (:mod:`palpate.sim.reference.fe3d`).

The law is what scenes use (:func:`palpate.sim.contact.stack.object_law`: the scene's box object and its box
inclusion give the material lookup at the press point). Both sides are compared as ratios, force with the lump over
force of the same block without it, so the 3-D mesh's own error (about 1-2%, against the axisymmetric reference on
the homogeneous block) cancels on one grid whose lines lie on the lump's faces, and the law's is its lateral part.

Cases: a 20 mm-thick block, 80 x 80 mm, bulk 25 kPa (the foam of scenarios/heterogeneous.toml); a box lump 15 mm
along x (away from the press), 20 mm wide, 10 mm tall, its top 1 or 5 mm down, 4x or 20x stiffer, its near face 0
(the press over its edge), 3, 8 or 15 mm from the press axis (or the press over its middle: near = -7.5 mm); nu
0.3 or 0.45 for both; pressed 1, 3 and 5 mm by the 8 mm tip. The law's ring mixing was chosen on the nu 0.3
cases (benchmarks/fe_offaxis_mixing.py); the nu 0.45 cases were not used for it. Soft lumps (:func:`soft_cases`:
4x and 20x softer, top 1 or 5 mm down, nu 0.45 or 0.3; a cyst or a void-like pocket under a skin) are separate.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from palpate.core.world.scene import Inclusion, Layer, Material, ObjectSpec, material_at
from palpate.sim.contact.stack import object_law
from palpate.sim.reference.fe3d import BoxBlock, BoxLump
from palpate.sim.reference.fe3d_solve import fe3d_press

TIP = 0.008
THICKNESS = 0.02
HALF = 0.04
BULK_E = 25e3
LUMP_LENGTH, LUMP_WIDTH, LUMP_HEIGHT = 0.015, 0.02, 0.01
DEPTHS = np.array([1.0, 3.0, 5.0]) * 1e-3
#: Element edge of the 3-D mesh across the contact (homogeneous block within 2% of the axisymmetric reference).
H = 0.001


@dataclass(frozen=True)
class OffAxisCase:
    """One lump beside the press: ``contrast`` = lump E / bulk E; ``top``, ``near``: the lump's top depth and its
    near face's distance from the press axis, m; ``poisson`` of both materials."""

    contrast: float
    top: float
    near: float
    poisson: float

    @property
    def label(self) -> str:
        return (f"{self.contrast:g}x top {1e3 * self.top:g} mm near {1e3 * self.near:+g} mm "
                f"nu {self.poisson:g}")


@dataclass(frozen=True)
class OffAxisRow:
    """The law's and the 3-D FE's force ratio (with lump / without) at each of :data:`DEPTHS`, and the law's error
    (law ratio / FE ratio - 1)."""

    case: OffAxisCase
    depth: np.ndarray
    law_ratio: np.ndarray
    fe_ratio: np.ndarray

    @property
    def error(self) -> np.ndarray:
        return self.law_ratio / self.fe_ratio - 1.0


def offaxis_cases(quick: bool = False) -> list[OffAxisCase]:
    """The cases of the module docstring (``quick``: 20x, top 1 mm, nu 0.3, near 0 and 3 mm)."""
    if quick:
        return [OffAxisCase(20.0, 0.001, near, 0.3) for near in (0.0, 0.003)]
    out = []
    for nu in (0.3, 0.45):
        for contrast in (4.0, 20.0):
            for top in (0.001, 0.005):
                for near in (0.0, 0.003, 0.008, 0.015):
                    out.append(OffAxisCase(contrast, top, near, nu))
        out += [OffAxisCase(20.0, top, -LUMP_LENGTH / 2, nu) for top in (0.001, 0.005)]
    return out


def soft_cases() -> list[OffAxisCase]:
    """Soft lumps (module docstring): 4x and 20x softer than the bulk, top 1 or 5 mm down, nu 0.45 or 0.3, near
    face 0, 3 and 8 mm from the press axis or the press over the lump's middle."""
    return [OffAxisCase(contrast, top, near, nu) for nu in (0.45, 0.3) for top in (0.001, 0.005)
            for contrast in (0.25, 0.05) for near in (0.0, 0.003, 0.008, -LUMP_LENGTH / 2)]


def case_block(case: OffAxisCase | None, poisson: float = 0.3) -> BoxBlock:
    """The 3-D FE's block (``case`` None: without a lump, at ``poisson``)."""
    if case is None:
        return BoxBlock(Material("bulk", BULK_E, poisson), THICKNESS, HALF, HALF)
    bulk = Material("bulk", BULK_E, case.poisson)
    lump = Material("lump", BULK_E * case.contrast, case.poisson)
    return BoxBlock(bulk, THICKNESS, HALF, HALF,
                    BoxLump(lump, case.near, LUMP_LENGTH, LUMP_WIDTH, case.top, LUMP_HEIGHT))


def case_object(case: OffAxisCase | None, poisson: float = 0.3) -> ObjectSpec:
    """The same block as a scene object pressed at (0, 0), for the contact law."""
    block = case_block(case, poisson)
    inclusions = ()
    if case is not None:
        lump = block.lump
        centre = (lump.near + lump.length / 2, 0.0, THICKNESS - lump.depth - lump.height / 2)
        inclusions = (Inclusion(lump.material, "box", centre, (lump.length, lump.width, lump.height)),)
    return ObjectSpec("block", "box", (2 * HALF, 2 * HALF, THICKNESS), (0.0, 0.0), block.material,
                      inclusions=inclusions)


def law_force(case: OffAxisCase | None, poisson: float = 0.3) -> np.ndarray:
    """The contact law's force (N) at :data:`DEPTHS` pressing the case's object at (0, 0)."""
    law = object_law(case_object(case, poisson), 0.0, 0.0, THICKNESS, TIP, float(DEPTHS[-1]))
    return law.force_at(DEPTHS)


def fe_force(case: OffAxisCase, h: float = H, *, without: bool = False) -> np.ndarray:
    """The 3-D FE's force (N) at :data:`DEPTHS`; ``without``: the lump given the bulk's material, on the same grid
    (its faces stay grid lines), so the ratio of the two compares like with like."""
    block = case_block(case)
    if without:
        block = replace(block, lump=replace(block.lump, material=block.material))
    return fe3d_press(block, TIP, DEPTHS, h=h).force


def compare(case: OffAxisCase, h: float = H, cache: dict | None = None) -> OffAxisRow:
    """Law vs 3-D FE ratios for ``case``; ``cache`` (a dict the caller keeps) shares the forces without the lump
    between cases on the same grid."""
    cache = {} if cache is None else cache
    key = ("fe", case.top, case.near, case.poisson, h)
    if key not in cache:
        cache[key] = fe_force(case, h, without=True)
    if ("law", case.poisson) not in cache:
        cache[("law", case.poisson)] = law_force(None, case.poisson)
    law = law_force(case) / cache[("law", case.poisson)]
    fe = fe_force(case, h) / cache[key]
    return OffAxisRow(case, DEPTHS.copy(), law, fe)


@dataclass(frozen=True)
class BuriedBoxPress:
    """A scene's buried box pressed over its middle: the 3-D FE's block, its force and the contact law's (N at
    ``depth``, m), and each reference material's force alone on a block as thick (name -> N)."""

    block: BoxBlock
    depth: np.ndarray
    fe: np.ndarray
    law: np.ndarray
    plain: dict[str, np.ndarray]


def buried_box_press(obj: ObjectSpec, box: Inclusion, tip_radius: float, depths, references: dict[str, Material],
                     margin: float = 0.02) -> BuriedBoxPress:
    """What a press over the middle of ``obj``'s box inclusion feels like: the 3-D FE with the box in a block of
    the material beside it (``margin`` m past it on every side), under the material above it where that differs,
    beside the contact law at that point of ``obj`` and each of ``references`` (name -> material) alone."""
    depths = np.asarray(depths, dtype=float)
    (cx, cy, cz), (sx, sy, sz) = box.center, box.size
    top = obj.height - cz - sz / 2
    above, beside = material_at(obj, np.array([[cx, cy, obj.height - top / 2], [cx + sx / 2 + 3e-3, cy, cz]]))
    half = max(sx, sy) / 2 + margin
    block = BoxBlock(beside, obj.height, half, half, BoxLump(box.material, -sx / 2, sx, sy, top, sz),
                     skin=None if above == beside else Layer(above, top))
    deepest = float(depths[-1])
    plain = {name: object_law(ObjectSpec("plain", "box", (2 * half, 2 * half, obj.height), (0.0, 0.0), m), 0.0, 0.0,
                              obj.height, tip_radius, deepest).force_at(depths) for name, m in references.items()}
    return BuriedBoxPress(block, depths, fe3d_press(block, tip_radius, depths).force,
                          object_law(obj, cx, cy, obj.height, tip_radius, deepest).force_at(depths), plain)
