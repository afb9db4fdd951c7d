"""Reading recordings: :func:`read_recording` validates every message of a palpate MCAP file, and reports a
truncated or damaged file (or salvages its complete chunks)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from palpate.core.errors import PalpateError, RecordingError
from palpate.core.io.mcap_schemas import FORMAT_VERSION, METADATA_NAME, VERSIONS_NAME
from palpate.core.io.recording import Annotation, JointState, Recording
from palpate.core.perception.streams import GroundTruth, PoseSample, TaxelFrame


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
