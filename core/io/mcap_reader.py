"""Reading recordings back: :func:`read_recording` validates every message and never trusts a size the file
declares (see :mod:`~palpate.core.io.mcap_records`). Every recording layout is read: format 3 (palpate's data on
``/palpate/...`` channels beside Foxglove views, which are skipped), format 2 (the data as extra fields of Foxglove's
well-known schemas) and format 1 (``palpate.*`` schemas). Each channel's decoder is picked by the file's format
version (its metadata record comes before any channel) and the channel's topic and schema name; channels of other
tools are skipped."""

from __future__ import annotations

import base64
import binascii
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from palpate.core import limits
from palpate.core.errors import PalpateError, RecordingError
from palpate.core.io.mcap_records import Channel, Damaged, Message, Metadata, ReadLimits, Schema, read_records
from palpate.core.io.mcap_schemas import DATA_PREFIX, METADATA_NAME, READABLE_VERSIONS, VERSIONS_NAME
from palpate.core.io.recording import Annotation, JointState, Recording
from palpate.core.perception.streams import GroundTruth, PoseSample, TaxelFrame


class _BadMessage(Exception):
    """A field of one message is missing or of the wrong type (turned into a RecordingError with topic/index)."""


_KINDS = {
    "number": lambda v: isinstance(v, (int, float)) and not isinstance(v, bool),
    "str": lambda v: isinstance(v, str),
    "list": lambda v: isinstance(v, list),
    "dict": lambda v: isinstance(v, dict),
    "int": lambda v: isinstance(v, int) and not isinstance(v, bool),
}


def _field(msg: dict, key: str, kind: str):
    try:
        value = msg[key]
    except KeyError:
        raise _BadMessage(f"missing field {key!r}") from None
    if not _KINDS[kind](value):
        raise _BadMessage(f"field {key!r} must be a {kind}, got {type(value).__name__}")
    if kind == "number" and not math.isfinite(value):
        raise _BadMessage(f"field {key!r} must be finite, got {value!r}")
    return value


@dataclass(frozen=True)
class _Bounds:
    """The plausible ranges in force while one file is read (limits are read once, not per message)."""

    length: float
    area_lo: float
    area_hi: float
    time: float

    @classmethod
    def in_force(cls) -> _Bounds:
        return cls(limits.limit("length_m"), limits.limit("length_min_m") ** 2, limits.limit("sensel_area_m2"),
                   limits.limit("time_s"))

    def time_of(self, msg: dict) -> float:
        t = _field(msg, "t", "number")
        # never negative: a recording's log times are unsigned, and palpate's writer refuses t < 0
        if not 0.0 <= t <= self.time:
            raise _BadMessage(str(limits.implausible("field 't'", t, 0.0, self.time, "s", "time_s")))
        return t

    def area(self, msg: dict) -> float:
        a = _field(msg, "sensel_area", "number")
        if not self.area_lo <= a <= self.area_hi:
            raise _BadMessage(str(limits.implausible("field 'sensel_area'", a, self.area_lo, self.area_hi, "m^2",
                                                     "length_min_m", "sensel_area_m2")))
        return a

    def position(self, msg: dict, key: str) -> np.ndarray:
        p = _field(msg, key, "dict")
        xyz = np.array([_field(p, k, "number") for k in "xyz"])
        if not np.all(np.abs(xyz) <= self.length):
            k = "xyz"[int(np.argmax(np.abs(xyz) > self.length))]
            raise _BadMessage(str(limits.implausible(f"field '{key}.{k}'", float(p[k]), -self.length, self.length,
                                                     "m", "length_m")))
        return xyz


def _numbers(msg: dict, key: str) -> np.ndarray:
    values = _field(msg, key, "list")
    try:  # one conversion for the whole list: strings, nulls, objects and nested lists fail it
        arr = np.array(values, dtype=float)
    except (TypeError, ValueError):
        raise _BadMessage(f"field {key!r} must be a list of numbers") from None
    if arr.ndim != 1 or not np.all(np.isfinite(arr)):
        raise _BadMessage(f"field {key!r} must be a list of finite numbers")
    return arr


