"""The rungs' images against the 3-D FE image reference: each rung pressed on each case of
:mod:`.image_cases` at the reference's depths, scored by :func:`.image.image_errors`.

``analytic`` and ``bem`` are evaluated at the depths directly (both are quasi-static: the image at a depth does not
depend on how the press got there); ``rigid`` shares analytic's contact law (:func:`palpate.sim.bem.law.press_law`)
and image, so it is scored as analytic.
``flex`` presses once to just past the deepest depth and is read on the loading branch; it is scored on the plain
objects it serves (blocks, skins) only: unmeasured over walls and lumps, ``auto`` never picks it there.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.session.sources import PressTarget
from palpate.core.world.scene import FingertipSpec, ObjectSpec, Scene
from palpate.sim.analytic import law_sensel_pressure
from palpate.sim.bem.law import press_law
from palpate.sim.bem.press import CELL, force_from_law
from palpate.sim.bem.solve import solve_ladder
from palpate.sim.bem.surface import build_surface
from palpate.sim.bem.wall import WallTable
from palpate.sim.blas import one_blas_thread
from palpate.sim.contact.stack import object_law
from palpate.sim.controller import press_profile
from palpate.sim.fingertip import sensel_bounds
from palpate.sim.flex.press import run_flex_press
from palpate.sim.validity.image import ImageErrors, PressImage, image_errors
from palpate.sim.validity.image_cases import FAMILIES, ImageCase
from palpate.sim.validity.measure import loading_force

#: The rungs scored here, and the families each is scored on.
IMAGE_RUNGS = ("analytic", "bem", "flex")
SCORED_FAMILIES = {"analytic": FAMILIES, "bem": FAMILIES, "flex": ("block", "skin")}


def scored(rung: str, family: str) -> bool:
    """Whether the image table holds ``rung`` on ``family`` (see SCORED_FAMILIES)."""
    return family in SCORED_FAMILIES.get(rung, ())


@dataclass(frozen=True)
class ImageScore:
    """One rung on one case: its errors per depth, its CPU time (s) and, for bem, how it mixed materials."""

    case: str
    family: str
    split: str
    rung: str
    errors: ImageErrors
    cpu: float
    mixing: str = ""


def rung_image(case: ImageCase, rung: str, tip: FingertipSpec, walls: WallTable | None = None) -> tuple[PressImage,
                                                                                                          str]:
    """The rung's image of ``case`` at the case's depths, and (bem) its mixing model."""
    obj = case.object_spec()
    x, y = case.press_point
    depths = np.asarray(case.depths, dtype=float)
    with one_blas_thread():
        if rung == "analytic":
            law = press_law(obj, x, y, obj.height, tip, 1.05 * depths[-1], walls=walls)
            return PressImage(depths, law.force_at(depths), law_sensel_pressure(law, depths, sensel_bounds(tip))), ""
        if rung == "bem":
            a = math.sqrt(tip.radius * depths[-1])
            surface = build_surface(obj, x, y, obj.height, tip, min(1.2 * a + 2 * CELL, 0.97 * tip.radius), CELL,
                                    a, walls)
            force, pressure = force_from_law(surface, *solve_ladder(surface, tip.radius, depths), depths,
                                             lambda: object_law(obj, x, y, obj.height, tip.radius, 1.05 * depths[-1]))
            return PressImage(depths, force, pressure.reshape(len(depths), tip.rows, tip.cols)), surface.mixing
        if rung == "flex":
            return _flex_image(obj, x, y, depths, tip), ""
    raise ValueError(f"rung_image: no image rung {rung!r}; one of {IMAGE_RUNGS}")


def _flex_image(obj: ObjectSpec, x: float, y: float, depths: np.ndarray, tip: FingertipSpec) -> PressImage:
    """One flex press to 3% past the deepest of ``depths`` (m), its force and sensel pressures read at each depth on
    the loading branch (interpolated between frames)."""
    target = PressTarget(x, y, depth=1.03 * float(depths[-1]), speed=0.01)
    profile = press_profile(target, obj.height, radius=tip.radius, timestep=0.002)
    trace = run_flex_press(Scene((obj,), fingertip=tip), obj, target, profile)
    force = loading_force(trace.indentation, trace.force, depths)
    frames = trace.sensel_pressure.reshape(len(trace.t), -1)
    pressure = np.stack([loading_force(trace.indentation, frames[:, j], depths) for j in range(frames.shape[1])],
                        axis=1)
    if not (np.all(np.isfinite(force)) and np.all(np.isfinite(pressure))):
        raise ValidationError(f"flex: the press stopped short of {depths[-1] * 1e3:.2f} mm; no image there")
    return PressImage(depths, force, pressure.reshape(len(depths), tip.rows, tip.cols))


def score(case: ImageCase, reference: PressImage, rung: str, split: str, tip: FingertipSpec,
          walls: WallTable | None = None) -> ImageScore:
    """``rung`` on ``case`` against its reference image."""
    t0 = time.process_time()
    image, mixing = rung_image(case, rung, tip, walls)
    cpu = time.process_time() - t0
    return ImageScore(case.name, case.family, split, rung, image_errors(image, reference, tip), cpu, mixing)
