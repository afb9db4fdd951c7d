"""Messages of the recording format (:mod:`~palpate.core.io.mcap_schemas`) built from palpate's types: JSON-ready
dicts, palpate's data in its own schemas and the views in Foxglove's well-known schemas with exactly Foxglove's
fields. The MCAP writer and the live view send the same dicts."""

from __future__ import annotations

import base64
import math
from collections.abc import Sequence

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.io.figures import rgb_image
from palpate.core.io.mcap_schemas import FLOAT32, LOG_INFO, UINT8, UNUSED_PRIMITIVES, WORLD_FRAME
from palpate.core.mapping.geometry import MapGeometry
from palpate.core.mapping.probability import entropy
from palpate.core.perception.streams import PoseSample, TaxelFrame
from palpate.core.world.scene import ObjectSpec


def time_ns(t: float, what: str) -> int:
    """``t`` seconds as the unsigned nanoseconds MCAP and Foxglove use; ValidationError unless finite and >= 0."""
    if not (isinstance(t, (int, float, np.floating, np.integer)) and math.isfinite(t) and t >= 0):
        raise ValidationError(f"{what}: t must be a finite time >= 0 s (log_time is unsigned ns), got {t!r}")
    return int(round(float(t) * 1e9))


def stamp(ns: int) -> dict:
    """Foxglove's ``{sec, nsec}`` time."""
    return {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}


def _b64(data: bytes) -> str:
    return base64.b64encode(data).decode("ascii")


def taxel_message(frame: TaxelFrame, ns: int, sensor_id: str) -> dict:
    """``foxglove.RawImage`` of a taxel frame: a mono8 image, one byte per sensel (``ns``: its time, ns)."""
    rows, cols = frame.counts.shape
    raw = np.ascontiguousarray(frame.counts, dtype=np.uint8)
    return {"timestamp": stamp(ns), "frame_id": sensor_id, "width": cols, "height": rows, "encoding": "mono8",
            "step": cols, "data": _b64(raw.tobytes())}


def taxel_frame_message(frame: TaxelFrame, sensor_id: str) -> dict:
    """``palpate.TaxelFrame``: the frame's time (s, exact), shape, sensel area (m^2) and counts, row-major."""
    rows, cols = frame.counts.shape
    return {"t": float(frame.t), "sensor_id": sensor_id, "rows": rows, "cols": cols,
            "sensel_area": float(frame.sensel_area),
            "counts": np.asarray(frame.counts, dtype=np.uint8).reshape(-1).tolist()}


def _xyz(v) -> dict:
    """A position or offset (m) as Foxglove's and palpate's {x, y, z}."""
    x, y, z = (float(c) for c in v)
    return {"x": x, "y": y, "z": z}


def _xyzw(q) -> dict:
    """palpate's (w, x, y, z) quaternion as {x, y, z, w}."""
    w, x, y, z = (float(c) for c in q)
    return {"x": x, "y": y, "z": z, "w": w}


def pose_message(sample: PoseSample, ns: int, sensor_id: str) -> dict:
    """``foxglove.FrameTransform``: the sensor's frame ``sensor_id`` in ``world`` (m, unit quaternion)."""
    return {"timestamp": stamp(ns), "parent_frame_id": WORLD_FRAME, "child_frame_id": sensor_id,
            "translation": _xyz(sample.position), "rotation": _xyzw(sample.quaternion)}


def pose_sample_message(sample: PoseSample, sensor_id: str) -> dict:
    """``palpate.PoseSample``: the sample's time (s, exact), position (m) and unit quaternion, bit for bit."""
    return {"t": float(sample.t), "sensor_id": sensor_id, "position": _xyz(sample.position),
            "orientation": _xyzw(sample.quaternion)}


def pad_message(ns: int, pose_id: str, taxel_id: str, offset: tuple[float, float, float]) -> dict:
    """``foxglove.FrameTransform`` placing the pad's frame ``taxel_id`` in the pose sensor's frame ``pose_id``
    (``offset``: the pad's centre in that frame, m; its axes the sensor's), exactly Foxglove's fields."""
    return {"timestamp": stamp(ns), "parent_frame_id": pose_id, "child_frame_id": taxel_id,
            "translation": _xyz(offset), "rotation": _xyzw((1.0, 0.0, 0.0, 0.0))}


def _describe(kind: str, data: dict) -> str:
    """A one-line, readable form of an event for Foxglove's Log panel."""
    parts = []
    for key, value in data.items():
        if isinstance(value, float):
            value = f"{value:.4g}"
        elif isinstance(value, list) and all(isinstance(v, float) for v in value):
            value = "[" + ", ".join(f"{v:.4g}" for v in value) + "]"
        parts.append(f"{key}={value}")
    line = f"{kind}: " + " ".join(parts)
    return line if len(line) <= 240 else line[:237] + "..."


