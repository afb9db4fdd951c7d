"""The "haptic material" format of seed 002: haptic features stored as 8-bit maps, like texture maps.

A haptic material is a folder holding one 8-bit grayscale PNG per feature and a ``manifest.json`` that states,
for each map, the format, range, resolution and units of seed 002's Table 3, so any reader (a renderer, palpate
itself) can decode it. palpate writes one per explored object (what palpation perceived) and reads one to give a
simulated object a spatially varying material.

What palpation measures, and how it maps onto Table 3:

- ``rate_hardness``: initial rate of force change over penetration velocity (Table 3: 8-bit, 0-10000
  N s^-1 / m s^-1, resolution 40). With force F(t) and indentation d(t), (dF/dt) / (dd/dt) = dF/dd, in N/m.
- ``contact_area_spread_rate``: Table 3 gives 8-bit, 0-25.6 N/cm^2, resolution 0.1; palpate measures it as the
  force change per change of contact area over the press phase (dF/dA), which carries exactly those units.
  0-25.6 in steps of 0.1 needs 257 codes, one more than 8 bits hold, so the stored range stops at 25.5.
- ``local_indentation``: Table 3 gives 8-bit, +-5 mm, resolution 0.04 mm; palpate stores the indentation reached
  at the cell (positive into the surface).
- ``material_probability_<name>``: palpate's own maps (a custom specification, as seed 002 section 3.3 allows):
  P(material) per cell, 8-bit, 0-1, resolution 1/255.

Every other feature of the format (local surface orientation, kinetic and static friction, relative
temperature, temperature slope, and the vibratory model references) is listed in the manifest as absent.

Seed inconsistency: Table 3 gives the local surface orientation as 3x8-bit over 2 x 0-180 degrees with a
resolution of 0.002 degrees, but 8 bits span 180 degrees in steps of at least 180/255 = 0.71 degrees; the spec
below keeps the range and states the achievable resolution (see tests/test_haptic_material.py).

Layout: array index [iy, ix] (iy along +y); image row 0 is the *top* of the picture, i.e. the largest y, so a PNG
looks like the object seen from above. A ``measured.png`` mask (255 measured, 0 not) says which cells hold data;
unmeasured cells are never decoded into numbers that look measured.
"""

from __future__ import annotations

import json
import os
import struct
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from palpate.core import files, limits
from palpate.core.errors import ValidationError
from palpate.core.names import file_stem
from palpate.core.world.haptic_material_manifest import check_manifest, check_probability_sums, check_quantisation

FORMAT_NAME = "palpate-haptic-material"
FORMAT_VERSION = 1


@dataclass(frozen=True)
class FeatureSpec:
    """How one haptic feature is quantised into an 8-bit map.

    Attributes:
        name: file stem of the map.
        label: the feature's name in seed 002 Table 3.
        unit: physical unit of the decoded value (as Table 3 writes it).
        lo, hi: representable range, in ``unit``.
        resolution: value of one 8-bit step, in ``unit``.
        si_scale: multiply a value in ``unit`` by this to get SI (N/m, Pa, m, ...).
    """

    name: str
    label: str
    unit: str
    lo: float
    hi: float
    resolution: float
    si_scale: float = 1.0

    @property
    def levels(self) -> int:
        """Number of 8-bit codes used (<= 256)."""
        return int(round((self.hi - self.lo) / self.resolution)) + 1

    def encode(self, values_si: np.ndarray) -> np.ndarray:
        """Quantise SI values to uint8 codes (clipped to the range; NaN is an error)."""
        v = np.asarray(values_si, dtype=float) / self.si_scale
        if not np.all(np.isfinite(v)):
            raise ValidationError(f"haptic map {self.name!r}: values must be finite before encoding")
        codes = np.rint((np.clip(v, self.lo, self.hi) - self.lo) / self.resolution)
        return np.clip(codes, 0, min(255, self.levels - 1)).astype(np.uint8)

    def decode(self, codes: np.ndarray) -> np.ndarray:
        """uint8 codes back to SI values."""
        return (self.lo + np.asarray(codes, dtype=float) * self.resolution) * self.si_scale

    def to_json(self) -> dict:
        return {
            "file": f"{self.name}.png",
            "feature": self.label,
            "format": "8-bit",
            "range": [self.lo, self.hi],
            "resolution": self.resolution,
            "units": self.unit,
            "si_scale": self.si_scale,
        }


