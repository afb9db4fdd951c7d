"""MCAP recordings of palpation streams: one append-only file any source writes and any stage can replay.

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

import json
import math
import platform
import re
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from palpate.core import __version__
from palpate.core.errors import PalpateError, RecordingError, ValidationError
from palpate.core.perception.streams import GroundTruth, PoseSample, PressRecording, TaxelFrame

PROFILE = ""  # no ROS profile: plain JSON channels
METADATA_NAME = "palpate"
VERSIONS_NAME = "palpate.versions"
FORMAT_VERSION = "1"
_SENSOR_ID = re.compile(r"^[A-Za-z0-9_.\-]+$")


@dataclass(frozen=True)
class JointState:
    """Joint readings of an actuator (e.g. the servos of a Dynamixel finger) at one time.

    Attributes:
        t: timestamp, s.
        names: joint names, one per joint.
        position: joint positions, rad (m for a prismatic joint), shape (n,).
        velocity: joint velocities, rad/s, shape (n,).
        current: motor currents, A, shape (n,).
    """

    t: float
    names: tuple[str, ...]
    position: np.ndarray
    velocity: np.ndarray
    current: np.ndarray

    def __post_init__(self) -> None:
        names = tuple(self.names)
        if not all(isinstance(n, str) and n for n in names):
            raise ValidationError(f"JointState.names must be non-empty strings, got {self.names!r}")
        object.__setattr__(self, "names", names)
        for key in ("position", "velocity", "current"):
            arr = np.asarray(getattr(self, key), dtype=float).reshape(-1)
            if arr.shape != (len(names),):
                raise ValidationError(f"JointState.{key} must have one value per joint ({len(names)}), got {arr.shape}")
            if not np.all(np.isfinite(arr)):
                raise ValidationError(f"JointState.{key} must be finite, got {arr.tolist()}")
            object.__setattr__(self, key, arr)
        if not np.isfinite(self.t):
            raise ValidationError(f"JointState.t must be finite, got {self.t!r}")


@dataclass(frozen=True)
class Annotation:
    """A timed event in a recording (e.g. ``kind="press_start"``, data ``{"label": "Region_3"}``).

    Attributes:
        t: timestamp, s.
        kind: what happened (a short identifier).
        data: JSON-serialisable details.
    """

    t: float
    kind: str
    data: dict = field(default_factory=dict)


@dataclass
class Recording:
    """Everything read back from one recording, each stream in file order.

    Attributes:
        frames: taxel frames of every taxel sensor.
        poses: pose samples of every pose sensor.
        joints: joint states.
        annotations: annotations.
        truth: ground truth assembled from ``/truth`` (None if the recording has none, as real ones do).
        metadata: the metadata dict the writer was given.
        salvaged: True when the file was truncated or damaged and only its complete chunks were read.
        versions: software versions recorded by the writer (name -> version string).
    """

    frames: list[TaxelFrame]
    poses: list[PoseSample]
    joints: list[JointState]
    annotations: list[Annotation]
    truth: GroundTruth | None
    metadata: dict
    salvaged: bool = False
    versions: dict = field(default_factory=dict)


# --------------------------------------------------------------------------------------------- schemas

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


def _versions() -> dict[str, str]:
    import mcap

    versions = {
        "palpate": __version__,
        "numpy": np.__version__,
        "mcap": getattr(mcap, "__version__", "unknown"),
        "python": platform.python_version(),
    }
    # Only report MuJoCo when the process actually used it; importing it here would cost time and couple core to it.
    mujoco = sys.modules.get("mujoco")
    if mujoco is not None:
        versions["mujoco"] = str(getattr(mujoco, "__version__", "unknown"))
    return versions


def _time_ns(t: float, what: str) -> int:
    if not (isinstance(t, (int, float, np.floating, np.integer)) and math.isfinite(t) and t >= 0):
        raise ValidationError(f"{what}: t must be a finite time >= 0 s (log_time is unsigned ns), got {t!r}")
    return int(round(float(t) * 1e9))


# --------------------------------------------------------------------------------------------- writer

class _FlushingStream:
    """File wrapper that pushes every write to the OS: mcap writes only whole records (header, metadata, a finished
    chunk, its indexes), so each completed chunk is on disk even if the process is then killed."""

    def __init__(self, f, fsync: bool):
        self._f = f
        self._fsync = fsync

    def write(self, data: bytes) -> int:
        n = self._f.write(data)
        self._f.flush()
        if self._fsync:
            import os

            os.fsync(self._f.fileno())
        return n

    def tell(self) -> int:
        return self._f.tell()

    def flush(self) -> None:
        self._f.flush()

    def close(self) -> None:
        self._f.close()


class RecordingWriter:
    """Append palpation streams to an MCAP file (see the module docstring for topics and crash safety).

    Use as a context manager; leaving the ``with`` block (also through an exception) finishes the file.

    Args:
        path: output file (.mcap); overwritten.
        metadata: JSON-serialisable dict with string keys (conventionally ``scenario`` and ``sources``).
        chunk_size: finish a chunk once it holds this many bytes; smaller loses less on a crash, compresses worse.
        flush_interval: also finish the chunk in progress when this much wall time, s, has passed since the
            last one, so a slow stream (annotations, 1 Hz poses) is not held in memory for long.
        fsync: also fsync after each chunk (survives power loss, not just a process crash; slower).
    """

    def __init__(self, path, metadata: dict, *, chunk_size: int = 8192, flush_interval: float = 1.0,
                 fsync: bool = False):
        from mcap.writer import CompressionType, Writer

        if not isinstance(metadata, dict):
            raise ValidationError(f"recording metadata must be a dict, got {type(metadata).__name__}")
        entries = {}
        for key, value in metadata.items():
            if not isinstance(key, str) or not key:
                raise ValidationError(f"recording metadata keys must be non-empty strings, got {key!r}")
            if key == "format_version":
                raise ValidationError("recording metadata key 'format_version' is reserved by the file format")
            try:
                entries[key] = json.dumps(value, allow_nan=False, sort_keys=True)
            except (TypeError, ValueError) as exc:
                raise ValidationError(f"recording metadata[{key!r}] is not JSON-serialisable: {exc}") from None
        if not (isinstance(chunk_size, int) and chunk_size > 0):
            raise ValidationError(f"chunk_size must be a positive number of bytes, got {chunk_size!r}")
        if not (flush_interval > 0):
            raise ValidationError(f"flush_interval must be > 0 s, got {flush_interval!r}")
        self.path = Path(path)
        try:
            f = open(self.path, "wb")
        except OSError as exc:
            raise RecordingError(f"{self.path}: cannot open for writing: {exc.strerror}") from None
        self._stream = _FlushingStream(f, fsync)
        self._writer = Writer(self._stream, chunk_size=chunk_size, compression=CompressionType.ZSTD)
        self._writer.start(profile=PROFILE, library=f"palpate {__version__}")
        self._writer.add_metadata(METADATA_NAME, {"format_version": FORMAT_VERSION, **entries})
        self._writer.add_metadata(VERSIONS_NAME, _versions())
        self._schema_ids: dict[str, int] = {}
        self._channels: dict[str, int] = {}
        self._sequence: dict[int, int] = {}
        self._flush_interval = float(flush_interval)
        self._last_flush = time.monotonic()
        self._closed = False
        self.message_count = 0

    def __enter__(self) -> RecordingWriter:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _channel(self, topic: str, schema_name: str) -> int:
        cid = self._channels.get(topic)
        if cid is None:
            sid = self._schema_ids.get(schema_name)
            if sid is None:
                data = json.dumps({"title": schema_name, **SCHEMAS[schema_name]}).encode()
                sid = self._writer.register_schema(schema_name, "jsonschema", data)
                self._schema_ids[schema_name] = sid
            cid = self._writer.register_channel(topic, "json", sid)
            self._channels[topic] = cid
            self._sequence[cid] = 0
        return cid

    def _write(self, topic: str, schema_name: str, t: float, msg: dict) -> None:
        if self._closed:
            raise RecordingError(f"{self.path}: write to {topic} after the recording was closed")
        ns = _time_ns(t, topic)
        try:
            data = json.dumps(msg, allow_nan=False, separators=(",", ":")).encode()
        except (TypeError, ValueError) as exc:
            raise ValidationError(f"{topic}: message is not JSON-serialisable (NaN or infinity?): {exc}") from None
        cid = self._channel(topic, schema_name)
        seq = self._sequence[cid]
        self._sequence[cid] = seq + 1
        self._writer.add_message(cid, log_time=ns, data=data, publish_time=ns, sequence=seq)
        self.message_count += 1
        now = time.monotonic()
        if now - self._last_flush >= self._flush_interval:
            self._writer.flush()
            self._last_flush = now

    def write_taxel(self, frame: TaxelFrame) -> None:
        """Append one taxel frame on ``/taxels/<frame.sensor_id>``."""
        if not isinstance(frame, TaxelFrame):
            raise ValidationError(f"write_taxel expects a TaxelFrame, got {type(frame).__name__}")
        sid = _check_sensor_id(frame.sensor_id)
        rows, cols = frame.counts.shape
        self._write(f"/taxels/{sid}", "palpate.TaxelFrame", frame.t, {
            "t": float(frame.t), "sensor_id": sid, "rows": rows, "cols": cols,
            "sensel_area": float(frame.sensel_area), "counts": frame.counts.reshape(-1).tolist(),
        })

    def write_pose(self, sample: PoseSample) -> None:
        """Append one pose sample on ``/pose/<sample.sensor_id>``."""
        if not isinstance(sample, PoseSample):
            raise ValidationError(f"write_pose expects a PoseSample, got {type(sample).__name__}")
        sid = _check_sensor_id(sample.sensor_id)
        x, y, z = (float(v) for v in sample.position)
        qw, qx, qy, qz = (float(v) for v in sample.quaternion)
        self._write(f"/pose/{sid}", "palpate.PoseSample", sample.t, {
            "t": float(sample.t), "sensor_id": sid, "position": {"x": x, "y": y, "z": z},
            "orientation": {"x": qx, "y": qy, "z": qz, "w": qw},
        })

    def write_joint_state(self, t, names, position, velocity, current) -> None:
        """Append joint readings on ``/joints``: positions rad, velocities rad/s, currents A (one per name)."""
        js = JointState(float(t), tuple(names), position, velocity, current)
        self._write("/joints", "palpate.JointState", js.t, {
            "t": js.t, "names": list(js.names), "position": js.position.tolist(),
            "velocity": js.velocity.tolist(), "current": js.current.tolist(),
        })

    def write_annotation(self, t, kind: str, data: dict) -> None:
        """Append an event on ``/annotations`` (e.g. kind ``press_start`` with ``{"label": ...}``)."""
        if not isinstance(kind, str) or not kind:
            raise ValidationError(f"annotation kind must be a non-empty string, got {kind!r}")
        if not isinstance(data, dict):
            raise ValidationError(f"annotation {kind!r}: data must be a dict, got {type(data).__name__}")
        self._write("/annotations", "palpate.Annotation", t, {"t": float(t), "kind": kind, "data": data})

    def write_truth(self, t, force, indentation, material: str | None = None) -> None:
        """Append one ground-truth sample on ``/truth``: force N, indentation m, material name (optional)."""
        force, indentation = float(force), float(indentation)
        if not (math.isfinite(force) and math.isfinite(indentation)):
            raise ValidationError(f"/truth at t={t}: force and indentation must be finite, got {force}, {indentation}")
        if material is not None and not isinstance(material, str):
            raise ValidationError(f"/truth at t={t}: material must be a string or None, got {material!r}")
        self._write("/truth", "palpate.GroundTruth", t,
                    {"t": float(t), "force": force, "indentation": indentation, "material": material})

    def close(self) -> None:
        """Finish the file (last chunk, indexes, summary, footer). Calling it twice is harmless."""
        if self._closed:
            return
        self._closed = True
        try:
            self._writer.finish()
        finally:
            self._stream.close()


def _check_sensor_id(sensor_id: str) -> str:
    if not isinstance(sensor_id, str) or not _SENSOR_ID.match(sensor_id):
        raise ValidationError(
            f"sensor_id {sensor_id!r} cannot name a topic; use letters, digits, '_', '-' or '.'")
    return sensor_id


# --------------------------------------------------------------------------------------------- reader

class _BadMessage(Exception):
    """A field of one message is missing or of the wrong type (turned into a RecordingError with topic/index)."""


def _field(msg: dict, key: str, kind):
    if key not in msg:
        raise _BadMessage(f"missing field {key!r}")
    value = msg[key]
    ok = {
        "number": isinstance(value, (int, float)) and not isinstance(value, bool),
        "str": isinstance(value, str),
        "list": isinstance(value, list),
        "dict": isinstance(value, dict),
        "int": isinstance(value, int) and not isinstance(value, bool),
    }[kind]
    if not ok:
        raise _BadMessage(f"field {key!r} must be a {kind}, got {type(value).__name__}")
    if kind == "number" and not math.isfinite(value):
        raise _BadMessage(f"field {key!r} must be finite, got {value!r}")
    return value


def _numbers(msg: dict, key: str) -> np.ndarray:
    values = _field(msg, key, "list")
    if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
        raise _BadMessage(f"field {key!r} must be a list of numbers")
    arr = np.asarray(values, dtype=float)
    if not np.all(np.isfinite(arr)):
        raise _BadMessage(f"field {key!r} must hold finite numbers")
    return arr


def _decode_taxel(msg: dict) -> TaxelFrame:
    rows, cols = _field(msg, "rows", "int"), _field(msg, "cols", "int")
    counts = _field(msg, "counts", "list")
    if rows < 1 or cols < 1 or len(counts) != rows * cols:
        raise _BadMessage(f"'counts' has {len(counts)} values, expected rows*cols = {rows}*{cols}")
    if not all(type(c) is int and 0 <= c <= 255 for c in counts):
        raise _BadMessage("'counts' must hold integers 0..255")
    return TaxelFrame(t=_field(msg, "t", "number"), counts=np.asarray(counts, dtype=np.uint8).reshape(rows, cols),
                      sensel_area=_field(msg, "sensel_area", "number"), sensor_id=_field(msg, "sensor_id", "str"))


def _decode_pose(msg: dict) -> PoseSample:
    p, q = _field(msg, "position", "dict"), _field(msg, "orientation", "dict")
    pos = [_field(p, k, "number") for k in "xyz"]
    quat = np.array([_field(q, k, "number") for k in "wxyz"])
    sample = PoseSample(t=_field(msg, "t", "number"), position=np.array(pos), quaternion=quat,
                        sensor_id=_field(msg, "sensor_id", "str"))
    # The writer stored an already-normalised quaternion; normalising it again can change its last bit, and a
    # recording must read back exactly what was written.
    if abs(float(np.linalg.norm(quat)) - 1.0) < 1e-12:
        object.__setattr__(sample, "quaternion", quat)
    return sample


def _decode_joints(msg: dict) -> JointState:
    names = _field(msg, "names", "list")
    if not all(isinstance(n, str) for n in names):
        raise _BadMessage("'names' must be a list of strings")
    return JointState(_field(msg, "t", "number"), tuple(names), _numbers(msg, "position"),
                      _numbers(msg, "velocity"), _numbers(msg, "current"))


def _decode_annotation(msg: dict) -> Annotation:
    return Annotation(_field(msg, "t", "number"), _field(msg, "kind", "str"), _field(msg, "data", "dict"))


def _decode_truth(msg: dict) -> tuple[float, float, float, str | None]:
    material = msg.get("material")
    if material is not None and not isinstance(material, str):
        raise _BadMessage("'material' must be a string or null")
    return (_field(msg, "t", "number"), _field(msg, "force", "number"), _field(msg, "indentation", "number"),
            material)


def _decoder_for(topic: str):
    if topic.startswith("/taxels/"):
        return "frames", _decode_taxel
    if topic.startswith("/pose/"):
        return "poses", _decode_pose
    return {
        "/joints": ("joints", _decode_joints),
        "/annotations": ("annotations", _decode_annotation),
        "/truth": ("truth", _decode_truth),
    }.get(topic, (None, None))


def read_recording(path, *, salvage: bool = False) -> Recording:
    """Read a palpate MCAP recording and validate every message.

    Args:
        path: the .mcap file.
        salvage: accept a truncated or damaged file and return what its complete chunks hold
            (``Recording.salvaged`` is then True).

    Raises:
        RecordingError: the file is missing, not MCAP, not a palpate recording, truncated or corrupt (without
            ``salvage``; ``exc.salvaged`` says how many messages could be kept), or a message lacks a field
            (the message names the topic and the message's index on it).
    """
    from mcap.records import Channel, Footer, Message, Metadata
    from mcap.stream_reader import StreamReader

    path = Path(path)
    try:
        f = open(path, "rb")
    except OSError as exc:
        raise RecordingError(f"{path}: cannot open recording: {exc.strerror}") from None
    size = path.stat().st_size
    out = {"frames": [], "poses": [], "joints": [], "annotations": [], "truth": []}
    metadata: dict | None = None
    versions: dict = {}
    channels: dict[int, tuple[str, str | None, object]] = {}
    per_topic: dict[str, int] = {}
    n_messages = 0
    damage: str | None = None
    with f:
        # A record can never be larger than the file; this keeps a corrupt length field from allocating gigabytes.
        records = StreamReader(f, validate_crcs=True, record_size_limit=max(size, 1)).records
        while True:
            offset = f.tell()
            try:
                record = next(records)
            except StopIteration:
                break
            except Exception as exc:  # noqa: BLE001 - damaged bytes make the mcap parser fail in many ways
                damage = _describe_damage(path, exc, offset, size)
                break
            if isinstance(record, Footer):
                break
            if isinstance(record, Metadata):
                if record.name == METADATA_NAME:
                    metadata = _decode_metadata(path, record.metadata)
                elif record.name == VERSIONS_NAME:
                    versions = dict(record.metadata)
            elif isinstance(record, Channel):
                if record.message_encoding != "json":
                    raise RecordingError(f"{path}: channel {record.topic!r} has message encoding "
                                         f"{record.message_encoding!r}, expected 'json'")
                key, decode = _decoder_for(record.topic)
                channels[record.id] = (record.topic, key, decode)
            elif isinstance(record, Message):
                if record.channel_id not in channels:
                    damage = f"message on unknown channel {record.channel_id}"
                    break
                topic, key, decode = channels[record.channel_id]
                index = per_topic.get(topic, 0)
                per_topic[topic] = index + 1
                n_messages += 1
                if key is None:
                    continue  # a topic another tool added: not ours to interpret
                try:
                    msg = json.loads(record.data)
                    if not isinstance(msg, dict):
                        raise _BadMessage("is not a JSON object")
                    out[key].append(decode(msg))
                except (_BadMessage, ValueError, PalpateError) as exc:
                    raise RecordingError(f"{path}: {topic} message {index}: {exc}", salvaged=n_messages - 1) from None
    if metadata is None:
        if damage is not None:
            raise RecordingError(f"{path}: not a readable palpate recording ({damage})")
        raise RecordingError(f"{path}: not a palpate recording (no {METADATA_NAME!r} metadata record)")
    if damage is not None and not salvage:
        raise RecordingError(
            f"{path}: recording is {damage}; {n_messages} messages in complete chunks could be salvaged "
            "(read it with salvage=True)", salvaged=n_messages)
    return Recording(frames=out["frames"], poses=out["poses"], joints=out["joints"],
                     annotations=out["annotations"], truth=_assemble_truth(out["truth"]), metadata=metadata,
                     salvaged=damage is not None, versions=versions)


def _describe_damage(path: Path, exc: Exception, offset: int, size: int) -> str:
    """'truncated ...' when the record that failed runs past the end of the file (what a killed writer leaves),
    else 'corrupt ...'. Every record starts with a 1-byte opcode and a uint64 length."""
    from mcap.exceptions import InvalidMagic

    if isinstance(exc, InvalidMagic):
        if size < 8:
            return f"truncated at byte {size} (shorter than the 8-byte MCAP magic)"
        return "not an MCAP file (its first bytes are not the MCAP magic)"
    with open(path, "rb") as f:
        f.seek(offset)
        head = f.read(9)
    if len(head) < 9 or offset + 9 + int.from_bytes(head[1:], "little") > size:
        return f"truncated at byte {size} (last complete record ends at byte {offset})"
    return f"corrupt at byte {offset} of {size} ({type(exc).__name__}: {exc})"


def _decode_metadata(path: Path, entries: dict[str, str]) -> dict:
    version = entries.get("format_version")
    if version != FORMAT_VERSION:
        raise RecordingError(f"{path}: palpate recording format version {version!r}, expected {FORMAT_VERSION!r}")
    out = {}
    for key, value in entries.items():
        if key == "format_version":
            continue
        try:
            out[key] = json.loads(value)
        except ValueError:
            raise RecordingError(f"{path}: metadata {key!r} is not valid JSON") from None
    return out


def _assemble_truth(rows: list) -> GroundTruth | None:
    if not rows:
        return None
    t, force, indentation, material = zip(*rows, strict=True)
    names = {m for m in material if m is not None}
    return GroundTruth(t=np.array(t), force=np.array(force), indentation=np.array(indentation),
                       material=names.pop() if len(names) == 1 else None)


def recording_to_press_recording(rec: Recording, *, taxel_sensor: str | None = None,
                                 pose_sensor: str | None = None) -> PressRecording:
    """The streams the perception stack consumes: one taxel pad and one pose sensor of a recording.

    Args:
        rec: a recording from :func:`read_recording`.
        taxel_sensor, pose_sensor: which sensor to take when the recording has several (required then).

    The metadata is copied into ``meta``, with the annotations as a list of ``{"t", "kind", "data"}`` under
    ``meta["annotations"]``.
    """
    frames = [f for f in rec.frames if f.sensor_id == _pick(taxel_sensor, {f.sensor_id for f in rec.frames}, "taxel")]
    poses = [p for p in rec.poses if p.sensor_id == _pick(pose_sensor, {p.sensor_id for p in rec.poses}, "pose")]
    meta = dict(rec.metadata)
    if rec.annotations:
        meta["annotations"] = [{"t": a.t, "kind": a.kind, "data": a.data} for a in rec.annotations]
    if rec.salvaged:
        meta["salvaged"] = True
    return PressRecording(frames=frames, poses=poses, truth=rec.truth, meta=meta)


def _pick(wanted: str | None, present: set[str], what: str) -> str | None:
    if wanted is not None:
        if wanted not in present:
            raise ValidationError(f"no {what} sensor {wanted!r} in the recording; it has {sorted(present)}")
        return wanted
    if len(present) > 1:
        raise ValidationError(f"the recording has several {what} sensors {sorted(present)}; choose one")
    return next(iter(present), None)