def _exact_quaternion(sample: PoseSample, quat: np.ndarray) -> PoseSample:
    # The writer stored an already-normalised quaternion; normalising it again can change its last bit, and a
    # recording must read back exactly what was written.
    if abs(float(np.linalg.norm(quat)) - 1.0) < 1e-12:
        object.__setattr__(sample, "quaternion", quat)
    return sample


# ---- format 2: Foxglove's well-known schemas carrying palpate's fields ----

def _taxel_image(msg: dict, b: _Bounds) -> TaxelFrame:
    rows, cols = _field(msg, "height", "int"), _field(msg, "width", "int")
    if msg.get("encoding") != "mono8":
        raise _BadMessage(f"'encoding' must be 'mono8' (one byte per sensel), got {msg.get('encoding')!r}")
    try:
        raw = base64.b64decode(_field(msg, "data", "str"), validate=True)
    except (binascii.Error, ValueError):
        raise _BadMessage("'data' is not base64") from None
    if rows < 1 or cols < 1 or len(raw) != rows * cols:
        raise _BadMessage(f"'data' has {len(raw)} bytes, expected height*width = {rows}*{cols}")
    counts = np.frombuffer(raw, dtype=np.uint8).reshape(rows, cols)
    return TaxelFrame(t=b.time_of(msg), counts=counts, sensel_area=b.area(msg),
                      sensor_id=_field(msg, "frame_id", "str"))


def _frame_transform(msg: dict, b: _Bounds) -> PoseSample:
    q = _field(msg, "rotation", "dict")
    quat = np.array([_field(q, k, "number") for k in "wxyz"])
    sample = PoseSample(t=b.time_of(msg), position=b.position(msg, "translation"), quaternion=quat,
                        sensor_id=_field(msg, "child_frame_id", "str"))
    return _exact_quaternion(sample, quat)


def _log(msg: dict, b: _Bounds) -> Annotation:
    return Annotation(b.time_of(msg), _field(msg, "kind", "str"), _field(msg, "data", "dict"))


def _truth_series(msg: dict, b: _Bounds) -> tuple:
    material = msg.get("material")
    if material is not None and not isinstance(material, str):
        raise _BadMessage("'material' must be a string or null")
    t, force, ind = _numbers(msg, "t"), _numbers(msg, "force"), _numbers(msg, "indentation")
    if not (t.shape == force.shape == ind.shape):
        raise _BadMessage(f"'t', 'force' and 'indentation' differ in length ({t.size}, {force.size}, {ind.size})")
    return t, force, ind, material


# ---- palpate.* schemas: format 1's channels, and format 3's data channels (the same messages) ----

def _taxel_v1(msg: dict, b: _Bounds) -> TaxelFrame:
    rows, cols = _field(msg, "rows", "int"), _field(msg, "cols", "int")
    counts = _field(msg, "counts", "list")
    if rows < 1 or cols < 1 or len(counts) != rows * cols:
        raise _BadMessage(f"'counts' has {len(counts)} values, expected rows*cols = {rows}*{cols}")
    if not all(type(c) is int and 0 <= c <= 255 for c in counts):
        raise _BadMessage("'counts' must hold integers 0..255")
    return TaxelFrame(t=b.time_of(msg), counts=np.asarray(counts, dtype=np.uint8).reshape(rows, cols),
                      sensel_area=b.area(msg), sensor_id=_field(msg, "sensor_id", "str"))


def _pose_v1(msg: dict, b: _Bounds) -> PoseSample:
    q = _field(msg, "orientation", "dict")
    quat = np.array([_field(q, k, "number") for k in "wxyz"])
    sample = PoseSample(t=b.time_of(msg), position=b.position(msg, "position"), quaternion=quat,
                        sensor_id=_field(msg, "sensor_id", "str"))
    return _exact_quaternion(sample, quat)


def _annotation_v1(msg: dict, b: _Bounds) -> Annotation:
    return Annotation(b.time_of(msg), _field(msg, "kind", "str"), _field(msg, "data", "dict"))


def _truth_v1(msg: dict, b: _Bounds) -> tuple:
    material = msg.get("material")
    if material is not None and not isinstance(material, str):
        raise _BadMessage("'material' must be a string or null")
    return (np.array([b.time_of(msg)]), np.array([_field(msg, "force", "number")]),
            np.array([_field(msg, "indentation", "number")]), material)


