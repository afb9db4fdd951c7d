"""An axisymmetric elastic sample under the press axis: what the FE reference (and the layered contact law) solve.

Coordinates: depth z below the undeformed top surface (m, >= 0), radius r from the press axis (m). The sample is a
disc of ``thickness`` resting on a rigid base, made of ``layers`` (top first) over the ``bulk`` material, with at
most one inclusion centred on the axis, and a free side at ``radius`` (``inf``: wide enough that the side does not
matter).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.world.scene import Layer, Material

#: How the sample's bottom meets the rigid base: glued, or free to slide (frictionless).
BASES = ("bonded", "frictionless")


@dataclass(frozen=True)
class AxisInclusion:
    """An inclusion centred on the press axis.

    Attributes:
        material: its material.
        shape: "sphere" (``radius``) or "cylinder" (``radius`` and ``height``, axis vertical).
        depth: depth of its top below the surface, m (>= 0).
        radius: sphere or cylinder radius, m.
        height: cylinder height, m (ignored for a sphere: 2 radius).
    """

    material: Material
    shape: str
    depth: float
    radius: float
    height: float = 0.0

    def __post_init__(self) -> None:
        if self.shape not in ("sphere", "cylinder"):
            raise ValidationError(f"AxisInclusion.shape must be 'sphere' or 'cylinder', got {self.shape!r}")
        if not (math.isfinite(self.depth) and self.depth >= 0):
            raise ValidationError(f"AxisInclusion.depth must be >= 0 m, got {self.depth!r}")
        if not (math.isfinite(self.radius) and self.radius > 0):
            raise ValidationError(f"AxisInclusion.radius must be > 0 m, got {self.radius!r}")
        if self.shape == "cylinder" and not (math.isfinite(self.height) and self.height > 0):
            raise ValidationError(f"AxisInclusion.height must be > 0 m for a cylinder, got {self.height!r}")

    @property
    def bottom(self) -> float:
        """Depth of its bottom, m."""
        return self.depth + (2.0 * self.radius if self.shape == "sphere" else self.height)

    def contains(self, r: np.ndarray, z: np.ndarray) -> np.ndarray:
        """Mask of the points at radius r and depth z (m) inside the inclusion."""
        r, z = np.asarray(r, dtype=float), np.asarray(z, dtype=float)
        if self.shape == "sphere":
            zc = self.depth + self.radius
            return r**2 + (z - zc) ** 2 <= self.radius**2
        return (r <= self.radius) & (z >= self.depth) & (z <= self.bottom)


@dataclass(frozen=True)
class AxisymmetricSample:
    """Layers on a bulk material on a rigid base, optionally an on-axis inclusion and a free side.

    Attributes:
        bulk: the material below the layers.
        thickness: total thickness, m (layers included).
        layers: top layers, first at the surface (their thicknesses must leave some bulk, or exactly none).
        base: "bonded" or "frictionless" contact with the rigid base.
        radius: lateral extent, m, with a free side there; ``inf`` for a sample wide enough not to matter.
        inclusion: an :class:`AxisInclusion` or None.
    """

    bulk: Material
    thickness: float
    layers: tuple[Layer, ...] = ()
    base: str = "bonded"
    radius: float = math.inf
    inclusion: AxisInclusion | None = None

    def __post_init__(self) -> None:
        if not (math.isfinite(self.thickness) and self.thickness > 0):
            raise ValidationError(f"AxisymmetricSample.thickness must be > 0 m, got {self.thickness!r}")
        if self.base not in BASES:
            raise ValidationError(f"AxisymmetricSample.base must be one of {BASES}, got {self.base!r}")
        if not self.radius > 0:
            raise ValidationError(f"AxisymmetricSample.radius must be > 0 m (or inf), got {self.radius!r}")
        if sum(layer.thickness for layer in self.layers) > self.thickness * (1 + 1e-9):
            raise ValidationError("AxisymmetricSample: the layers are thicker than the sample")
        if self.inclusion is not None and self.inclusion.bottom > self.thickness * (1 + 1e-9):
            raise ValidationError("AxisymmetricSample: the inclusion reaches below the sample's bottom")
        if self.inclusion is not None and self.inclusion.radius > self.radius:
            raise ValidationError("AxisymmetricSample: the inclusion is wider than the sample")

    def interfaces(self) -> list[float]:
        """Depths of the layer interfaces, m (excluding 0 and the bottom)."""
        out, z = [], 0.0
        for layer in self.layers:
            z += layer.thickness
            if z < self.thickness * (1 - 1e-9):
                out.append(z)
        return out

    def materials_at(self, r: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Young's modulus (Pa) and Poisson ratio at radius r and depth z (m), vectorised."""
        z = np.asarray(z, dtype=float)
        young = np.full(z.shape, self.bulk.young)
        poisson = np.full(z.shape, self.bulk.poisson)
        top = 0.0
        for layer in self.layers:
            inside = (z >= top) & (z < top + layer.thickness)
            young[inside] = layer.material.young
            poisson[inside] = layer.material.poisson
            top += layer.thickness
        if self.inclusion is not None:
            inside = self.inclusion.contains(r, z)
            young[inside] = self.inclusion.material.young
            poisson[inside] = self.inclusion.material.poisson
        return young, poisson

    @property
    def surface(self) -> Material:
        """The material at the top surface on the axis."""
        if self.inclusion is not None and self.inclusion.depth == 0.0:
            return self.inclusion.material
        return self.layers[0].material if self.layers else self.bulk

    def describe(self) -> str:
        """One line: layers, bulk, base, width, inclusion (mm and kPa)."""
        parts = [f"{1e3 * la.thickness:g} mm {la.material.young / 1e3:g} kPa" for la in self.layers]
        parts.append(f"{self.bulk.young / 1e3:g} kPa nu {self.bulk.poisson:g} to {1e3 * self.thickness:g} mm")
        text = " / ".join(parts) + f", {self.base} base"
        if math.isfinite(self.radius):
            text += f", free side at r = {1e3 * self.radius:g} mm"
        if self.inclusion is not None:
            inc = self.inclusion
            text += (f", {inc.shape} inclusion {inc.material.young / 1e3:g} kPa r {1e3 * inc.radius:g} mm "
                     f"from {1e3 * inc.depth:g} mm")
        return text
