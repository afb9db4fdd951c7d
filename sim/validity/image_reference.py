"""The 3-D FE image reference, computed once and cached as data (models/image_reference.json, validated on load):
per case of :mod:`.image_cases`, the force and the 4x4 sensel image at each depth, and the image's change under
mesh refinement for a few cases.

Regenerate with ``.venv/bin/python benchmarks/image_reference.py --write`` (tens of minutes on one core).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.files import number_array
from palpate.core.world.resources import models_dir
from palpate.core.world.scene import FingertipSpec
from palpate.sim.reference.fe3d_image import fe3d_image
from palpate.sim.validity.image import PressImage, image_errors
from palpate.sim.validity.image_cases import FAMILIES, SPLITS, ImageCase
from palpate.sim.validity.reference import read_document

IMAGE_REFERENCE_PATH = models_dir() / "image_reference.json"
FORMAT = "palpate-fe-image-reference"
VERSION = 1
#: Element edge across the contact, m, and growth per cell away from it, of the shipped reference.
H = 0.0007
GROWTH = 1.3
#: The refinement study: each case at h x these factors (h / sqrt(2) steps), the last the finest.
CONVERGENCE_FACTORS = (1.0, 1 / 2**0.5)
#: Cases with a material at or above this Poisson ratio get NEAR_INCOMPRESSIBLE's mesh: trilinear bricks with
#: one-point volume converge slowly there, and tall bricks under the contact stiffen the block (the plain block at
#: nu 0.49 +6% at 1 mm with the default mesh against the axisymmetric FE; benchmarks/image_reference.py).
NEAR_INCOMPRESSIBLE_NU = 0.48
#: The two meshes as keyword arguments of :func:`fe3d_image`.
DEFAULT_MESH = MappingProxyType({"h": H, "growth": GROWTH})
NEAR_INCOMPRESSIBLE = MappingProxyType({"h": 0.0005, "growth": GROWTH, "depth_growth": 1.1, "depth_uniform": 1.0})
MAX_CASES = 500


def tip_dict(tip: FingertipSpec) -> dict:
    return {"radius": tip.radius, "rows": tip.rows, "cols": tip.cols, "pitch": tip.pitch,
            "sensel_size": tip.sensel_size}


def describe(case: ImageCase) -> str:
    """One line: the case's materials and geometry in mm and kPa."""
    b = case.block
    out = [f"{b.material.young / 1e3:g} kPa nu {b.material.poisson:g}",
           f"{2e3 * b.half_x:g} x {2e3 * b.half_y:g} x {1e3 * b.thickness:g} mm"]
    if b.wall is not None:
        out.append(f"wall to {b.wall.material.young / 1e3:g} kPa at {np.degrees(b.wall.angle):g} deg, "
                   f"{1e3 * b.wall.offset:+g} mm")
    if b.lump is not None:
        lump = b.lump
        out.append(f"lump {lump.material.young / 1e3:g} kPa x {1e3 * lump.near:+g}.."
                   f"{1e3 * (lump.near + lump.length):+g} mm, {1e3 * lump.width:g} wide, "
                   f"top {1e3 * lump.depth:g} mm down, {1e3 * lump.height:g} tall")
    if b.skin is not None:
        out.append(f"skin {b.skin.material.young / 1e3:g} kPa {1e3 * b.skin.thickness:g} mm")
    return "; ".join(out)


def image_entry(image: PressImage) -> dict:
    return {"depth": image.depth.tolist(), "force": image.force.tolist(), "pressure": image.pressure.tolist()}


def case_mesh(case: ImageCase) -> dict:
    """The mesh a case is computed on (keyword arguments of :func:`fe3d_image`): h, growth and, near
    incompressibility, the finer depth grading (see NEAR_INCOMPRESSIBLE_NU)."""
    b = case.block
    materials = [b.material] + [x.material for x in (b.wall, b.lump, b.skin) if x is not None]
    if max(m.poisson for m in materials) >= NEAR_INCOMPRESSIBLE_NU:
        return dict(NEAR_INCOMPRESSIBLE)
    return dict(DEFAULT_MESH)


def compute_case(case: ImageCase, tip: FingertipSpec, mesh: dict | None = None) -> dict:
    """One case's entry of the file: its image on ``mesh`` (None: :func:`case_mesh`), the mesh and what it cost."""
    mesh = case_mesh(case) if mesh is None else mesh
    t0 = time.perf_counter()
    image, field = fe3d_image(case.block, tip, case.depths, **mesh)
    return {"family": case.family, "split": case.split, "describe": describe(case), **image_entry(image),
            "mesh": mesh, "dofs": field.dofs, "half": field.half, "seconds": round(time.perf_counter() - t0, 1)}


def convergence_study(case: ImageCase, tip: FingertipSpec, factors=CONVERGENCE_FACTORS) -> dict:
    """The case on its mesh (:func:`case_mesh`) with h x each factor: its dofs, force and image per level (the
    file's ``convergence`` entry)."""
    mesh = case_mesh(case)
    levels = []
    for factor in factors:
        image, field = fe3d_image(case.block, tip, case.depths, **{**mesh, "h": mesh["h"] * factor})
        levels.append({"h": mesh["h"] * factor, "dofs": field.dofs, **image_entry(image)})
    return {"depth": list(case.depths), "levels": levels}


def new_document(tip: FingertipSpec, h: float = H, growth: float = GROWTH) -> dict:
    return {"format": FORMAT, "version": VERSION, "tip": tip_dict(tip), "mesh": {"h": h, "growth": growth},
            "cases": {}, "convergence": {}}


@dataclass(frozen=True)
class ImageReferenceCase:
    """One cached case: its family, split, description and image."""

    family: str
    split: str
    describe: str
    image: PressImage


