"""Plain descriptions of what is pressed: materials, objects with layers and inclusions, the fingertip, sensors.

These are data only (numpy, no MuJoCo): the scenario loader builds them, the simulation turns them into a
MuJoCo scene, and the run loop uses :func:`material_index_at` for ground truth (true material per map cell or
voxel). Coordinates are SI metres in the world frame; the table top is z = 0 and objects rest on it, so an
object's top surface is at z = its height.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from numbers import Integral, Real

import numpy as np

from palpate.core.errors import ValidationError


def finite_number(value) -> bool:
    """A real number that is finite and not a bool (Python's, numpy's, a JSON document's)."""
    return isinstance(value, Real) and not isinstance(value, bool) and math.isfinite(value)


def integer(value) -> bool:
    """An integer of Python's or numpy's that is not a bool."""
    return isinstance(value, Integral) and not isinstance(value, bool)


def check_finite(owner: str, **fields) -> None:
    """ValidationError naming ``owner`` and the field unless each field is a finite real number (not a bool): the
    range checks after it compare values, which NaN and a string escape."""
    for name, value in fields.items():
        if not finite_number(value):
            raise ValidationError(f"{owner}: {name} must be a finite number (SI units), got {value!r}")


def _sequence(owner: str, name: str, value) -> None:
    """ValidationError unless ``value`` is a tuple or list of finite numbers."""
    if not (isinstance(value, (tuple, list)) and all(finite_number(v) for v in value)):
        raise ValidationError(f"{owner}: {name} must be a tuple of finite numbers (SI units), got {value!r}")


@dataclass(frozen=True)
class Material:
    """A homogeneous elastic material.

    Attributes:
        name: label used in maps and reports.
        young: Young's modulus, Pa.
        poisson: Poisson ratio, dimensionless, in [0, 0.5).
        damping: viscous relaxation time, s (Kelvin-Voigt: stress = E (strain + damping * strain rate)).
    """

    name: str
    young: float
    poisson: float = 0.3
    damping: float = 0.0

    def __post_init__(self) -> None:
        if not self.name:
            raise ValidationError("Material.name must not be empty")
        check_finite(f"Material {self.name!r}", young=self.young, poisson=self.poisson, damping=self.damping)
        if not self.young > 0:
            raise ValidationError(f"Material {self.name!r}: young must be a positive modulus in Pa, got {self.young}")
        if not (0.0 <= self.poisson < 0.5):
            raise ValidationError(f"Material {self.name!r}: poisson must be in [0, 0.5), got {self.poisson}")
        if not self.damping >= 0:
            raise ValidationError(f"Material {self.name!r}: damping must be >= 0 s, got {self.damping}")

    @property
    def effective_modulus(self) -> float:
        """Plane-strain modulus E / (1 - nu^2), Pa, as used by Hertz contact against a rigid indenter."""
        return self.young / (1.0 - self.poisson**2)


@dataclass(frozen=True)
class Layer:
    """A layer at the top of an object, from its surface down to ``thickness`` (m)."""

    material: Material
    thickness: float

    def __post_init__(self) -> None:
        check_finite("Layer", thickness=self.thickness)
        if not self.thickness > 0:
            raise ValidationError(f"Layer thickness must be > 0 m, got {self.thickness}")


@dataclass(frozen=True)
class Inclusion:
    """A region of another material inside an object.

    Attributes:
        material: the inclusion's material.
        shape: "sphere" (size = (radius,)), "box" (size = full extents (sx, sy, sz)) or
            "column" (a vertical prism through the whole height, size = (sx, sy)).
        center: (x, y, z) centre in the world frame, m (z is ignored for "column").
        size: see shape, m.
    """

    material: Material
    shape: str
    center: tuple[float, float, float]
    size: tuple[float, ...]

    def __post_init__(self) -> None:
        expected = {"sphere": 1, "box": 3, "column": 2}
        if self.shape not in expected:
            raise ValidationError(f"Inclusion.shape must be one of {sorted(expected)}, got {self.shape!r}")
        _sequence("Inclusion", "size", self.size)
        _sequence("Inclusion", "center", self.center)
        if len(self.size) != expected[self.shape]:
            raise ValidationError(
                f"Inclusion of shape {self.shape!r} needs {expected[self.shape]} size values, got {len(self.size)}"
            )
        if any(not s > 0 for s in self.size):
            raise ValidationError(f"Inclusion sizes must be > 0 m, got {self.size}")
        if len(self.center) != 3:
            raise ValidationError(f"Inclusion.center must be (x, y, z) in m, got {self.center}")

    def contains(self, points: np.ndarray) -> np.ndarray:
        """Boolean mask of the points (n, 3) that lie inside the inclusion."""
        c = np.asarray(self.center, dtype=float)
        d = points - c
        if self.shape == "sphere":
            return np.einsum("ij,ij->i", d, d) <= self.size[0] ** 2
        half = np.asarray(self.size, dtype=float) / 2.0
        if self.shape == "box":
            return np.all(np.abs(d) <= half, axis=1)
        return np.all(np.abs(d[:, :2]) <= half, axis=1)


@dataclass(frozen=True)
class ObjectSpec:
    """An object resting on the table.

    Attributes:
        name: label.
        shape: "box" (size = full extents (sx, sy, sz)), "cylinder" (size = (radius, height), axis vertical)
            or "mesh" (mesh_path to a file trimesh reads; size = scale factors (sx, sy, sz)).
        size: see shape, m.
        position: (x, y) of the object's centre on the table, m.
        material: the bulk material.
        layers: top layers, first is at the surface.
        inclusions: regions of other materials; later ones win where they overlap.
        mesh_path: for shape "mesh", path of the mesh file (relative paths resolve against models/).
        material_map: optional haptic-material map (see palpate.core.world.haptic_material) giving a spatially
            varying surface material; None for none.
        map_materials: the Materials the map's category names stand for (the map stores names only).
    """

    name: str
    shape: str
    size: tuple[float, ...]
    position: tuple[float, float]
    material: Material
    layers: tuple[Layer, ...] = ()
    inclusions: tuple[Inclusion, ...] = ()
    mesh_path: str | None = None
    material_map: object | None = None
    map_materials: tuple[Material, ...] = ()

    def __post_init__(self) -> None:
        expected = {"box": 3, "cylinder": 2, "mesh": 3}
        if self.shape not in expected:
            raise ValidationError(f"object {self.name!r}: shape must be one of {sorted(expected)}, got {self.shape!r}")
        _sequence(f"object {self.name!r}", "size", self.size)
        _sequence(f"object {self.name!r}", "position", self.position)
        if len(self.size) != expected[self.shape]:
            raise ValidationError(
                f"object {self.name!r}: shape {self.shape!r} needs {expected[self.shape]} size values, "
                f"got {len(self.size)}"
            )
        if any(not s > 0 for s in self.size):
            raise ValidationError(f"object {self.name!r}: sizes must be > 0 m, got {self.size}")
        if self.shape == "mesh" and not self.mesh_path:
            raise ValidationError(f"object {self.name!r}: shape 'mesh' needs mesh_path")
        if len(self.position) != 2:
            raise ValidationError(f"object {self.name!r}: position must be (x, y) in m, got {self.position}")
        if self.material_map is not None:
            known = {m.name for m in self.map_materials}
            missing = [n for n in getattr(self.material_map, "materials", []) if n not in known]
            if missing:
                raise ValidationError(f"object {self.name!r}: its material map names {missing}, which "
                                      "map_materials does not define")

    @property
    def height(self) -> float:
        """Height of the top surface above the table, m (for meshes, the scaled z extent is not known here)."""
        if self.shape == "box":
            return float(self.size[2])
        if self.shape == "cylinder":
            return float(self.size[1])
        return float(self.size[2])

    def materials(self) -> list[Material]:
        """Every distinct material of the object, bulk first, in order of appearance."""
        seen: dict[str, Material] = {self.material.name: self.material}
        for m in ([layer.material for layer in self.layers] + list(self.map_materials)
                  + [inc.material for inc in self.inclusions]):
            seen.setdefault(m.name, m)
        return list(seen.values())

    def contains_xy(self, xy: np.ndarray) -> np.ndarray:
        """Boolean mask of the (n, 2) points whose vertical line passes through the object's footprint."""
        d = np.asarray(xy, dtype=float) - np.asarray(self.position, dtype=float)
        if self.shape == "cylinder":
            return np.einsum("ij,ij->i", d, d) <= self.size[0] ** 2
        half = np.asarray(self.size[:2], dtype=float) / 2.0
        return np.all(np.abs(d) <= half, axis=1)


def material_at(obj: ObjectSpec, points: np.ndarray) -> list[Material | None]:
    """Material at each point (n, 3) of the world, None outside the object. See :func:`material_index_at`."""
    palette = obj.materials()
    idx = material_index_at(obj, points, [m.name for m in palette])
    return [palette[i] if i >= 0 else None for i in idx]


def material_index_at(obj: ObjectSpec, points: np.ndarray, names: list[str]) -> np.ndarray:
    """Index into ``names`` of the material at each point, vectorised.

    Args:
        obj: the object.
        points: (n, 3) world points, m.
        names: material names to index into (e.g. the haptic memory's reference materials).

    Returns:
        int array (n,): index into ``names``; -1 outside the object or for a material not in ``names``.
        Layers are measured down from the top surface; inclusions override layers and bulk; a haptic-material
        map, when given, overrides the bulk at the surface layer it describes.
    """
    pts = np.atleast_2d(np.asarray(points, dtype=float))
    if pts.shape[1] != 3:
        raise ValidationError(f"points must have shape (n, 3), got {pts.shape}")
    lookup = {n: i for i, n in enumerate(names)}
    out = np.full(len(pts), lookup.get(obj.material.name, -1), dtype=int)
    top = obj.height
    depth_below_top = top - pts[:, 2]
    start = 0.0
    for layer in obj.layers:
        inside = (depth_below_top >= start) & (depth_below_top < start + layer.thickness)
        out[inside] = lookup.get(layer.material.name, -1)
        start += layer.thickness
    if obj.material_map is not None:
        # the map's own materials indexed into ``names`` once, not once a point (presses look up thousands)
        best, named = obj.material_map.material_codes_at(pts[:, :2])  # type: ignore[attr-defined]
        codes = np.array([lookup.get(n, -1) for n in obj.material_map.materials], dtype=int)  # type: ignore[attr-defined]
        out[named] = codes[best[named]]
    for inc in obj.inclusions:
        out[inc.contains(pts)] = lookup.get(inc.material.name, -1)
    outside = ~obj.contains_xy(pts[:, :2]) | (pts[:, 2] < 0.0) | (pts[:, 2] > top + 1e-12)
    out[outside] = -1
    return out


@dataclass(frozen=True)
class FingertipSpec:
    """A spherical fingertip carrying a rows x cols sensel pad (one Tekscan Grip pad by default).

    Attributes:
        radius: tip radius, m (human index fingertip ~8 mm).
        rows, cols: sensel grid.
        pitch: centre-to-centre sensel spacing, m. The default 2.5 mm pad (10 mm wide) is fine enough that the
            contact area keeps growing through a press on soft and hard materials alike; at 4 mm a hard material's
            contact stays inside the inner four sensels and c_A is constant (the cutaneous fit is then undefined).
        sensel_size: side of one square sensel, m (<= pitch); sensel area = sensel_size^2.
    """

    radius: float = 0.008
    rows: int = 4
    cols: int = 4
    pitch: float = 0.0025
    sensel_size: float = 0.0022

    def __post_init__(self) -> None:
        check_finite("FingertipSpec", radius=self.radius, pitch=self.pitch, sensel_size=self.sensel_size)
        if not self.radius > 0:
            raise ValidationError(f"FingertipSpec.radius must be > 0 m, got {self.radius}")
        if not (integer(self.rows) and integer(self.cols)):
            raise ValidationError(f"FingertipSpec: rows and cols must be whole numbers, got {self.rows}x{self.cols}")
        if self.rows < 1 or self.cols < 1:
            raise ValidationError(f"FingertipSpec needs at least one sensel, got {self.rows}x{self.cols}")
        if not (0 < self.sensel_size <= self.pitch):
            raise ValidationError(
                f"FingertipSpec.sensel_size must be in (0, pitch={self.pitch}] m, got {self.sensel_size}"
            )

    @property
    def sensel_area(self) -> float:
        """Area of one sensel, m^2."""
        return self.sensel_size**2

    def sensel_centres(self) -> np.ndarray:
        """(rows, cols, 2) sensel centres in the pad plane, m, relative to the tip's axis; row 0 at +y."""
        ys = (np.arange(self.rows)[::-1] - (self.rows - 1) / 2.0) * self.pitch
        xs = (np.arange(self.cols) - (self.cols - 1) / 2.0) * self.pitch
        gx, gy = np.meshgrid(xs, ys)
        return np.stack([gx, gy], axis=-1)


@dataclass(frozen=True)
class TaxelSensorSpec:
    """A Tekscan-like 8-bit taxel array model.

    Attributes:
        rate: frame rate, Hz (Tekscan Grip: 50 Hz in seed 000).
        gain: raw counts per Pa of mean pressure over a sensel.
        noise_std: standard deviation of additive noise, counts.
        threshold: noise floor, counts; readings at or below it are reported as 0.
        clock_offset: offset of the sensor clock from simulation time, s.
    """

    rate: float = 50.0
    gain: float = 1.2e-3
    noise_std: float = 0.5
    threshold: int = 2
    clock_offset: float = 0.0

    def __post_init__(self) -> None:
        check_finite("TaxelSensorSpec", rate=self.rate, gain=self.gain, noise_std=self.noise_std,
                     threshold=self.threshold, clock_offset=self.clock_offset)
        if not self.rate > 0:
            raise ValidationError(f"TaxelSensorSpec.rate must be > 0 Hz, got {self.rate}")
        if not self.gain > 0:
            raise ValidationError(f"TaxelSensorSpec.gain must be > 0 counts/Pa, got {self.gain}")
        if self.noise_std < 0 or not (0 <= self.threshold < 255):
            raise ValidationError("TaxelSensorSpec: noise_std must be >= 0 and threshold in [0, 255)")


@dataclass(frozen=True)
class PoseSensorSpec:
    """A Polhemus-like pose tracker model.

    Attributes:
        rate: nominal sample rate, Hz (~30 Hz in seed 000).
        noise_std: position noise per axis, m (sub-millimetre).
        clock_offset: offset of the tracker clock from simulation time, s.
        jitter: standard deviation of sample-time jitter, s.
    """

    rate: float = 30.0
    noise_std: float = 2.0e-4
    clock_offset: float = 0.0
    jitter: float = 1.0e-3

    def __post_init__(self) -> None:
        check_finite("PoseSensorSpec", rate=self.rate, noise_std=self.noise_std, clock_offset=self.clock_offset,
                     jitter=self.jitter)
        if not self.rate > 0:
            raise ValidationError(f"PoseSensorSpec.rate must be > 0 Hz, got {self.rate}")
        if self.noise_std < 0 or self.jitter < 0:
            raise ValidationError("PoseSensorSpec: noise_std and jitter must be >= 0")
        if self.jitter * self.rate > 0.25:
            raise ValidationError("PoseSensorSpec.jitter must stay below a quarter of the sample period")


@dataclass(frozen=True)
class Scene:
    """Everything a simulated press needs to know about the world."""

    objects: tuple[ObjectSpec, ...]
    fingertip: FingertipSpec = field(default_factory=FingertipSpec)
    taxels: TaxelSensorSpec = field(default_factory=TaxelSensorSpec)
    pose: PoseSensorSpec = field(default_factory=PoseSensorSpec)

    def object_under(self, x: float, y: float) -> ObjectSpec | None:
        """The object whose footprint contains (x, y), or None."""
        for obj in self.objects:
            if obj.contains_xy(np.array([[x, y]]))[0]:
                return obj
        return None
