"""The palpate recording format: MCAP, one append-only file any source writes and any stage can replay.

Layout (readable by Foxglove and ROS 2 MCAP tools): every channel has ``message_encoding="json"`` and a
``jsonschema`` schema. One topic per sensor:

===========================  ========================  ====================================================
topic                        schema                    message fields (SI units)
===========================  ========================  ====================================================
``/taxels/<sensor_id>``      ``palpate.TaxelFrame``    t [s], sensor_id, rows, cols, sensel_area [m^2],
                                                       counts: rows*cols ints 0..255, row-major
``/pose/<sensor_id>``        ``palpate.PoseSample``    t [s], sensor_id, position {x,y,z} [m],
                                                       orientation {x,y,z,w} (unit quaternion)
``/joints``                  ``palpate.JointState``    t [s], names, position [rad], velocity [rad/s],
                                                       current [A]
``/annotations``             ``palpate.Annotation``    t [s], kind, data (free JSON object)
``/truth``                   ``palpate.GroundTruth``   t [s], force [N], indentation [m], material (opt.)
===========================  ========================  ====================================================

Each message's ``log_time`` is ``round(t * 1e9)`` ns, so ``t`` must be >= 0 (sources start their clocks at 0 or
use the Unix epoch). ``t`` itself is stored as a JSON number, which round-trips a float exactly.

Metadata records (written first, before any message, so they survive a crash): ``palpate`` holds the caller's
metadata dict, one record entry per top-level key, each value JSON-encoded (conventionally ``scenario`` and
``sources``); ``palpate.versions`` holds the versions of palpate, numpy, mcap, Python and MuJoCo if it was loaded.

Crash safety: messages are grouped in small chunks (``chunk_size`` bytes, or at most ``flush_interval`` seconds of
wall time) and every finished chunk is flushed to the operating system at once, so a writer killed at any moment
(even by SIGKILL) leaves a file readable up to its last complete chunk. :func:`read_recording` reports such a file
as truncated (a :class:`~palpate.core.errors.RecordingError` carrying how many messages could be salvaged), or
returns those messages with ``salvage=True``.
"""

from __future__ import annotations

import re

PROFILE = ""  # no ROS profile: plain JSON channels
METADATA_NAME = "palpate"
VERSIONS_NAME = "palpate.versions"
FORMAT_VERSION = "1"
SENSOR_ID = re.compile(r"^[A-Za-z0-9_.\-]+$")


def _num(description: str) -> dict:
    return {"type": "number", "description": description}


def _xyz(unit: str) -> dict:
    return {"type": "object", "required": ["x", "y", "z"],
            "properties": {k: _num(f"{k}, {unit}") for k in ("x", "y", "z")}}


SCHEMAS: dict[str, dict] = {
    "palpate.TaxelFrame": {
        "type": "object",
        "required": ["t", "sensor_id", "rows", "cols", "sensel_area", "counts"],
        "properties": {
            "t": _num("timestamp, s"),
            "sensor_id": {"type": "string"},
            "rows": {"type": "integer", "minimum": 1},
            "cols": {"type": "integer", "minimum": 1},
            "sensel_area": _num("area of one sensel, m^2"),
            "counts": {"type": "array", "description": "raw counts, row-major, rows*cols values",
                       "items": {"type": "integer", "minimum": 0, "maximum": 255}},
        },
    },
    "palpate.PoseSample": {
        "type": "object",
        "required": ["t", "sensor_id", "position", "orientation"],
        "properties": {
            "t": _num("timestamp, s"),
            "sensor_id": {"type": "string"},
            "position": _xyz("m"),
            "orientation": {"type": "object", "required": ["x", "y", "z", "w"],
                            "properties": {k: _num("unit quaternion component") for k in "xyzw"}},
        },
    },
    "palpate.JointState": {
        "type": "object",
        "required": ["t", "names", "position", "velocity", "current"],
        "properties": {
            "t": _num("timestamp, s"),
            "names": {"type": "array", "items": {"type": "string"}},
            "position": {"type": "array", "items": _num("rad")},
            "velocity": {"type": "array", "items": _num("rad/s")},
            "current": {"type": "array", "items": _num("A")},
        },
    },
    "palpate.Annotation": {
        "type": "object",
        "required": ["t", "kind", "data"],
        "properties": {"t": _num("timestamp, s"), "kind": {"type": "string"}, "data": {"type": "object"}},
    },
    "palpate.GroundTruth": {
        "type": "object",
        "required": ["t", "force", "indentation"],
        "properties": {
            "t": _num("timestamp, s"),
            "force": _num("true normal force, N"),
            "indentation": _num("true indentation, m"),
            "material": {"type": ["string", "null"]},
        },
    },
}
