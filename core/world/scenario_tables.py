"""Parsers of a scenario's tables beyond the top level: objects (layers, inclusions, haptic-material maps, regions),
material references, and the small keys with rules of their own."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from palpate.core import files, limits
from palpate.core.errors import ValidationError
from palpate.core.files import brief
from palpate.core.names import check_name
from palpate.core.world.haptic_material import HapticMaterialMap
from palpate.core.world.scenario import MaterialEntry, ObjectEntry, RealismSpec
from palpate.core.world.scene import Inclusion, Layer, Material, ObjectSpec
from palpate.core.world.table_reader import REQUIRED, TableReader, resolve_path

#: Largest press force, N.
MAX_FORCE_N = 1e4
#: Object sizes, mm (10 m), and positions (100 m from the origin).
MAX_SIZE_MM, MAX_POSITION_MM = 1e4, 1e5
#: Cells along one side of a map (the product is bounded by the limit ``map_cells``).
MAX_CELLS_SIDE = 1_000_000
#: Most simulated sessions a run's predictive realism check may ask for (each is a training's presses).
MAX_PREDICTIVE_SESSIONS = 10_000


def training_source(r: TableReader) -> str:
    """``training.source``: the registered source that presses the reference materials (a simulation)."""
    value = r.get("source", str, "sim")
    if value in ("operator", "dynamixel"):
        raise r.err("source", f"{value!r} is an exploration actuator ([actuator] kind); the reference materials "
                    "are pressed by a registered simulated source (e.g. 'sim'), or give training.memory")
    if not value:
        raise r.err("source", "must name a registered source, e.g. 'sim'")
    return value


def realism_spec(r: TableReader, base: Path) -> RealismSpec:
    """``[realism]``: ``profile`` (a name, or a ``.toml`` path resolved against the scenario) and ``real_params``."""
    profile = r.get("profile", str, "ideal")
    if not profile:
        raise r.err("profile", 'must name a profile ("ideal", "lab", a shipped profile) or a .toml file')
    if profile.endswith(".toml") or "/" in profile or "\\" in profile:
        path = resolve_path(base, profile)
        if not path.is_file():
            raise r.err("profile", f"realism profile file {path} not found")
        profile = str(path)
    real = r.get("real_params", str, "")
    real_path = resolve_path(base, real) if real else None
    if real_path is not None and not real_path.is_file():
        raise r.err("real_params", f"per-press parameter table {real_path} not found")
    sessions = r.get("predictive_sessions", int, 0)
    if sessions and real_path is None:
        raise r.err("predictive_sessions", "judges the simulation against a real table: give real_params too")
    if sessions:
        # lazily: loading a scenario that asks for no check leaves the statistics modules unloaded
        from palpate.core.perception.predictive_check import MIN_SESSIONS

        if not MIN_SESSIONS <= sessions <= MAX_PREDICTIVE_SESSIONS:
            raise r.err("predictive_sessions", f"must be 0 (off) or {MIN_SESSIONS}-{MAX_PREDICTIVE_SESSIONS}, "
                        f"got {sessions}")
    r.finish()
    return RealismSpec(profile, real_path, sessions)


def optional_force(r: TableReader) -> float | None:
    value = r.number("max_force_n", 5.0, lo=0.0, hi=MAX_FORCE_N)
    return None if value == 0 else value


def extrapolation_passes(r: TableReader) -> int | None:
    """``extrapolation_passes``: an integer >= 1 (1 = seed 000 eq. 6.15 once) or "all" (None: repeat until every
    cell is filled)."""
    value = r.get("extrapolation_passes", (int, str), 1)
    if isinstance(value, str):
        if value != "all":
            raise r.err("extrapolation_passes", f'expected an integer >= 1 or "all", got {value!r}')
        return None
    if value < 1:
        raise r.err("extrapolation_passes", f'must be >= 1 (or "all"), got {value}')
    return value


def material_named(r: TableReader, key: str, materials: dict[str, MaterialEntry], default: Any = REQUIRED) -> Material:
    name = r.get(key, str, default)
    if name not in materials:
        raise r.err(key, f"unknown material {name!r}; defined materials: {', '.join(materials)}")
    return materials[name].material


def _height(shape: str, size: tuple[float, ...]) -> float:
    return size[1] if shape == "cylinder" else size[2]


def _span_mm(centre: float, size: tuple[float, ...], axis: int, shape: str) -> str:
    half = size[0] if shape == "cylinder" else size[axis] / 2
    return f"{1e3 * (centre - half):g} to {1e3 * (centre + half):g} mm"


def inclusion_meets_object(inc: Inclusion, shape: str, size: tuple[float, ...], position: tuple[float, float]) -> bool:
    """Whether an inclusion shares any volume with a box or cylinder object resting on the table (z from 0 up to
    its height, m): the inclusion's bounding box against the object's (a cylinder: the nearest point of the box's
    footprint within its radius)."""
    c = np.asarray(inc.center, dtype=float)
    if inc.shape == "sphere":
        half = np.full(3, inc.size[0])
    elif inc.shape == "box":
        half = np.asarray(inc.size, dtype=float) / 2
    else:  # a column runs through the whole height
        half = np.array([inc.size[0] / 2, inc.size[1] / 2, np.inf])
    top = _height(shape, size)
    if c[2] + half[2] <= 0.0 or c[2] - half[2] >= top:
        return False
    lo, hi = c[:2] - half[:2], c[:2] + half[:2]
    p = np.asarray(position, dtype=float)
    if shape == "cylinder":
        nearest = np.clip(p, lo, hi)
        return bool(np.sum((nearest - p) ** 2) < size[0] ** 2)
    ohalf = np.asarray(size[:2], dtype=float) / 2
    return bool(np.all(hi > p - ohalf) and np.all(lo < p + ohalf))


def object_entry(r: TableReader, materials: dict[str, MaterialEntry], base: Path) -> ObjectEntry:
    name = check_name(r.get("name", str), f"{r.file}: {r.path}.name")
    shape = r.choice("shape", ("box", "cylinder", "mesh"), "box")
    count = {"box": 3, "cylinder": 2, "mesh": 3}[shape]
    size = tuple(v * 1e-3 for v in r.numbers("size_mm", count, positive=True, limit=MAX_SIZE_MM))
    position = tuple(v * 1e-3 for v in r.numbers("position_mm", 2, (0.0, 0.0), limit=MAX_POSITION_MM))
    bulk = material_named(r, "material", materials)
    mesh = r.get("mesh", str, "")
    layers = []
    for lr in r.subs("layers"):
        thickness = lr.number("thickness_mm", lo=0.0, lo_open=True, hi=MAX_SIZE_MM) * 1e-3
        layers.append(Layer(material_named(lr, "material", materials), thickness))
        lr.finish()
    inclusions = []
    for ir in r.subs("inclusions"):
        ishape = ir.choice("shape", ("sphere", "box", "column"))
        icount = {"sphere": 1, "box": 3, "column": 2}[ishape]
        centre = ir.numbers("center_mm", (2, 3), limit=MAX_POSITION_MM)
        centre3 = (centre[0] * 1e-3, centre[1] * 1e-3, (centre[2] if len(centre) == 3 else 0.0) * 1e-3)
        inc = Inclusion(material_named(ir, "material", materials), ishape, centre3,
                        tuple(v * 1e-3 for v in ir.numbers("size_mm", icount, positive=True, limit=MAX_SIZE_MM)))
        ir.finish()
        if shape != "mesh" and not inclusion_meets_object(inc, shape, size, position):
            raise ir.err("center_mm", f"the {ishape} at {brief(list(centre))} mm (x, y in the world frame, z up from "
                         f"the table) lies wholly outside object {name!r} (x {_span_mm(position[0], size, 0, shape)}, "
                         f"y {_span_mm(position[1], size, 1, shape)}, z 0 to {1e3 * _height(shape, size):g} mm); "
                         "move it inside or remove it")
        inclusions.append(inc)
    material_map = None
    map_path = r.get("material_map", str, "")
    if map_path:
        folder = resolve_path(base, map_path)
        hm = HapticMaterialMap.read(folder)
        unknown = [m for m in hm.materials if m not in materials]
        if unknown:
            raise r.err("material_map", f"{folder} names materials {unknown} that the scenario does not define")
        material_map = hm
    regions = []
    for i, cell in enumerate(r.get("regions", list, [])):
        if not (isinstance(cell, list) and len(cell) == 2
                and all(isinstance(c, int) and not isinstance(c, bool) and 1 <= c <= MAX_CELLS_SIDE for c in cell)):
            raise r.err(f"regions[{i}]", f"expected a 1-based [column, row] pair of integers, got {brief(cell)}")
        regions.append((cell[0], cell[1]))
    grid_origin = r.numbers("grid_origin_mm", 2, None, limit=MAX_POSITION_MM)
    grid_shape = r.get("grid_cells", list, None)
    if grid_shape is not None and not (len(grid_shape) == 2 and all(
            isinstance(v, int) and not isinstance(v, bool) and 0 < v <= MAX_CELLS_SIDE for v in grid_shape)):
        raise r.err("grid_cells", f"expected [columns, rows] positive integers (at most {MAX_CELLS_SIDE}), got "
                    f"{brief(grid_shape)}")
    mesh_path = None
    if mesh:
        mesh_path = files.regular_file(resolve_path(base, mesh), f"{r.file}: {r.path}.mesh")
        limits.check("mesh_mb", f"{r.file}: {r.path}.mesh: {mesh_path}: file size", mesh_path.stat().st_size)
    r.finish()
    try:
        map_materials = tuple(materials[n].material for n in material_map.materials) if material_map else ()
        spec = ObjectSpec(name, shape, size, position, bulk, tuple(layers), tuple(inclusions),
                          mesh_path=str(mesh_path) if mesh_path else None, material_map=material_map,
                          map_materials=map_materials)
    except ValidationError as exc:
        raise ValidationError(f"{r.file}: {r.path}: {exc}") from None
    return ObjectEntry(spec, tuple(regions),
                       tuple(v * 1e-3 for v in grid_origin) if grid_origin else None,
                       tuple(grid_shape) if grid_shape else None)