@dataclass(frozen=True)
class ConvergenceChange:
    """A case's image at one mesh level against the finest: per depth the rms sensel change over the finest
    image's peak and the force change (fractions)."""

    case: str
    h: float
    dofs: int
    rms_share: np.ndarray
    force_change: np.ndarray


@dataclass(frozen=True)
class ImageReference:
    """A loaded image reference: case name -> case; the refinement study (each level against the finest); the
    pad (FingertipSpec) and the default mesh edge h (m) it was computed with (cases near incompressibility use
    their own mesh, :func:`case_mesh`, recorded in their entries)."""

    cases: dict[str, ImageReferenceCase]
    convergence: tuple[ConvergenceChange, ...]
    tip: FingertipSpec
    h: float


def _image(path: Path, key: str, entry, tip: FingertipSpec) -> PressImage:
    if not isinstance(entry, dict):
        raise ValidationError(f"{path}: {key} must be an object")
    d = number_array(entry.get("depth"), f"{path}: {key}.depth", 1, max_size=100)
    f = number_array(entry.get("force"), f"{path}: {key}.force", 1, max_size=100)
    p = number_array(entry.get("pressure"), f"{path}: {key}.pressure", 3, max_size=100 * tip.rows * tip.cols)
    if f.shape != d.shape or p.shape != (len(d), tip.rows, tip.cols):
        raise ValidationError(f"{path}: {key}: need depth (n,), force (n,), pressure (n, {tip.rows}, {tip.cols}); "
                              f"got {d.shape}, {f.shape}, {p.shape}")
    if np.any(d <= 0) or np.any(np.diff(d) <= 0) or np.any(f <= 0) or np.any(np.diff(f) <= 0) or np.any(p < 0):
        raise ValidationError(f"{path}: {key}: depths and forces must be positive and increasing, pressures >= 0")
    return PressImage(depth=d, force=f, pressure=p)


def _positive(path: Path, key: str, value) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 0:
        raise ValidationError(f"{path}: {key} must be a positive number")
    return float(value)


def load_image_reference(path: Path | str = IMAGE_REFERENCE_PATH) -> ImageReference:
    """Read and validate the image reference: the pad, every case's image, the refinement study.

    Raises:
        ValidationError: missing, too large, not JSON, wrong format/version, or a bad entry, naming file and key.
    """
    path = Path(path)
    raw = read_document(path, "FE image reference", FORMAT, VERSION,
                        "compute it with `.venv/bin/python benchmarks/image_reference.py --write`")
    t = raw.get("tip")
    if not isinstance(t, dict):
        raise ValidationError(f"{path}: key 'tip' must be an object")
    try:
        tip = FingertipSpec(radius=_positive(path, "tip.radius", t.get("radius")), rows=int(t["rows"]),
                            cols=int(t["cols"]), pitch=_positive(path, "tip.pitch", t.get("pitch")),
                            sensel_size=_positive(path, "tip.sensel_size", t.get("sensel_size")))
    except (KeyError, TypeError, ValueError):
        raise ValidationError(f"{path}: tip needs radius, rows, cols, pitch and sensel_size") from None
    mesh = raw.get("mesh")
    h = _positive(path, "mesh.h", mesh.get("h") if isinstance(mesh, dict) else None)
    cases = raw.get("cases")
    if not isinstance(cases, dict) or not cases or len(cases) > MAX_CASES:
        raise ValidationError(f"{path}: key 'cases' must be an object of 1 to {MAX_CASES} cases")
    out = {}
    for name, c in cases.items():
        image = _image(path, f"cases.{name}", c, tip)
        if c.get("family") not in FAMILIES or c.get("split") not in SPLITS or not isinstance(c.get("describe"), str):
            raise ValidationError(f"{path}: cases.{name} needs family in {FAMILIES}, split in {SPLITS} and a "
                                  "describe string")
        out[name] = ImageReferenceCase(c["family"], c["split"], c["describe"], image)
    study = raw.get("convergence", {})
    if not isinstance(study, dict) or len(study) > MAX_CASES:
        raise ValidationError(f"{path}: key 'convergence' must be an object")
    changes = []
    for name, s in study.items():
        levels = s.get("levels") if isinstance(s, dict) else None
        if not isinstance(levels, list) or not 2 <= len(levels) <= 10:
            raise ValidationError(f"{path}: convergence.{name}.levels must be a list of 2 to 10 levels")
        images = [_image(path, f"convergence.{name}.levels[{i}]", lev, tip) for i, lev in enumerate(levels)]
        for i, (lev, image) in enumerate(zip(levels, images, strict=True)):
            dofs = lev.get("dofs")
            if isinstance(dofs, bool) or not isinstance(dofs, int) or dofs <= 0:
                raise ValidationError(f"{path}: convergence.{name}.levels[{i}].dofs must be a positive integer")
            err = image_errors(image, images[-1], tip)
            changes.append(ConvergenceChange(name, _positive(path, f"convergence.{name}.levels[{i}].h", lev.get("h")),
                                             dofs, err.rms_share, err.force_error))
    return ImageReference(cases=out, convergence=tuple(changes), tip=tip, h=h)


def reference_image(reference: ImageReference, case: ImageCase) -> PressImage:
    """The cached image of ``case``.

    Raises:
        ValidationError: the file lacks the case or holds it at other depths (regenerate it).
    """
    entry = reference.cases.get(case.name)
    if entry is None:
        raise ValidationError(f"the FE image reference has no case {case.name!r}; compute it with "
                              "`.venv/bin/python benchmarks/image_reference.py --write`")
    if len(entry.image.depth) != len(case.depths) or not np.allclose(entry.image.depth, case.depths, rtol=1e-9):
        raise ValidationError(f"the FE image reference holds {case.name!r} at other depths; regenerate it")
    return entry.image
