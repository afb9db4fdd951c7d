"""The palpate recording format: MCAP, one append-only file any source writes and any stage can replay, and that
Foxglove shows natively (3D, Image, Plot, Log and Raw Messages panels; the layout ``models/foxglove_layout.json``
ships in the package, see ``docs/recordings.md``).

Format version 2. Every channel has ``message_encoding="json"`` and a ``jsonschema`` schema. Where Foxglove has a
well-known schema it is used under its own name (``foxglove.*``), so Foxglove knows what to draw; palpate adds a
few fields of its own to some of them (Foxglove ignores fields its schema does not use). Topics:

===========================  ============================  ==================================================
topic                        schema                        fields (SI units) besides Foxglove's
===========================  ============================  ==================================================
``/taxels/<sensor_id>``      ``foxglove.RawImage``         the pad as a ``mono8`` image (``data``: counts,
                                                           row-major); ``t`` [s], ``sensel_area`` [m^2],
                                                           ``counts`` (the same counts as a list, plottable)
``/pose/<sensor_id>``        ``foxglove.FrameTransform``   the fingertip as frame ``<sensor_id>`` in
                                                           ``world`` (m, unit quaternion); ``t`` [s]
``/joints``                  ``palpate.JointState``        t [s], names, position [rad], velocity [rad/s],
                                                           current [A]
``/annotations``             ``foxglove.Log``              a readable ``message``; ``t`` [s], ``kind``,
                                                           ``data`` (free JSON object: press windows, targets)
``/truth``                   ``palpate.GroundTruthSeries``  one message per press: t [s], force [N],
                                                           indentation [m] (equal-length arrays), material
``/map/<object>``            ``foxglove.Grid`` (2-D) or    the map after every press: per cell ``red``,
                             ``foxglove.VoxelGrid``        ``green``, ``blue``, ``alpha`` (uint8, the RGB
                                                           probability colours of the figures), one float32
                                                           ``P_<material>`` field each, ``entropy`` (float32),
                                                           ``explored`` (uint8)
``/scene``                   ``foxglove.SceneUpdate``      each object as an entity (its box or cylinder)
``/tf/<pad sensor_id>``      ``foxglove.FrameTransform``   once: the pad's frame in the first pose sensor's
                                                           (Foxglove's fields only; written by runs)
===========================  ============================  ==================================================

Times: each message's ``log_time`` and Foxglove ``timestamp`` are ``round(t * 1e9)`` ns, so ``t`` must be >= 0;
``t`` itself is stored as a JSON number, which round-trips a float exactly (replay rebuilds maps bit for bit).
Maps and the scene are outputs for viewing: replay ignores them and recomputes the maps.

Metadata records (written first, before any message, so they survive a crash): ``palpate`` holds the caller's
metadata dict, one record entry per top-level key, each value JSON-encoded (conventionally ``scenario``,
``sources`` and ``maps``) plus ``format_version``; ``palpate.versions`` holds the versions of palpate, numpy, mcap,
Python and MuJoCo if it was loaded.

Format version 1 (palpate before Foxglove-native channels: ``palpate.TaxelFrame``, ``palpate.PoseSample``,
``palpate.Annotation`` and one ``palpate.GroundTruth`` message per sample) is still read; the reader picks each
channel's decoder by its schema name.

Crash safety: messages are grouped in small chunks (``chunk_size`` bytes, or at most ``flush_interval`` seconds of
wall time) and every finished chunk is flushed to the operating system at once, so a writer killed at any moment
(even by SIGKILL) leaves a file readable up to its last complete chunk. :func:`read_recording` reports such a file
as truncated (a :class:`~palpate.core.errors.RecordingError` carrying how many messages could be salvaged), or
returns those messages with ``salvage=True`` (``palpate replay --salvage``). Reads are bounded: see
:mod:`~palpate.core.io.mcap_records`.
"""

from __future__ import annotations

import re

PROFILE = ""  # no ROS profile: plain JSON channels
METADATA_NAME = "palpate"
VERSIONS_NAME = "palpate.versions"
FORMAT_VERSION = "2"
READABLE_VERSIONS = ("1", "2")
SENSOR_ID = re.compile(r"^[A-Za-z0-9_.\-]+$")
WORLD_FRAME = "world"

# Foxglove's NumericType enumeration (PackedElementField.type).
UINT8, FLOAT32 = 1, 7
LOG_INFO = 2


def _num(description: str) -> dict:
    return {"type": "number", "description": description}


def _int(description: str) -> dict:
    return {"type": "integer", "minimum": 0, "description": description}


def _obj(props: dict, description: str = "") -> dict:
    out = {"type": "object", "properties": props}
    if description:
        out["description"] = description
    return out


def _time(description: str) -> dict:
    return {"type": "object", "title": "time", "description": description,
            "properties": {"sec": {"type": "integer", "minimum": 0},
                           "nsec": {"type": "integer", "minimum": 0, "maximum": 999_999_999}}}


def _vec(keys: str, unit: str) -> dict:
    return _obj({k: _num(f"{k}, {unit}") for k in keys})


def _quat() -> dict:
    return _obj({k: _num("quaternion component") for k in "xyzw"}, "unit quaternion")


