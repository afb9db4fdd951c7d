"""Lump templates: how much a buried lump or a deeper layer changes what the pad reads as it presses in, tabulated
once by a contact law of the simulation for one pad and read by :mod:`.lump_depth`.

Each template is the sum of the pad's sensel pressures at a set of indentations over a sample whose top material
has modulus E and whose deep material (E times a contrast) starts ``top`` below the surface: a layer to the sample's
base, or an on-axis sphere or cylinder of a radius. It is stored as its log ratio to the same sum on the top
material alone, which for linear-elastic contact depends on the contrast, not on E.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from palpate.core.boundary.templates import Pad, bracket, read_template_document
from palpate.core.errors import ValidationError
from palpate.core.files import decimal_array, number_array, pack_decimals

FORMAT = "palpate-lump-templates"
VERSION = 1
LUMP_TEMPLATES_FILE = "lump_templates.json"
#: Shapes a template may have: a layer to the base, or an on-axis inclusion.
SHAPES = ("layer", "sphere", "cylinder")
#: Largest number of stored ratios a file may hold (shapes x contrasts x tops x depths).
MAX_VALUES = 200000


@dataclass(frozen=True)
class LumpTemplates:
    """Log ratios of the pad's summed pressure over a two-material sample to the top material's alone.

    Attributes:
        pad: the pad they were made for.
        poisson: both materials' Poisson ratio.
        depths: indentations, m, (D,) increasing.
        tops: depths of the deep material's top below the surface, m, (T,) increasing.
        contrasts: deep over top modulus, (C,) increasing, none equal to 1.
        shapes: per template, one of :data:`SHAPES`, (K,).
        radii: per template, the inclusion's radius, m (0 for a layer), (K,).
        log_ratio: (K, C, T, D).
    """

    pad: Pad
    poisson: float
    depths: np.ndarray
    tops: np.ndarray
    contrasts: np.ndarray
    shapes: tuple[str, ...]
    radii: np.ndarray
    log_ratio: np.ndarray

    def at_contrast(self, contrast: float) -> np.ndarray:
        """The log ratios (K, T, D) for a deep material ``contrast`` times the top's modulus: linear in log
        contrast between the stored ones, clamped to their range on each side of 1 (a harder lump is never read
        from softer templates)."""
        if not (np.isfinite(contrast) and contrast > 0 and contrast != 1):
            raise ValidationError(f"LumpTemplates.at_contrast: contrast must be positive and not 1, got {contrast}")
        side = (self.contrasts > 1) == (contrast > 1)
        if not side.any():
            raise ValidationError(f"LumpTemplates.at_contrast: no template is {'harder' if contrast > 1 else 'softer'}"
                                  " than its top")
        logs, table = np.log(self.contrasts[side]), self.log_ratio[:, side]
        if len(logs) == 1:
            return table[:, 0]
        k, w = bracket(logs, np.log(contrast))
        return (1 - w) * table[:, k] + w * table[:, k + 1]


def lump_templates_from_document(doc: object, source: str) -> LumpTemplates:
    """Validate a lump templates document (see :func:`read_lump_templates`)."""
    if not isinstance(doc, dict) or doc.get("format") != FORMAT or doc.get("version") != VERSION:
        raise ValidationError(f"{source}: not a {FORMAT} file of version {VERSION}")
    try:
        pad = Pad.from_dict(doc["pad"])
        poisson = float(doc["poisson"])
        depths = number_array(doc["depths"], f"{source}: depths", 1, 64)
        tops = number_array(doc["tops"], f"{source}: tops", 1, 256)
        contrasts = number_array(doc["contrasts"], f"{source}: contrasts", 1, 64)
        shapes = doc["shapes"]
        radii = number_array(doc["radii"], f"{source}: radii", 1, 64)
        log_ratio = decimal_array(doc["log_ratio"], f"{source}: log_ratio", 4, MAX_VALUES)
    except (KeyError, TypeError, ValueError) as exc:
        raise ValidationError(f"{source}: a lump templates file needs pad, poisson, depths, tops, contrasts, shapes, "
                              f"radii and log_ratio ({exc})") from None
    if not (0 < pad.sensel_size <= pad.pitch < pad.radius < 0.1) or not (1 <= pad.rows <= 64 and 1 <= pad.cols <= 64):
        raise ValidationError(f"{source}: pad must have 0 < sensel_size <= pitch < radius < 0.1 m")
    if not 0.0 <= poisson < 0.5:
        raise ValidationError(f"{source}: poisson must be in [0, 0.5), got {poisson}")
    for arr, name in ((depths, "depths"), (tops, "tops"), (contrasts, "contrasts")):
        if np.any(np.diff(arr) <= 0):
            raise ValidationError(f"{source}: {name} must be strictly increasing")
    if not (0 < depths[0] and depths[-1] < pad.radius and 0 <= tops[0] and tops[-1] < 0.1 and contrasts[0] > 1e-4
            and contrasts[-1] < 1e4 and not np.any(contrasts == 1)):
        raise ValidationError(f"{source}: depths must be in (0, radius), tops in [0, 0.1) m, contrasts in (1e-4, 1e4) "
                              "and none 1")
    if (not isinstance(shapes, list) or len(shapes) != len(radii) or any(s not in SHAPES for s in shapes)
            or any((s == "layer") != (r == 0) for s, r in zip(shapes, radii, strict=True)) or np.any(radii < 0)
            or np.any(radii > 0.1)):
        raise ValidationError(f"{source}: shapes must be one of {SHAPES} per radius (0 m for a layer only, inclusions "
                              "0-0.1 m)")
    want = (len(shapes), len(contrasts), len(tops), len(depths))
    if log_ratio.shape != want:
        raise ValidationError(f"{source}: log_ratio must have shape {want}, got {log_ratio.shape}")
    if np.any(np.abs(log_ratio) > 20):
        raise ValidationError(f"{source}: log_ratio must lie in [-20, 20]")
    return LumpTemplates(pad, poisson, depths, tops, contrasts, tuple(shapes), radii, log_ratio)


def read_lump_templates(path: str | Path) -> LumpTemplates:
    """The lump templates in ``path``, validated.

    Raises:
        ValidationError: missing, not JSON, of another format, or any array of the wrong shape or out of range.
    """
    doc = read_template_document(path, "lump templates", "benchmarks/lump_templates.py")
    return lump_templates_from_document(doc, str(path))


def lump_templates_document(pad: Pad, poisson: float, depths, tops, contrasts, shapes, radii, log_ratio,
                            source: str) -> dict:
    """The JSON document :func:`read_lump_templates` reads (see :class:`LumpTemplates`)."""
    return {"format": FORMAT, "version": VERSION, "source": source,
            "pad": pad.to_dict(),
            "poisson": poisson, "depths": list(map(float, depths)), "tops": list(map(float, tops)),
            "contrasts": list(map(float, contrasts)), "shapes": list(shapes), "radii": list(map(float, radii)),
            "log_ratio": pack_decimals(log_ratio, 4)}