def log_message(ns: int, kind: str, data: dict) -> dict:
    """``foxglove.Log`` INFO line of an annotation (``ns``: its time, ns)."""
    return {"timestamp": stamp(ns), "level": LOG_INFO, "message": _describe(kind, data), "name": "palpate",
            "file": "", "line": 0}


def annotation_message(t: float, kind: str, data: dict) -> dict:
    """``palpate.Annotation``: the event's time (s, exact), kind and details."""
    return {"t": float(t), "kind": kind, "data": data}


def truth_message(t: np.ndarray, force: np.ndarray, indentation: np.ndarray, material: str | None) -> dict:
    """``palpate.GroundTruthSeries``: a stretch of ground truth as arrays."""
    return {"t": t.tolist(), "force": force.tolist(), "indentation": indentation.tolist(), "material": material}


def _cells(probabilities: np.ndarray, explored: np.ndarray, materials: Sequence[str], base: float,
           alpha_unexplored: int) -> tuple[np.ndarray, list[dict]]:
    """Packed cells (red, green, blue, alpha, P_<material>..., entropy, explored) and their field list."""
    names = ["red", "green", "blue", "alpha"] + [f"P_{m}" for m in materials] + ["entropy", "explored"]
    types = ["u1"] * 4 + ["<f4"] * (len(materials) + 1) + ["u1"]
    cells = np.zeros(explored.shape, dtype=np.dtype(list(zip(names, types, strict=True))))
    rgb = np.round(rgb_image(probabilities) * 255).astype(np.uint8)
    for i, c in enumerate(("red", "green", "blue")):
        cells[c] = rgb[..., i]
    cells["alpha"] = np.where(explored, 255, alpha_unexplored)
    for j, m in enumerate(materials):
        cells[f"P_{m}"] = probabilities[..., j]
    cells["entropy"] = entropy(probabilities, base=base)
    cells["explored"] = explored
    fields = [{"name": n, "offset": cells.dtype.fields[n][1], "type": UINT8 if t == "u1" else FLOAT32}
              for n, t in zip(names, types, strict=True)]
    return cells, fields