# Seed 002 Table 3, for the features a press-and-release palpation measures.
RATE_HARDNESS = FeatureSpec("rate_hardness", "Rate-hardness", "N.s^-1/m.s^-1", 0.0, 10000.0, 40.0, 1.0)
CONTACT_AREA_SPREAD_RATE = FeatureSpec(
    "contact_area_spread_rate", "Contact area spread rate", "N/cm^2", 0.0, 25.5, 0.1, 1.0e4
)
LOCAL_INDENTATION = FeatureSpec("local_indentation", "Local indentation", "mm", -5.0, 5.0, 0.04, 1.0e-3)
MEASURED_FEATURES = {s.name: s for s in (RATE_HARDNESS, CONTACT_AREA_SPREAD_RATE, LOCAL_INDENTATION)}

# Features of the format that palpation does not measure (listed as absent in every manifest).
ABSENT_FEATURES = {
    "local_surface_orientation": {
        "feature": "Local surface orientation", "format": "3x8-bit", "range": "2 x 0-180 deg",
        "resolution_in_seed": "0.002 deg", "resolution_achievable": f"{180.0 / 255.0:.3f} deg",
        "note": "seed 002 Table 3 states 0.002 deg, which 8 bits over 180 deg cannot reach",
    },
    "kinetic_friction": {"feature": "Kinetic friction", "format": "8-bit", "range": "+-5", "resolution": 0.04},
    "static_friction": {"feature": "Static friction", "format": "8-bit", "range": "+-5", "resolution": 0.04},
    "relative_temperature": {"feature": "Relative temperature", "format": "8-bit", "range": "+-25.4 deg",
                             "resolution": 0.2},
    "temperature_slope": {"feature": "Temperature slope", "format": "8-bit", "range": "0-5.0 deg/s",
                          "resolution": 0.02},
    "dynamic_stiffness": {"feature": "Dynamic stiffness", "format": "model reference"},
    "stroke_spectral_response": {"feature": "Stroke spectral response", "format": "model reference"},
    "stick_slip": {"feature": "Stick-slip", "format": "model reference"},
}


def probability_spec(material: str) -> FeatureSpec:
    """The custom 8-bit spec of a material-probability map (0-1 in steps of 1/255)."""
    return FeatureSpec(f"material_probability_{file_stem(material)}", f"P({material})", "1", 0.0, 1.0, 1.0 / 255.0)