def _joints(msg: dict, b: _Bounds) -> JointState:
    names = _field(msg, "names", "list")
    if not all(isinstance(n, str) for n in names):
        raise _BadMessage("'names' must be a list of strings")
    return JointState(b.time_of(msg), tuple(names), _numbers(msg, "position"),
                      _numbers(msg, "velocity"), _numbers(msg, "current"))


# (topic prefix or exact topic, schema name) -> (Recording list, decoder), for formats 1 and 2; a channel that
# comes before the metadata record (no palpate writer puts one there) is read as these formats are.
_DECODERS = {
    ("/taxels/", "foxglove.RawImage"): ("frames", _taxel_image),
    ("/pose/", "foxglove.FrameTransform"): ("poses", _frame_transform),
    ("/annotations", "foxglove.Log"): ("annotations", _log),
    ("/truth", "palpate.GroundTruthSeries"): ("truth", _truth_series),
    ("/joints", "palpate.JointState"): ("joints", _joints),
    ("/taxels/", "palpate.TaxelFrame"): ("frames", _taxel_v1),
    ("/pose/", "palpate.PoseSample"): ("poses", _pose_v1),
    ("/annotations", "palpate.Annotation"): ("annotations", _annotation_v1),
    ("/truth", "palpate.GroundTruth"): ("truth", _truth_v1),
}
# Format 3: only palpate's channels are data; the foxglove.* views on /taxels/, /pose/ and /annotations hold
# Foxglove's fields alone (no exact time) and are skipped like the maps.
_DECODERS_V3 = {
    (f"{DATA_PREFIX}/taxels/", "palpate.TaxelFrame"): ("frames", _taxel_v1),
    (f"{DATA_PREFIX}/pose/", "palpate.PoseSample"): ("poses", _pose_v1),
    (f"{DATA_PREFIX}/annotations", "palpate.Annotation"): ("annotations", _annotation_v1),
    ("/truth", "palpate.GroundTruthSeries"): ("truth", _truth_series),
    ("/joints", "palpate.JointState"): ("joints", _joints),
}
_PREFIXES = (f"{DATA_PREFIX}/taxels/", f"{DATA_PREFIX}/pose/", "/taxels/", "/pose/")


def _decoder_for(topic: str, schema_name: str | None, version: str | None):
    table = _DECODERS_V3 if version == "3" else _DECODERS
    prefix = next((p for p in _PREFIXES if topic.startswith(p)), topic)
    return table.get((prefix, schema_name), (None, None))


def read_recording(path, *, salvage: bool = False, limits: ReadLimits | None = None, progress=None) -> Recording:
    """Read a palpate MCAP recording (format 1, 2 or 3) and validate every message.

    Args:
        path: the .mcap file.
        salvage: accept a truncated or damaged file and return what its complete chunks hold
            (``Recording.salvaged`` is then True).
        limits: sizes the file may make the reader allocate (default: :meth:`ReadLimits.in_force`).
        progress: a :class:`~palpate.core.session.progress.Progress` to show the bytes read (optional).

    Raises:
        RecordingError: the file is missing, not MCAP, not a palpate recording, breaks a size limit, is
            truncated or corrupt (without ``salvage``; ``exc.salvaged`` says how many messages could be kept;
            ``palpate replay --salvage`` reads it), or a message lacks a field or holds an implausible number (a
            time, position or sensel area outside the limits ``time_s``, ``length_m``, ``length_min_m``,
            ``sensel_area_m2``; the message names the topic, the message's index on it and the field).
    """
    path = Path(path)
    limits = limits or ReadLimits.in_force()
    f, size = _open_regular(path)
    with f:
        return _read(f, path, size, salvage, limits, progress)


def _open_regular(path: Path):
    """The open file and its size; opened without blocking (a FIFO does not wait for a writer) and refused unless
    the open descriptor is a regular file (a device, pipe or folder cannot be a recording)."""
    import os
    import stat

    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
    except OSError as exc:
        raise RecordingError(f"{path}: cannot open recording: {exc.strerror}") from None
    st = os.fstat(fd)
    if not stat.S_ISREG(st.st_mode):
        os.close(fd)
        raise RecordingError(f"{path}: not a regular file (a device, pipe or folder cannot be a recording)")
    return os.fdopen(fd, "rb"), st.st_size