def _pose(description: str) -> dict:
    return _obj({"position": _vec("xyz", "m"), "orientation": _quat()}, description)


def _color() -> dict:
    return _obj({k: _num(f"{k}, 0..1") for k in "rgba"})


def _bytes(description: str) -> dict:
    return {"type": "string", "contentEncoding": "base64", "description": description}


def _fields() -> dict:
    return {"type": "array", "description": "fields of each cell in data",
            "items": _obj({"name": {"type": "string"}, "offset": _int("byte offset in a cell"),
                           "type": {"type": "integer", "description": "foxglove.NumericType: 1 UINT8, 7 FLOAT32"}})}


def _t() -> dict:
    return _num("palpate: timestamp, s, exactly as the source gave it")


def _entity() -> dict:
    prim = {"pose": _pose("centre"), "size": _vec("xyz", "m"), "color": _color()}
    cyl = {**prim, "bottom_scale": _num("1 = straight cylinder"), "top_scale": _num("1 = straight cylinder")}
    text = {"pose": _pose("anchor"), "billboard": {"type": "boolean"}, "font_size": _num("px"),
            "scale_invariant": {"type": "boolean"}, "color": _color(), "text": {"type": "string"}}
    return _obj({"timestamp": _time("time of the entity"), "frame_id": {"type": "string"},
                 "id": {"type": "string"}, "lifetime": _time("0 = forever"), "frame_locked": {"type": "boolean"},
                 "metadata": {"type": "array", "items": _obj({"key": {"type": "string"},
                                                             "value": {"type": "string"}})},
                 "cubes": {"type": "array", "items": _obj(prim)},
                 "cylinders": {"type": "array", "items": _obj(cyl)},
                 "texts": {"type": "array", "items": _obj(text)}})


SCHEMAS: dict[str, dict] = {
    "foxglove.RawImage": _obj({
        "timestamp": _time("time of the frame"), "frame_id": {"type": "string"},
        "width": _int("columns of taxels"), "height": _int("rows of taxels"), "encoding": {"type": "string"},
        "step": _int("bytes per row"), "data": _bytes("raw counts, row-major, one byte each"),
        "t": _t(), "sensel_area": _num("palpate: area of one sensel, m^2"),
        "counts": {"type": "array", "items": {"type": "integer", "minimum": 0, "maximum": 255},
                   "description": "palpate: the counts of data, as numbers (for the Plot panel)"},
    }, "a frame of a tactile array, shown as an image"),
    "foxglove.FrameTransform": _obj({
        "timestamp": _time("time of the pose"), "parent_frame_id": {"type": "string"},
        "child_frame_id": {"type": "string"}, "translation": _vec("xyz", "m"), "rotation": _quat(), "t": _t(),
    }, "a pose sample: the sensor's frame in the world frame"),
    "foxglove.Log": _obj({
        "timestamp": _time("time of the event"), "level": {"type": "integer", "description": "2 = INFO"},
        "message": {"type": "string"}, "name": {"type": "string"}, "file": {"type": "string"},
        "line": _int("unused (0)"), "t": _t(), "kind": {"type": "string", "description": "palpate: event kind"},
        "data": {"type": "object", "description": "palpate: the event's details"},
    }, "an annotation: an event on the recording's timeline"),
    "foxglove.Grid": _obj({
        "timestamp": _time("time of the map"), "frame_id": {"type": "string"},
        "pose": _pose("the map's corner with the smallest x and y"), "column_count": _int("cells along x"),
        "cell_size": _vec("xy", "m"), "row_stride": _int("bytes per row"), "cell_stride": _int("bytes per cell"),
        "fields": _fields(), "data": _bytes("cells, rows along y from the corner"),
    }, "a 2-D material map"),
    "foxglove.VoxelGrid": _obj({
        "timestamp": _time("time of the map"), "frame_id": {"type": "string"},
        "pose": _pose("the map's corner with the smallest x, y and z"), "row_count": _int("cells along y"),
        "column_count": _int("cells along x"), "cell_size": _vec("xyz", "m"),
        "slice_stride": _int("bytes per z slice"), "row_stride": _int("bytes per row"),
        "cell_stride": _int("bytes per cell"), "fields": _fields(), "data": _bytes("cells, slices from the bottom"),
    }, "a voxel material map"),
    "foxglove.SceneUpdate": _obj({
        "deletions": {"type": "array", "items": _obj({"timestamp": _time(""), "type": {"type": "integer"},
                                                      "id": {"type": "string"}})},
        "entities": {"type": "array", "items": _entity()},
    }, "the explored objects"),
    "palpate.JointState": _obj({
        "t": _num("timestamp, s"), "names": {"type": "array", "items": {"type": "string"}},
        "position": {"type": "array", "items": _num("rad")}, "velocity": {"type": "array", "items": _num("rad/s")},
        "current": {"type": "array", "items": _num("A")},
    }, "joint readings of an actuator"),
    "palpate.GroundTruthSeries": _obj({
        "t": {"type": "array", "items": _num("s")}, "force": {"type": "array", "items": _num("true normal force, N")},
        "indentation": {"type": "array", "items": _num("true indentation, m")},
        "material": {"type": ["string", "null"]},
    }, "what the simulation knows beside the streams, one message per press"),
}
