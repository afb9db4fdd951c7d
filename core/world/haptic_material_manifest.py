"""Validation of a haptic-material folder's ``manifest.json`` (seed 002 format, :mod:`.haptic_material`).

Everything a manifest states is checked before a pixel is decoded: its format and version, an integer shape within
``png_pixels``, an origin and a cell size that are physically plausible (the limits ``length_m`` and
``length_min_m``, docs/limits.md), distinct material names, and each map's entry: a probability map only for a listed
material, and a range and resolution that are the ones palpate decodes with (a reader that trusted another range
would decode other numbers). Errors name the manifest and the key.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from palpate.core import files, limits
from palpate.core.errors import ValidationError
from palpate.core.names import unique_stems
from palpate.core.world.scene import finite_number

PROBABILITY_PREFIX = "material_probability_"


@dataclass(frozen=True)
class Manifest:
    """What a valid manifest states (SI)."""

    shape: tuple[int, int]
    origin: tuple[float, float]
    cell_size: float
    materials: list[str]
    maps: dict
    meta: dict


def check_manifest(manifest, mpath: Path, format_name: str, version: int, probability_name) -> Manifest:
    """The manifest's content, validated (module docstring); ``probability_name(material)`` is the map name of a
    material's probability map."""
    if not isinstance(manifest, dict):
        raise ValidationError(f"{mpath}: expected a JSON object")
    if manifest.get("format") != format_name:
        raise ValidationError(f"{mpath}: key 'format' must be {format_name!r}, got "
                              f"{files.brief(manifest.get('format'))}")
    if manifest.get("version") != version:
        raise ValidationError(f"{mpath}: key 'version' {files.brief(manifest.get('version'))} is not supported "
                              f"(this palpate reads version {version})")
    for key in ("shape", "origin_m", "cell_size_m", "materials", "maps"):
        if key not in manifest:
            raise ValidationError(f"{mpath}: missing key {key!r}")
    shape = manifest["shape"]
    if not (isinstance(shape, list) and len(shape) == 2
            and all(isinstance(v, int) and not isinstance(v, bool) and v >= 1 for v in shape)):
        raise ValidationError(f"{mpath}: key 'shape' must be [ny, nx], two integers >= 1, got {files.brief(shape)}")
    limits.check("png_pixels", f"{mpath}: key 'shape' {shape}: pixels per map", shape[0] * shape[1])
    longest, shortest = limits.limit("length_m"), limits.limit("length_min_m")
    origin = manifest["origin_m"]
    if not (isinstance(origin, list) and len(origin) == 2 and all(finite_number(v) for v in origin)):
        raise ValidationError(f"{mpath}: key 'origin_m' must be [x0, y0], two finite numbers (m), got "
                              f"{files.brief(origin)}")
    for i, v in enumerate(origin):
        if abs(v) > longest:
            raise limits.implausible(f"{mpath}: key 'origin_m'[{i}]", v, -longest, longest, "m", "length_m")
    cell = manifest["cell_size_m"]
    if not finite_number(cell):
        raise ValidationError(f"{mpath}: key 'cell_size_m' must be a finite number > 0 (m), got {files.brief(cell)}")
    if not shortest <= cell <= longest:
        raise limits.implausible(f"{mpath}: key 'cell_size_m'", cell, shortest, longest, "m", "length_min_m",
                                 "length_m")
    materials = manifest["materials"]
    if not (isinstance(materials, list) and all(isinstance(m, str) and m for m in materials)
            and len(set(materials)) == len(materials)):
        raise ValidationError(f"{mpath}: key 'materials' must list distinct material names, got "
                              f"{files.brief(materials)}")
    limits.check("materials", f"{mpath}: key 'materials'", len(materials))
    unique_stems(materials, f"{mpath}: key 'materials'")
    maps = manifest["maps"]
    if not isinstance(maps, dict) or not all(isinstance(e, dict) for e in maps.values()):
        raise ValidationError(f"{mpath}: key 'maps' must map each map's name to an object (file, range, ...)")
    listed = {probability_name(m): m for m in materials}
    for name, entry in maps.items():
        named = entry.get("material")
        if (name.startswith(PROBABILITY_PREFIX) and name not in listed) or (named is not None
                                                                            and listed.get(name) != named):
            raise ValidationError(f"{mpath}: map {files.brief(name)} is for material {files.brief(named)}, which "
                                  f"key 'materials' does not list ({files.brief(materials)})")
    meta = manifest.get("meta", {})
    if not isinstance(meta, dict):
        raise ValidationError(f"{mpath}: key 'meta' must be an object, got {files.brief(meta)}")
    return Manifest((shape[0], shape[1]), (float(origin[0]), float(origin[1])), float(cell), materials, maps, meta)


def check_quantisation(mpath: Path, name: str, entry: dict, lo: float, hi: float, resolution: float) -> None:
    """A map entry's ``range`` and ``resolution`` (when stated) must be an increasing pair and a positive step, and
    the ones palpate decodes this map with."""
    where = f"{mpath}: map {name!r}"
    rng = entry.get("range", [lo, hi])
    if not (isinstance(rng, list) and len(rng) == 2 and all(finite_number(v) for v in rng) and rng[0] < rng[1]):
        raise ValidationError(f"{where}: key 'range' must be [low, high], two finite numbers with low < high, got "
                              f"{files.brief(rng)}")
    step = entry.get("resolution", resolution)
    if not (finite_number(step) and step > 0):
        raise ValidationError(f"{where}: key 'resolution' must be a finite number > 0, got {files.brief(step)}")
    if not (np.allclose(rng, [lo, hi], rtol=1e-9, atol=0) and math.isclose(step, resolution, rel_tol=1e-9)):
        raise ValidationError(f"{where}: key 'range' {files.brief(rng)} / 'resolution' {files.brief(step)} is not "
                              f"what palpate decodes this map with ({[lo, hi]} / {resolution})")


def check_probability_sums(probs: np.ndarray, measured: np.ndarray, where: str) -> None:
    """Every measured cell's decoded probabilities (ny, nx, M) must sum to 1 within the maps' 8-bit rounding (half a
    step of 1/255 per map): a cell of zeros (or of twice the mass) is no distribution, and renormalising it would
    make up a measurement."""
    total = probs.sum(axis=-1)
    slack = probs.shape[-1] * 0.5 / 255.0 + 1e-9
    bad = measured & (np.abs(total - 1.0) > slack)
    if bad.any():
        iy, ix = (int(v) for v in np.argwhere(bad)[0])
        raise ValidationError(f"{where}: measured cell [{iy}, {ix}]: the material probabilities sum to "
                              f"{total[iy, ix]:.4g}, not 1 (within the 8-bit rounding, +-{slack:.3g}); "
                              f"{int(bad.sum())} such cell(s)")