@dataclass
class HapticMaterialMap:
    """A haptic material over a rectangular patch of an object's top surface.

    Attributes:
        origin: (x0, y0) of the corner of cell [0, 0], m.
        cell_size: side of one square cell, m.
        materials: material category names (order of the probability maps).
        probabilities: (ny, nx, M) P(material) per cell, or None.
        features: SI arrays (ny, nx) by feature name (keys of MEASURED_FEATURES).
        measured: (ny, nx) bool, cells holding measured data.
        meta: provenance (object name, scenario, palpate version), JSON-serialisable.
    """

    origin: tuple[float, float]
    cell_size: float
    materials: list[str]
    probabilities: np.ndarray | None
    features: dict[str, np.ndarray] = field(default_factory=dict)
    measured: np.ndarray | None = None
    meta: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        if len(self.origin) != 2 or not all(np.isfinite(v) for v in self.origin):
            raise ValidationError(f"haptic material: origin must be two finite numbers (m), got {self.origin}")
        if not (np.isfinite(self.cell_size) and self.cell_size > 0):
            raise ValidationError(f"haptic material: cell_size must be > 0 m, got {self.cell_size}")
        shape = None
        if self.probabilities is not None:
            p = np.asarray(self.probabilities, dtype=float)
            if p.ndim != 3 or p.shape[2] != len(self.materials):
                raise ValidationError(
                    f"haptic material: probabilities must be (ny, nx, {len(self.materials)}), got {p.shape}"
                )
            if not np.all(np.isfinite(p)) or np.any(p < 0):
                raise ValidationError("haptic material: probabilities must be finite and >= 0")
            self.probabilities = p
            shape = p.shape[:2]
        for name, arr in self.features.items():
            if name not in MEASURED_FEATURES:
                raise ValidationError(f"haptic material: unknown feature {name!r}; known: {sorted(MEASURED_FEATURES)}")
            a = np.asarray(arr, dtype=float)
            if shape is None:
                shape = a.shape
            if a.shape != shape:
                raise ValidationError(f"haptic material: feature {name!r} has shape {a.shape}, expected {shape}")
            if not np.all(np.isfinite(a)):
                raise ValidationError(f"haptic material: feature {name!r} holds NaN or inf")
            self.features[name] = a
        if shape is None:
            raise ValidationError("haptic material: needs probabilities or at least one feature map")
        if self.measured is None:
            self.measured = np.ones(shape, dtype=bool)
        self.measured = np.asarray(self.measured, dtype=bool)
        if self.measured.shape != shape:
            raise ValidationError(f"haptic material: measured mask has shape {self.measured.shape}, expected {shape}")

    @property
    def shape(self) -> tuple[int, int]:
        """(ny, nx)."""
        return tuple(self.measured.shape)  # type: ignore[return-value]

    def cell_index(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(iy, ix, inside) of world points (n, 2), m."""
        pts = np.atleast_2d(np.asarray(xy, dtype=float))
        ix = np.floor((pts[:, 0] - self.origin[0]) / self.cell_size).astype(int)
        iy = np.floor((pts[:, 1] - self.origin[1]) / self.cell_size).astype(int)
        ny, nx = self.shape
        inside = (ix >= 0) & (ix < nx) & (iy >= 0) & (iy < ny)
        return np.clip(iy, 0, ny - 1), np.clip(ix, 0, nx - 1), inside

    def material_codes_at(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(best, named) at each (x, y) point (n, 2), m: the index into ``materials`` of the most probable material
        and whether the point names one (inside the map and measured); :meth:`material_names_at` as arrays."""
        if self.probabilities is None:
            raise ValidationError("haptic material has no material-probability maps to name a material from")
        iy, ix, inside = self.cell_index(xy)
        return np.argmax(self.probabilities[iy, ix], axis=1), inside & self.measured[iy, ix]

    def material_names_at(self, xy: np.ndarray) -> list[str | None]:
        """Most probable material at each (x, y) point (n, 2); None outside the map or where not measured."""
        best, ok = self.material_codes_at(xy)
        return [self.materials[b] if o else None for b, o in zip(best, ok, strict=True)]

    def write(self, folder: str | Path) -> Path:
        """Write the PNG maps and manifest.json into ``folder`` (created). Returns the manifest path."""
        from PIL import Image

        out = Path(folder)
        out.mkdir(parents=True, exist_ok=True)
        maps = {}
        if self.probabilities is not None:
            for m, name in enumerate(self.materials):
                spec = probability_spec(name)
                _write_png(Image, out / f"{spec.name}.png", spec.encode(self.probabilities[:, :, m]))
                maps[spec.name] = {**spec.to_json(), "material": name}
        for name, arr in self.features.items():
            spec = MEASURED_FEATURES[name]
            clipped = int(np.sum(self.measured & ((arr / spec.si_scale < spec.lo) | (arr / spec.si_scale > spec.hi))))
            _write_png(Image, out / f"{spec.name}.png", spec.encode(np.where(self.measured, arr, 0.0)))
            maps[spec.name] = {**spec.to_json(), "clipped_cells": clipped}
        _write_png(Image, out / "measured.png", np.where(self.measured, 255, 0).astype(np.uint8))
        manifest = {
            "format": FORMAT_NAME,
            "version": FORMAT_VERSION,
            "specification": "seed 002 (haptic material) Table 3, plus palpate's material-probability maps",
            "origin_m": [float(self.origin[0]), float(self.origin[1])],
            "cell_size_m": float(self.cell_size),
            "shape": list(self.shape),
            "image_orientation": "row 0 = largest y (top view); column 0 = smallest x",
            "materials": list(self.materials),
            "maps": maps,
            "measured_mask": "measured.png",
            "absent": ABSENT_FEATURES,
            "meta": self.meta,
        }
        path = out / "manifest.json"
        files.write_text(path, json.dumps(manifest, indent=2))
        return path

    @classmethod
    def read(cls, folder: str | Path) -> HapticMaterialMap:
        """Read a haptic material folder written by :meth:`write` (or by hand following the manifest).

        Everything is validated before it is decoded: the manifest (bounded JSON, format, version, integer shape,
        plausible origin and cell, distinct material names, each map's range and resolution, probability maps only
        for listed materials; :mod:`.haptic_material_manifest`), each map's file name (a plain name inside the
        folder, also after symlinks) and each PNG's size from its header (the limit ``png_pixels``, the manifest's
        shape); an undecodable or truncated PNG is an error naming it, and so is a measured cell whose probabilities do
        not sum to 1. Errors name the file and key.
        """
        root = Path(folder)
        mpath = root / "manifest.json"
        if not root.is_dir():
            raise ValidationError(f"{root}: not a folder (a haptic material is a folder with manifest.json)")
        if not mpath.exists():
            raise ValidationError(f"{root}: no manifest.json (not a haptic material folder)")
        manifest = files.read_json(mpath, "haptic-material manifest")
        m = check_manifest(manifest, mpath, FORMAT_NAME, FORMAT_VERSION, lambda name: probability_spec(name).name)
        shape, materials, maps = m.shape, m.materials, m.maps

        def load(stem: str, fname) -> np.ndarray:
            return read_png(root, fname, (shape[0], shape[1]), f"{mpath}: map {stem!r}")

        measured = load("measured", manifest.get("measured_mask", "measured.png")) > 127
        probs = None
        if materials:
            layers = []
            for name in materials:
                spec = probability_spec(name)
                if spec.name not in maps:
                    raise ValidationError(f"{mpath}: 'maps' has no entry {spec.name!r} for material {name!r}")
                entry = maps[spec.name]
                check_quantisation(mpath, spec.name, entry, spec.lo, spec.hi, spec.resolution)
                layers.append(spec.decode(load(spec.name, entry.get("file", f"{spec.name}.png"))))
            probs = np.stack(layers, axis=-1)
            check_probability_sums(probs, measured, str(mpath))
            total = probs.sum(axis=-1, keepdims=True)
            # 8-bit rounding leaves sums slightly off 1: renormalise; an unmeasured cell of zeros (nothing was
            # perceived there) is kept uniform.
            probs = np.where(total > 0, probs / np.where(total > 0, total, 1.0), 1.0 / len(materials))
        features = {}
        for name, spec in MEASURED_FEATURES.items():
            if name in maps:
                entry = maps[name]
                check_quantisation(mpath, name, entry, spec.lo, spec.hi, spec.resolution)
                features[name] = spec.decode(load(name, entry.get("file", f"{name}.png")))
        return cls(origin=m.origin, cell_size=m.cell_size, materials=materials, probabilities=probs,
                   features=features, measured=measured, meta=dict(m.meta))


PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def read_png(root: Path, fname, shape: tuple[int, int], where: str) -> np.ndarray:
    """An 8-bit grayscale PNG of the folder ``root`` as a (ny, nx) uint8 array, row 0 at the smallest y.

    ``fname`` must be a plain file name inside ``root`` (no folder part, not absolute, and not a symlink leading
    out); its size is read from the PNG header and checked against the limit ``png_pixels`` and ``shape`` before
    any pixel is decoded.
    """
    from PIL import Image

    if not isinstance(fname, str) or not fname or Path(fname).name != fname or fname in (".", ".."):
        raise ValidationError(f"{where}: file {files.brief(fname)} must be a file name inside {root}")
    path = root / fname
    real_root = Path(os.path.realpath(root))
    if real_root not in Path(os.path.realpath(path)).parents:
        raise ValidationError(f"{where}: {path} leads outside the material folder {root} (a symlink?)")
    head = files.read_bytes_head(path, f"haptic-material map ({where})", 33)
    if len(head) < 24 or head[:8] != PNG_SIGNATURE or head[12:16] != b"IHDR":
        raise ValidationError(f"{path}: not a PNG file")
    width, height = struct.unpack(">II", head[16:24])
    limits.check("png_pixels", f"{path}: {width} x {height} image: pixels", width * height)
    if (height, width) != shape:
        raise ValidationError(f"{path}: size {(height, width)} does not match manifest shape {shape}")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            with Image.open(path, formats=["PNG"]) as img:
                if img.mode != "L":
                    raise ValidationError(f"{path}: expected an 8-bit grayscale PNG, got mode {img.mode!r}")
                img.load()
                arr = np.asarray(img, dtype=np.uint8)[::-1]
    except ValidationError:
        raise
    except Exception as exc:  # noqa: BLE001 - whatever a broken PNG makes the decoder raise is the file's fault
        raise ValidationError(f"{path}: not a readable PNG ({type(exc).__name__}: "
                              f"{files.brief(str(exc), 100)})") from None
    if arr.shape != shape:
        raise ValidationError(f"{path}: size {arr.shape} does not match manifest shape {shape}")
    return arr


def _write_png(image_module, path: Path, codes: np.ndarray) -> None:
    # Flip so that image row 0 is the largest y: the picture is a top view of the object.
    with files.writing(path):
        image_module.fromarray(np.ascontiguousarray(codes[::-1], dtype=np.uint8)).save(path)
