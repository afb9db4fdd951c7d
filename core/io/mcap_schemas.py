"""The palpate recording format: MCAP, one append-only file any source writes and any stage can replay, and that
Foxglove shows natively (3D, Image, Plot, Log and Raw Messages panels; the layout ``models/foxglove_layout.json``
ships in the package, see ``docs/recordings.md``).

Format version 3. Every channel has ``message_encoding="json"`` and a ``jsonschema`` schema. palpate's data, what
replay reads, is on palpate's own channels under ``palpate.*`` schemas. Beside them, views for Foxglove use its
well-known schemas under their own names (``foxglove.*``) with exactly Foxglove's fields, so Foxglove knows what to
draw and any tool checking a message against Foxglove's schema finds nothing else in it; replay skips the views.

Data (SI units):

===============================  =============================  ==================================================
topic                            schema                         fields
===============================  =============================  ==================================================
``/palpate/taxels/<sensor_id>``  ``palpate.TaxelFrame``         ``t`` [s], ``sensor_id``, ``rows``, ``cols``,
                                                                ``sensel_area`` [m^2], ``counts`` (rows*cols
                                                                integers 0..255, row-major; plottable)
``/palpate/pose/<sensor_id>``    ``palpate.PoseSample``         ``t`` [s], ``sensor_id``, ``position`` {x, y, z}
                                                                [m], ``orientation`` {x, y, z, w} (the unit
                                                                quaternion of the sensor's frame in ``world``)
``/palpate/annotations``         ``palpate.Annotation``         ``t`` [s], ``kind``, ``data`` (free JSON object:
                                                                press windows, targets)
``/joints``                      ``palpate.JointState``         ``t`` [s], ``names``, ``position`` [rad],
                                                                ``velocity`` [rad/s], ``current`` [A]
``/truth``                       ``palpate.GroundTruthSeries``  one message per press: ``t`` [s], ``force`` [N],
                                                                ``indentation`` [m] (equal-length arrays),
                                                                ``material``
===============================  =============================  ==================================================

Views (Foxglove's fields only; replay skips them):

===============================  =============================  ==================================================
topic                            schema                         what it shows
===============================  =============================  ==================================================
``/taxels/<sensor_id>``          ``foxglove.RawImage``          each taxel frame as a ``mono8`` image (``data``:
                                                                the counts, row-major; ``frame_id``: the pad)
``/pose/<sensor_id>``            ``foxglove.FrameTransform``    each pose sample: frame ``<sensor_id>`` in
                                                                ``world`` (m, unit quaternion)
``/annotations``                 ``foxglove.Log``               each annotation as an INFO line (``level`` 2)
                                                                whose ``message`` reads kind and data
``/tf/<pad sensor_id>``          ``foxglove.FrameTransform``    once: the pad's frame in the first pose sensor's
                                                                (written by runs)
``/map/<object>``                ``foxglove.Grid`` (2-D) or     the map after every press: per cell ``red``,
                                 ``foxglove.VoxelGrid``         ``green``, ``blue``, ``alpha`` (uint8, the RGB
                                                                probability colours of the figures), one float32
                                                                ``P_<material>`` field each, ``entropy`` (float32),
                                                                ``explored`` (uint8)
``/scene``                       ``foxglove.SceneUpdate``       each object as an entity: its box or cylinder
                                                                and its name (cubes, cylinders and texts)
``/spots/<object>``              ``foxglove.SceneUpdate``       once, if any: the fine map's stiffness spots
                                                                (a red / blue marker and its sign and z)
===============================  =============================  ==================================================

Times: each message's ``log_time`` and Foxglove ``timestamp`` are ``round(t * 1e9)`` ns, so ``t`` must be >= 0;
``t`` itself is stored as a JSON number on the data channels, which round-trips a float exactly (replay rebuilds
maps bit for bit; nanoseconds could not hold an arbitrary float time). The views and the maps are outputs for
viewing: replay ignores them and recomputes the maps.

Metadata records (written first, before any channel, so they survive a crash and tell the reader the format before
any message): ``palpate`` holds the caller's metadata dict, one record entry per top-level key, each value
JSON-encoded (conventionally ``scenario``, ``sources`` and ``maps``) plus ``format_version``; ``palpate.versions``
holds the versions of palpate, numpy, mcap, Python and MuJoCo if it was loaded.

Older formats are still read; the reader picks each channel's decoder by the file's format version and the
channel's topic and schema name:

- format 2: no ``/palpate/...`` channels; the data rode on the Foxglove channels as extra fields
  (``foxglove.RawImage`` on ``/taxels/<id>`` with ``t``, ``sensel_area``, ``counts``; ``foxglove.FrameTransform``
  on ``/pose/<id>`` with ``t``; ``foxglove.Log`` on ``/annotations`` with ``t``, ``kind``, ``data``);
- format 1 (before Foxglove views): ``palpate.TaxelFrame`` on ``/taxels/<id>``, ``palpate.PoseSample`` on
  ``/pose/<id>``, ``palpate.Annotation`` on ``/annotations`` and one ``palpate.GroundTruth`` message per sample on
  ``/truth``.

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
FORMAT_VERSION = "3"
READABLE_VERSIONS = ("1", "2", "3")
SENSOR_ID = re.compile(r"^[A-Za-z0-9_.\-]+$")
WORLD_FRAME = "world"
DATA_PREFIX = "/palpate"  # palpate's own channels: /palpate/taxels/<id>, /palpate/pose/<id>, /palpate/annotations

# Foxglove's NumericType enumeration (PackedElementField.type) and LogLevel.
NUMERIC_TYPES = ("UNKNOWN", "UINT8", "INT8", "UINT16", "INT16", "UINT32", "INT32", "FLOAT32", "FLOAT64")
UINT8, FLOAT32 = NUMERIC_TYPES.index("UINT8"), NUMERIC_TYPES.index("FLOAT32")
LOG_LEVELS = ("UNKNOWN", "DEBUG", "INFO", "WARNING", "ERROR", "FATAL")
LOG_INFO = LOG_LEVELS.index("INFO")


def _num(description: str) -> dict:
    return {"type": "number", "description": description}


def _int(description: str, minimum: int = 0) -> dict:
    return {"type": "integer", "minimum": minimum, "description": description}


def _str(description: str = "") -> dict:
    return {"type": "string", "description": description} if description else {"type": "string"}


def _obj(props: dict, description: str = "", required: bool = True) -> dict:
    # Foxglove's schemas require every field they list; so do palpate's (the writer always writes them all).
    out = {"type": "object", "properties": props}
    if required:
        out["required"] = list(props)
    if description:
        out["description"] = description
    return out


def _enum(title: str, names: tuple[str, ...], description: str) -> dict:
    """An enumeration as Foxglove writes one: one titled constant per value, 0, 1, 2..."""
    return {"title": title, "description": description,
            "oneOf": [{"title": name, "const": i} for i, name in enumerate(names)]}


def _time(description: str) -> dict:
    return {"type": "object", "title": "time", "description": description,
            "properties": {"sec": {"type": "integer", "minimum": 0},
                           "nsec": {"type": "integer", "minimum": 0, "maximum": 999_999_999}}}


def _duration(description: str) -> dict:
    return {"type": "object", "title": "duration", "description": description,
            "properties": {"sec": {"type": "integer"},
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


def _array(items: dict, description: str = "") -> dict:
    out = {"type": "array", "items": items}
    if description:
        out["description"] = description
    return out


def _fields() -> dict:
    return _array(_obj({"name": _str(), "offset": _int("byte offset in a cell"),
                        "type": _enum("foxglove.NumericType", NUMERIC_TYPES, "type of the field")}),
                  "fields of each cell in data")


def _t() -> dict:
    return _num("timestamp, s, exactly as the source gave it")


#: SceneEntity's primitive arrays palpate never fills (written empty: Foxglove's schema requires them).
UNUSED_PRIMITIVES = ("arrows", "spheres", "lines", "triangles", "models")


def _entity() -> dict:
    prim = {"pose": _pose("centre"), "size": _vec("xyz", "m"), "color": _color()}
    cyl = {"pose": prim["pose"], "size": prim["size"], "bottom_scale": _num("1 = straight cylinder"),
           "top_scale": _num("1 = straight cylinder"), "color": prim["color"]}
    text = {"pose": _pose("anchor"), "billboard": {"type": "boolean"}, "font_size": _num("px"),
            "scale_invariant": {"type": "boolean"}, "color": _color(), "text": _str()}
    # SceneEntity requires all eight primitive arrays; palpate draws three, the others are always empty
    unused = {k: _array({"type": "object", "description": "not drawn by palpate: always empty"})
              for k in UNUSED_PRIMITIVES}
    return _obj({"timestamp": _time("time of the entity"), "frame_id": _str(), "id": _str(),
                 "lifetime": _duration("0 = forever"), "frame_locked": {"type": "boolean"},
                 "metadata": _array(_obj({"key": _str(), "value": _str()})),
                 "cubes": _array(_obj(prim)), "cylinders": _array(_obj(cyl)), "texts": _array(_obj(text)), **unused})


# Foxglove's well-known schemas: exactly Foxglove's field names and types (github.com/foxglove/foxglove-sdk,
# schemas/jsonschema), with palpate's descriptions.
FOXGLOVE_SCHEMAS: dict[str, dict] = {
    "foxglove.RawImage": _obj({
        "timestamp": _time("time of the frame"), "frame_id": _str("the pad"),
        "width": _int("columns of taxels"), "height": _int("rows of taxels"), "encoding": _str("mono8"),
        "step": _int("bytes per row"), "data": _bytes("raw counts, row-major, one byte each"),
    }, "a frame of a tactile array, shown as an image"),
    "foxglove.FrameTransform": _obj({
        "timestamp": _time("time of the pose"), "parent_frame_id": _str(), "child_frame_id": _str(),
        "translation": _vec("xyz", "m"), "rotation": _quat(),
    }, "a sensor's frame in its parent frame"),
    "foxglove.Log": _obj({
        "timestamp": _time("time of the event"), "level": _enum("foxglove.LogLevel", LOG_LEVELS, "log level"),
        "message": _str("the event, readable"), "name": _str(), "file": _str(), "line": _int("unused (0)"),
    }, "an annotation: an event on the recording's timeline"),
    "foxglove.Grid": _obj({
        "timestamp": _time("time of the map"), "frame_id": _str(),
        "pose": _pose("the map's corner with the smallest x and y"), "column_count": _int("cells along x"),
        "cell_size": _vec("xy", "m"), "row_stride": _int("bytes per row"), "cell_stride": _int("bytes per cell"),
        "fields": _fields(), "data": _bytes("cells, rows along y from the corner"),
    }, "a 2-D material map"),
    "foxglove.VoxelGrid": _obj({
        "timestamp": _time("time of the map"), "frame_id": _str(),
        "pose": _pose("the map's corner with the smallest x, y and z"), "row_count": _int("cells along y"),
        "column_count": _int("cells along x"), "cell_size": _vec("xyz", "m"),
        "slice_stride": _int("bytes per z slice"), "row_stride": _int("bytes per row"),
        "cell_stride": _int("bytes per cell"), "fields": _fields(), "data": _bytes("cells, slices from the bottom"),
    }, "a voxel material map"),
    "foxglove.SceneUpdate": _obj({
        "deletions": _array(_obj({"timestamp": _time("entities older than this are deleted"),
                                  "type": _enum("foxglove.SceneEntityDeletionType", ("MATCHING_ID", "ALL"),
                                                "what to delete"),
                                  "id": _str()})),
        "entities": _array(_entity()),
    }, "the explored objects"),
}

# palpate's data: what replay reads. The first three are format 1's schemas, unchanged.
PALPATE_SCHEMAS: dict[str, dict] = {
    "palpate.TaxelFrame": _obj({
        "t": _t(), "sensor_id": _str(), "rows": _int("rows of taxels", 1), "cols": _int("columns of taxels", 1),
        "sensel_area": _num("area of one sensel, m^2"),
        "counts": _array({"type": "integer", "minimum": 0, "maximum": 255}, "raw counts, row-major, rows*cols values"),
    }, "a frame of a tactile array"),
    "palpate.PoseSample": _obj({
        "t": _t(), "sensor_id": _str(), "position": _vec("xyz", "m"), "orientation": _quat(),
    }, "a pose sample: the sensor's frame in the world frame"),
    "palpate.Annotation": _obj({
        "t": _t(), "kind": _str("event kind"), "data": {"type": "object", "description": "the event's details"},
    }, "an event on the recording's timeline"),
    "palpate.JointState": _obj({
        "t": _t(), "names": _array(_str()), "position": _array(_num("rad")), "velocity": _array(_num("rad/s")),
        "current": _array(_num("A")),
    }, "joint readings of an actuator"),
    "palpate.GroundTruthSeries": _obj({
        "t": _array(_num("s")), "force": _array(_num("true normal force, N")),
        "indentation": _array(_num("true indentation, m")), "material": {"type": ["string", "null"]},
    }, "what the simulation knows beside the streams, one message per press"),
}

SCHEMAS: dict[str, dict] = {**FOXGLOVE_SCHEMAS, **PALPATE_SCHEMAS}