def _read(f, path: Path, size: int, salvage: bool, limits: ReadLimits, progress) -> Recording:
    out = {"frames": [], "poses": [], "joints": [], "annotations": [], "truth": []}
    metadata: dict | None = None
    version: str | None = None  # the file's format version, once its metadata record has been read
    versions: dict = {}
    schemas: dict[int, str] = {}
    channels: dict[int, tuple] = {}
    per_topic: dict[int, int] = {}
    n_messages = 0
    damage: str | None = None
    if progress is not None:
        progress.start(f"reading {path.name}", size, unit="B")
    loads = json.loads
    bounds = _Bounds.in_force()
    try:
        for record in read_records(f, path, size, limits):
            if type(record) is Message:
                entry = channels.get(record.channel_id)
                if entry is None:
                    damage = f"corrupt (message on unknown channel {record.channel_id})"
                    break
                n_messages += 1
                index = per_topic[record.channel_id]
                per_topic[record.channel_id] = index + 1
                key, decode, topic = entry
                if key is None:
                    continue  # a topic another tool added, or a view (image, frame, log line, map): not ours to read
                try:
                    msg = loads(record.data)
                    if type(msg) is not dict:
                        raise _BadMessage("is not a JSON object")
                    out[key].append(decode(msg, bounds))
                except (_BadMessage, ValueError, TypeError, PalpateError) as exc:
                    raise RecordingError(f"{path}: {topic} message {index}: {exc}",
                                         salvaged=n_messages - 1) from None
                if progress is not None and not n_messages % 4096:
                    progress.update(f.tell())
            elif type(record) is Channel:
                key, decode = _decoder_for(record.topic, schemas.get(record.schema_id), version)
                if key is not None and record.message_encoding != "json":
                    raise RecordingError(f"{path}: channel {record.topic!r} has message encoding "
                                         f"{record.message_encoding!r}, expected 'json'")
                channels[record.id] = (key, decode, record.topic)
                per_topic.setdefault(record.id, 0)
            elif type(record) is Schema:
                schemas[record.id] = record.name
            elif type(record) is Metadata:
                if record.name == METADATA_NAME:
                    metadata = _decode_metadata(path, record.entries)
                    version = record.entries["format_version"]
                elif record.name == VERSIONS_NAME:
                    versions = dict(record.entries)
    except Damaged as exc:
        damage = str(exc)
    if progress is not None:
        progress.update(size)
    if metadata is None:
        if damage is not None:
            raise RecordingError(f"{path}: not a readable palpate recording ({damage})")
        raise RecordingError(f"{path}: not a palpate recording (no {METADATA_NAME!r} metadata record)")
    if damage is not None and not salvage:
        raise RecordingError(
            f"{path}: recording is {damage}; {n_messages} messages in complete chunks could be salvaged "
            "(palpate replay --salvage, or read_recording(..., salvage=True))", salvaged=n_messages)
    return Recording(frames=out["frames"], poses=out["poses"], joints=out["joints"],
                     annotations=out["annotations"], truth=_assemble_truth(out["truth"]), metadata=metadata,
                     salvaged=damage is not None, versions=versions)


def _decode_metadata(path: Path, entries: dict[str, str]) -> dict:
    version = entries.get("format_version")
    if version not in READABLE_VERSIONS:
        raise RecordingError(f"{path}: palpate recording format version {version!r}; this palpate reads "
                             f"{', '.join(READABLE_VERSIONS)} (a newer palpate wrote it?)")
    out = {}
    for key, value in entries.items():
        if key == "format_version":
            continue
        try:
            out[key] = json.loads(value)
        except ValueError:
            raise RecordingError(f"{path}: metadata {key!r} is not valid JSON") from None
    return out


def _assemble_truth(parts: list) -> GroundTruth | None:
    if not parts:
        return None
    t, force, indentation, material = zip(*parts, strict=True)
    names = {m for m in material if m is not None}
    return GroundTruth(t=np.concatenate(t), force=np.concatenate(force), indentation=np.concatenate(indentation),
                       material=names.pop() if len(names) == 1 else None)