def map_message(ns: int, name: str, probabilities: np.ndarray, explored: np.ndarray, geometry: MapGeometry,
                surface_z: float) -> tuple[str, dict]:
    """(schema name, message) of a map: ``foxglove.Grid`` on the object's surface at ``surface_z`` m, or
    ``foxglove.VoxelGrid`` below it. Unexplored cells are half transparent (2-D) or nearly invisible (voxels)."""
    p = np.asarray(probabilities, dtype=float)
    ex = np.asarray(explored, dtype=bool)
    materials = list(geometry.materials)
    x0, y0 = geometry.origin
    c = geometry.cell_size
    if not geometry.voxel:  # arrays are [iy, ix]: rows along y, as Grid lays out its data
        cells, fields = _cells(p, ex, materials, geometry.entropy_base, 150)
        ny, nx = ex.shape
        stride = cells.dtype.itemsize
        return "foxglove.Grid", {
            "timestamp": stamp(ns), "frame_id": WORLD_FRAME,
            "pose": {"position": {"x": x0, "y": y0, "z": surface_z + 1e-4},
                     "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}},
            "column_count": nx, "cell_size": {"x": c, "y": c}, "row_stride": nx * stride, "cell_stride": stride,
            "fields": fields, "data": _b64(cells.tobytes())}
    # voxels are [ix, iy, iz] with iz = 0 at the surface; VoxelGrid wants slices from the bottom, rows along y
    nx, ny, nz = ex.shape
    cells, fields = _cells(p.transpose(2, 1, 0, 3)[::-1], ex.transpose(2, 1, 0)[::-1], materials,
                           geometry.entropy_base, 25)
    stride = cells.dtype.itemsize
    return "foxglove.VoxelGrid", {
        "timestamp": stamp(ns), "frame_id": WORLD_FRAME,
        "pose": {"position": {"x": x0, "y": y0, "z": geometry.z_top - nz * c},
                 "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}},
        "row_count": ny, "column_count": nx, "cell_size": {"x": c, "y": c, "z": c},
        "slice_stride": nx * ny * stride, "row_stride": nx * stride, "cell_stride": stride, "fields": fields,
        "data": _b64(cells.tobytes())}


def _identity_pose(x: float, y: float, z: float) -> dict:
    return {"position": _xyz((x, y, z)), "orientation": _xyzw((1.0, 0.0, 0.0, 0.0))}


def scene_message(ns: int, objects: Sequence[ObjectSpec]) -> dict:
    """``foxglove.SceneUpdate`` with one entity per object: its box or cylinder (translucent grey) and its name."""
    grey = {"r": 0.6, "g": 0.6, "b": 0.6, "a": 0.25}
    entities = []
    for spec in objects:
        x, y = spec.position
        h = spec.height
        cubes, cylinders = [], []
        if spec.shape == "cylinder":
            r = spec.size[0]
            cylinders.append({"pose": _identity_pose(x, y, h / 2), "size": {"x": 2 * r, "y": 2 * r, "z": h},
                              "bottom_scale": 1.0, "top_scale": 1.0, "color": grey})
        elif spec.shape == "box":
            sx, sy, sz = spec.size
            cubes.append({"pose": _identity_pose(x, y, sz / 2), "size": {"x": sx, "y": sy, "z": sz}, "color": grey})
        text = {"pose": _identity_pose(x, y, h + 0.01), "billboard": True, "font_size": 14.0,
                "scale_invariant": True, "color": {"r": 0.1, "g": 0.1, "b": 0.1, "a": 1.0}, "text": spec.name}
        entities.append({"timestamp": stamp(ns), "frame_id": WORLD_FRAME, "id": f"object/{spec.name}",
                         "lifetime": {"sec": 0, "nsec": 0}, "frame_locked": False,
                         "metadata": [{"key": "material", "value": spec.material.name}, {"key": "shape",
                                                                                       "value": spec.shape}],
                         "cubes": cubes, "cylinders": cylinders, "texts": [text],
                         **{k: [] for k in UNUSED_PRIMITIVES}})
    return {"deletions": [], "entities": entities}


#: Colour of a stiffness spot's marker: harder red, softer blue.
SPOT_COLOURS = {"harder": {"r": 0.85, "g": 0.1, "b": 0.1, "a": 0.9}, "softer": {"r": 0.1, "g": 0.3, "b": 0.9, "a": 0.9}}


def spots_message(ns: int, name: str, anomalies: Sequence[dict], surface_z: float,
                  footprint: tuple[float, float] | None = None) -> dict:
    """``foxglove.SceneUpdate`` with one entity per stiffness spot of object ``name`` (summary.json's
    ``stiffness_anomalies``): a flat 4 mm marker on the surface at ``surface_z`` m, red harder, blue softer, and
    its sign and z as text; a spot that reads a lump (its ``lump``) has a second marker at the lump's top and its
    material and depth in the text. With ``footprint`` (a voxel map's cell side and depth, m), the lump as the lump
    layer holds it (:mod:`palpate.core.mapping.lump_layer`): a translucent box under each of the spot's presses
    from the read top to the map's depth, as opaque as the reading is sure of its material."""
    entities = []
    for k, a in enumerate(anomalies):
        x, y = a["centroid_m"]
        colour = SPOT_COLOURS[a["sign"]]
        cubes = [{"pose": _identity_pose(x, y, surface_z + 0.001), "size": {"x": 0.004, "y": 0.004, "z": 0.002},
                  "color": colour}]
        words = f"{a['sign']} {a['z']:+.1f}"
        lump = a.get("lump")
        if lump:
            cubes.append({"pose": _identity_pose(x, y, surface_z - lump["top_m"] - 0.001),
                          "size": {"x": 0.004, "y": 0.004, "z": 0.002}, "color": colour | {"a": 0.5}})
            words += f", {lump['material']} from {lump['top_m'] * 1e3:.1f} mm"
            if footprint is not None and lump["top_m"] < footprint[1]:
                cell, depth = footprint
                mid = surface_z - (lump["top_m"] + depth) / 2
                cubes += [{"pose": _identity_pose(px, py, mid),
                           "size": {"x": cell, "y": cell, "z": depth - lump["top_m"]},
                           "color": colour | {"a": 0.4 * float(lump.get("p_material", 1.0))}}
                          for px, py in a.get("press_locations_m") or ()]
        text = {"pose": _identity_pose(x, y, surface_z + 0.006), "billboard": True, "font_size": 12.0,
                "scale_invariant": True, "color": colour, "text": words}
        entities.append({"timestamp": stamp(ns), "frame_id": WORLD_FRAME, "id": f"spot/{name}/{k}",
                         "lifetime": {"sec": 0, "nsec": 0}, "frame_locked": False,
                         "metadata": [{"key": key, "value": str(a[key])} for key in ("sign", "material", "presses",
                                                                                        "z")],
                         "cubes": cubes, "cylinders": [], "texts": [text], **{k: [] for k in UNUSED_PRIMITIVES}})
    return {"deletions": [], "entities": entities}
