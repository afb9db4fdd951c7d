"""Writing recordings: :class:`RecordingWriter` appends palpation streams to an MCAP file, crash-safe (see
:mod:`~palpate.core.io.mcap_schemas` for topics and schemas)."""

from __future__ import annotations

import json
import math
import platform
import sys
import time
from pathlib import Path

import numpy as np

from palpate.core import __version__
from palpate.core.errors import RecordingError, ValidationError
from palpate.core.io.mcap_schemas import FORMAT_VERSION, METADATA_NAME, PROFILE, SCHEMAS, SENSOR_ID, VERSIONS_NAME
from palpate.core.io.recording import JointState
from palpate.core.perception.streams import PoseSample, TaxelFrame


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
    if not isinstance(sensor_id, str) or not SENSOR_ID.match(sensor_id):
        raise ValidationError(
            f"sensor_id {sensor_id!r} cannot name a topic; use letters, digits, '_', '-' or '.'")
    return sensor_id
