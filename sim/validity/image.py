"""A press's taxel image as data, and how far one image is from another.

:class:`PressImage` is what every rung and the 3-D FE reference give for one press point at a set of depths: the
total force and the mean pressure over each sensel's footprint (the pad's geometry from
:func:`palpate.sim.fingertip.sensel_bounds`: row 0 at +y, column 0 at -x, in the pad plane relative to the tip
axis). :func:`image_errors` scores an image against a reference with the quantities the validity table's image
columns report.

Definitions (every one per depth):

- force error: force / reference force - 1;
- rms share: the root mean square over sensels of the pressure difference, over the reference's largest sensel
  pressure (so 0.1 is "10% of the reference's peak");
- asymmetry along x: (right half - left half) / total of the sensel pressures, halves split at the pad's centre
  line (columns 0..cols/2-1 left); along y likewise with the top rows first; 0 for an image with no load;
- active sensels: sensels whose mean pressure times the sensor's gain exceeds its threshold (counts), as the
  8-bit pad would report them without noise; c_A is that count times the sensel area.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.world.scene import FingertipSpec, TaxelSensorSpec


@dataclass(frozen=True)
class PressImage:
    """One press point's force and sensel image at a set of depths.

    Attributes:
        depth: indentations, m, (n,), increasing.
        force: total normal force, N, (n,).
        pressure: mean normal pressure over each sensel footprint, Pa, (n, rows, cols).
    """

    depth: np.ndarray
    force: np.ndarray
    pressure: np.ndarray

    def __post_init__(self) -> None:
        d, f, p = (np.asarray(v, dtype=float) for v in (self.depth, self.force, self.pressure))
        if d.ndim != 1 or f.shape != d.shape or p.ndim != 3 or p.shape[0] != d.shape[0]:
            raise ValidationError(f"PressImage: need depth (n,), force (n,), pressure (n, rows, cols); got "
                                  f"{d.shape}, {f.shape}, {p.shape}")
        if not (np.all(np.isfinite(d)) and np.all(np.isfinite(f)) and np.all(np.isfinite(p))):
            raise ValidationError("PressImage: depth, force and pressure must be finite")
        object.__setattr__(self, "depth", d)
        object.__setattr__(self, "force", f)
        object.__setattr__(self, "pressure", p)


def asymmetry(pressure: np.ndarray, axis: str = "x") -> np.ndarray:
    """(far half - near half) / total of sensel pressures (..., rows, cols) along the pad's x (columns, + to the
    right) or y (rows, + towards row 0); 0 where the image is empty. An odd middle column or row counts in neither
    half."""
    p = np.asarray(pressure, dtype=float)
    if axis == "x":
        n = p.shape[-1]
        lo, hi = p[..., : n // 2].sum(axis=(-1, -2)), p[..., (n + 1) // 2:].sum(axis=(-1, -2))
    elif axis == "y":
        n = p.shape[-2]
        hi, lo = p[..., : n // 2, :].sum(axis=(-1, -2)), p[..., (n + 1) // 2:, :].sum(axis=(-1, -2))
    else:
        raise ValidationError(f"asymmetry: axis must be 'x' or 'y', got {axis!r}")
    total = p.sum(axis=(-1, -2))
    return np.where(total > 0, (hi - lo) / np.where(total > 0, total, 1.0), 0.0)


def active_sensels(pressure: np.ndarray, taxels: TaxelSensorSpec) -> np.ndarray:
    """Sensels the pad reports as loaded (no noise): pressure x gain above the threshold, counted per image."""
    return np.sum(np.asarray(pressure, dtype=float) * taxels.gain > taxels.threshold, axis=(-1, -2))


@dataclass(frozen=True)
class ImageErrors:
    """An image against its reference, per depth (see the module docstring for each definition).

    Attributes:
        depth: m, (n,).
        force_error: (n,) signed fraction.
        rms_share: (n,) rms sensel error over the reference's peak sensel pressure.
        asymmetry, reference_asymmetry: (n,) along x.
        asymmetry_y, reference_asymmetry_y: (n,) along y.
        active, reference_active: (n,) active sensels.
        contact_area, reference_contact_area: (n,) c_A, m^2.
    """

    depth: np.ndarray
    force_error: np.ndarray
    rms_share: np.ndarray
    asymmetry: np.ndarray
    reference_asymmetry: np.ndarray
    asymmetry_y: np.ndarray
    reference_asymmetry_y: np.ndarray
    active: np.ndarray
    reference_active: np.ndarray
    contact_area: np.ndarray
    reference_contact_area: np.ndarray

    def asymmetry_ok(self, min_asymmetry: float = 0.1, tolerance: float = 0.2) -> np.ndarray:
        """Per depth: the asymmetry has the reference's sign along both axes wherever the reference's exceeds
        ``min_asymmetry`` in size (smaller ones carry no sign worth keeping), and is within ``tolerance`` (a
        fraction) of it there."""
        ok = np.ones(len(self.depth), dtype=bool)
        for got, ref in ((self.asymmetry, self.reference_asymmetry), (self.asymmetry_y, self.reference_asymmetry_y)):
            big = np.abs(ref) > min_asymmetry
            close = np.abs(got - ref) <= tolerance * np.abs(ref)
            ok &= ~big | ((np.sign(got) == np.sign(ref)) & close)
        return ok


def image_errors(image: PressImage, reference: PressImage, tip: FingertipSpec,
                 taxels: TaxelSensorSpec | None = None) -> ImageErrors:
    """``image`` against ``reference`` at the same depths (see the module docstring).

    Raises:
        ValidationError: the depths or the pad shapes differ, or the reference carries no load at a depth.
    """
    taxels = TaxelSensorSpec() if taxels is None else taxels
    if image.pressure.shape != reference.pressure.shape or not np.allclose(image.depth, reference.depth,
                                                                           rtol=1e-9, atol=1e-12):
        raise ValidationError(f"image_errors: the images' depths or pads differ ({image.pressure.shape} against "
                              f"{reference.pressure.shape})")
    if image.pressure.shape[1:] != (tip.rows, tip.cols):
        raise ValidationError(f"image_errors: a {tip.rows}x{tip.cols} pad cannot score {image.pressure.shape[1:]} "
                              "images")
    peak = reference.pressure.max(axis=(-1, -2))
    if np.any(peak <= 0) or np.any(reference.force <= 0):
        raise ValidationError("image_errors: the reference image carries no load at some depth")
    diff = image.pressure - reference.pressure
    active = active_sensels(image.pressure, taxels)
    ref_active = active_sensels(reference.pressure, taxels)
    return ImageErrors(
        depth=reference.depth,
        force_error=image.force / reference.force - 1.0,
        rms_share=np.sqrt(np.mean(diff**2, axis=(-1, -2))) / peak,
        asymmetry=asymmetry(image.pressure, "x"), reference_asymmetry=asymmetry(reference.pressure, "x"),
        asymmetry_y=asymmetry(image.pressure, "y"), reference_asymmetry_y=asymmetry(reference.pressure, "y"),
        active=active, reference_active=ref_active,
        contact_area=active * tip.sensel_area, reference_contact_area=ref_active * tip.sensel_area,
    )
