"""Writing recordings: :class:`RecordingWriter` appends palpation streams to an MCAP file, crash-safe, and can send
the same messages to a live view (see :mod:`~palpate.core.io.mcap_schemas` for topics and schemas). Each taxel
frame, pose sample and annotation goes twice: as palpate's data (what replay reads) and as a Foxglove view."""

from __future__ import annotations

import json
import math
import platform
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Protocol

import numpy as np

from palpate.core import __version__
from palpate.core.errors import RecordingError, ValidationError
from palpate.core.files import writing
from palpate.core.io import foxglove_messages as fm
from palpate.core.io.mcap_schemas import (
    DATA_PREFIX,
    FORMAT_VERSION,
    METADATA_NAME,
    PROFILE,
    SCHEMAS,
    SENSOR_ID,
    VERSIONS_NAME,
)
from palpate.core.io.recording import JointState
from palpate.core.mapping.geometry import MapGeometry
from palpate.core.names import file_stem
from palpate.core.perception.streams import PoseSample, TaxelFrame
from palpate.core.world.scene import ObjectSpec


class LiveSink(Protocol):
    """Where a live view takes messages (e.g. :class:`palpate.core.io.live.LiveServer`)."""

    def publish(self, topic: str, schema_name: str, schema: bytes, log_time: int, data: bytes) -> None: ...


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


class _FlushingStream:
    """File wrapper that pushes every write to the OS: mcap writes only whole records (header, metadata, a finished
    chunk, its indexes), so each completed chunk is on disk even if the process is then killed."""

    def __init__(self, f, fsync: bool, path: Path):
        self._f = f
        self._fsync = fsync
        self._path = path

    def write(self, data: bytes) -> int:
        with writing(self._path):  # a full disk names the recording
            n = self._f.write(data)
            self._f.flush()
            if self._fsync:
                import os

                os.fsync(self._f.fileno())
        return n

    def tell(self) -> int:
        return self._f.tell()

    def flush(self) -> None:
        with writing(self._path):
            self._f.flush()

    def close(self) -> None:
        with writing(self._path):
            self._f.close()


class RecordingWriter:
    """Append palpation streams to an MCAP file and/or a live view (see the module docstring for topics and crash
    safety).

    Use as a context manager; leaving the ``with`` block (also through an exception) finishes the file.

    Args:
        path: output file (.mcap), overwritten; None to write no file (only ``live``).
        metadata: JSON-serialisable dict with string keys (conventionally ``scenario``, ``sources`` and ``maps``).
        chunk_size: finish a chunk once it holds this many bytes; smaller loses less on a crash, compresses worse.
        flush_interval: also finish the chunk in progress when this much wall time, s, has passed since the
            last one, so a slow stream (annotations, 1 Hz poses) is not held in memory for long.
        fsync: also fsync after each chunk (survives power loss, not just a process crash; slower).
        live: also send every message to this live view.
        pad_offset: where each tactile pad's centre sits in the first pose sensor's frame, m (a run tracks the
            fingertip sphere's centre: (0, 0, -radius)); written once per pad as ``/tf/<pad>`` so that the pad's
            images hang in the transform tree. None (a rig whose marker-to-pad offset is not known): no transform.
    """

    def __init__(self, path, metadata: dict, *, chunk_size: int = 8192, flush_interval: float = 1.0,
                 fsync: bool = False, live: LiveSink | None = None,
                 pad_offset: tuple[float, float, float] | None = None):
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
        self.path = None if path is None else Path(path)
        self.live = live
        self._writer = self._stream = None
        if self.path is not None:
            from mcap.writer import CompressionType, Writer

            try:
                f = open(self.path, "wb")
            except OSError as exc:
                raise RecordingError(f"{self.path}: cannot open for writing: {exc.strerror}") from None
            self._stream = _FlushingStream(f, fsync, self.path)
            self._writer = Writer(self._stream, chunk_size=chunk_size, compression=CompressionType.ZSTD)
            self._writer.start(profile=PROFILE, library=f"palpate {__version__}")
            self._writer.add_metadata(METADATA_NAME, {"format_version": FORMAT_VERSION, **entries})
            self._writer.add_metadata(VERSIONS_NAME, _versions())
        self._schema_ids: dict[str, int] = {}
        self._schema_data: dict[str, bytes] = {}
        self._channels: dict[str, int] = {}
        self._sequence: dict[str, int] = {}
        self._flush_interval = float(flush_interval)
        self._last_flush = time.monotonic()
        self._closed = False
        self.message_count = 0
        if pad_offset is not None and (len(pad_offset) != 3 or not all(
                math.isfinite(float(v)) and abs(float(v)) < 1.0 for v in pad_offset)):
            raise ValidationError(f"pad_offset must be three finite lengths under 1 m, got {pad_offset!r}")
        self.pad_offset = None if pad_offset is None else tuple(float(v) for v in pad_offset)
        self._pose_ids: list[str] = []
        self._taxel_ids: list[str] = []

    def __enter__(self) -> RecordingWriter:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _schema(self, name: str) -> bytes:
        data = self._schema_data.get(name)
        if data is None:
            data = self._schema_data[name] = json.dumps({"title": name, **SCHEMAS[name]}).encode()
        return data

    def _channel(self, topic: str, schema_name: str) -> int:
        cid = self._channels.get(topic)
        if cid is None:
            sid = self._schema_ids.get(schema_name)
            if sid is None:
                sid = self._writer.register_schema(schema_name, "jsonschema", self._schema(schema_name))
                self._schema_ids[schema_name] = sid
            cid = self._writer.register_channel(topic, "json", sid)
            self._channels[topic] = cid
        return cid

    def _write(self, topic: str, schema_name: str, ns: int, msg: dict) -> None:
        if self._closed:
            raise RecordingError(f"{self.path or 'live view'}: write to {topic} after the recording was closed")
        try:
            data = json.dumps(msg, allow_nan=False, separators=(",", ":")).encode()
        except (TypeError, ValueError) as exc:
            raise ValidationError(f"{topic}: message is not JSON-serialisable (NaN or infinity?): {exc}") from None
        seq = self._sequence.get(topic, 0)
        self._sequence[topic] = seq + 1
        self.message_count += 1
        if self.live is not None:
            self.live.publish(topic, schema_name, self._schema(schema_name), ns, data)
        if self._writer is None:
            return
        self._writer.add_message(self._channel(topic, schema_name), log_time=ns, data=data, publish_time=ns,
                                 sequence=seq)
        now = time.monotonic()
        if now - self._last_flush >= self._flush_interval:
            self._writer.flush()
            self._last_flush = now

    def write_taxel(self, frame: TaxelFrame) -> None:
        """Append one taxel frame: its data on ``/palpate/taxels/<frame.sensor_id>`` (time s, counts, sensel area
        m^2) and its image on ``/taxels/<frame.sensor_id>``."""
        if not isinstance(frame, TaxelFrame):
            raise ValidationError(f"write_taxel expects a TaxelFrame, got {type(frame).__name__}")
        sid = _check_sensor_id(frame.sensor_id)
        topic = f"/taxels/{sid}"
        ns = fm.time_ns(frame.t, topic)
        self._write(f"{DATA_PREFIX}{topic}", "palpate.TaxelFrame", ns, fm.taxel_frame_message(frame, sid))
        self._write(topic, "foxglove.RawImage", ns, fm.taxel_message(frame, ns, sid))
        if sid not in self._taxel_ids:
            self._taxel_ids.append(sid)
            if self._pose_ids:
                self._place_pads(ns, self._pose_ids[0], [sid])

    def write_pose(self, sample: PoseSample) -> None:
        """Append one pose sample: its data on ``/palpate/pose/<sample.sensor_id>`` (time s, position m, unit
        quaternion) and the sensor's frame in ``world`` on ``/pose/<sample.sensor_id>``."""
        if not isinstance(sample, PoseSample):
            raise ValidationError(f"write_pose expects a PoseSample, got {type(sample).__name__}")
        sid = _check_sensor_id(sample.sensor_id)
        topic = f"/pose/{sid}"
        ns = fm.time_ns(sample.t, topic)
        self._write(f"{DATA_PREFIX}{topic}", "palpate.PoseSample", ns, fm.pose_sample_message(sample, sid))
        self._write(topic, "foxglove.FrameTransform", ns, fm.pose_message(sample, ns, sid))
        if sid not in self._pose_ids:
            self._pose_ids.append(sid)
            if len(self._pose_ids) == 1:
                self._place_pads(ns, sid, self._taxel_ids)

    def _place_pads(self, ns: int, pose_id: str, taxel_ids: list[str]) -> None:
        # each pad's frame joins the transform tree once, under the first pose sensor seen: world -> pose -> taxels
        if self.pad_offset is None:
            return
        for taxel_id in taxel_ids:
            self._write(f"/tf/{taxel_id}", "foxglove.FrameTransform", ns,
                        fm.pad_message(ns, pose_id, taxel_id, self.pad_offset))

    def write_joint_state(self, t, names, position, velocity, current) -> None:
        """Append joint readings on ``/joints``: positions rad, velocities rad/s, currents A (one per name)."""
        js = JointState(float(t), tuple(names), position, velocity, current)
        self._write("/joints", "palpate.JointState", fm.time_ns(js.t, "/joints"), {
            "t": js.t, "names": list(js.names), "position": js.position.tolist(),
            "velocity": js.velocity.tolist(), "current": js.current.tolist(),
        })

    def write_annotation(self, t, kind: str, data: dict) -> None:
        """Append an event at ``t`` s (e.g. kind ``press_start`` with ``{"label": ...}``) on
        ``/palpate/annotations``, and as a line of Foxglove's Log panel on ``/annotations``."""
        if not isinstance(kind, str) or not kind:
            raise ValidationError(f"annotation kind must be a non-empty string, got {kind!r}")
        if not isinstance(data, dict):
            raise ValidationError(f"annotation {kind!r}: data must be a dict, got {type(data).__name__}")
        ns = fm.time_ns(t, "/annotations")
        self._write(f"{DATA_PREFIX}/annotations", "palpate.Annotation", ns, fm.annotation_message(float(t), kind, data))
        self._write("/annotations", "foxglove.Log", ns, fm.log_message(ns, kind, data))

    def write_truth(self, t, force, indentation, material: str | None = None) -> None:
        """Append ground truth on ``/truth``: times s, forces N, indentations m (scalars or equal-length arrays,
        one message for all of them), material name (optional)."""
        t, force, indentation = (np.atleast_1d(np.asarray(v, dtype=float)) for v in (t, force, indentation))
        if not (t.ndim == 1 and t.shape == force.shape == indentation.shape and t.size):
            raise ValidationError(f"/truth: t, force and indentation must be equal-length 1-D arrays, got shapes "
                                  f"{t.shape}, {force.shape}, {indentation.shape}")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(force)) and np.all(np.isfinite(indentation))):
            raise ValidationError(f"/truth at t={t[0]}: t, force and indentation must be finite")
        if material is not None and not isinstance(material, str):
            raise ValidationError(f"/truth at t={t[0]}: material must be a string or None, got {material!r}")
        ns = fm.time_ns(float(t[0]), "/truth")
        self._write("/truth", "palpate.GroundTruthSeries", ns, fm.truth_message(t, force, indentation, material))

    def write_map(self, t: float, name: str, probabilities: np.ndarray, explored: np.ndarray, geometry: MapGeometry,
                  surface_z: float) -> None:
        """Append an object's map on ``/map/<name>`` (a Grid on the surface at ``surface_z`` m, or a VoxelGrid)."""
        topic = f"/map/{file_stem(name)}"  # a topic per object, whatever characters its name has
        ns = fm.time_ns(t, topic)
        schema, msg = fm.map_message(ns, name, probabilities, explored, geometry, surface_z)
        self._write(topic, schema, ns, msg)

    def write_scene(self, t: float, objects: Sequence[ObjectSpec]) -> None:
        """Append the objects as scene entities on ``/scene``."""
        ns = fm.time_ns(t, "/scene")
        self._write("/scene", "foxglove.SceneUpdate", ns, fm.scene_message(ns, objects))

    def write_spots(self, t: float, name: str, anomalies, surface_z: float,
                    footprint: tuple[float, float] | None = None) -> None:
        """Append an object's stiffness spots (summary.json's ``stiffness_anomalies``) as scene entities on
        ``/spots/<name>`` (``footprint``: a voxel map's cell side and depth, m, to draw the lumps they read as
        the lump layer holds them)."""
        topic = f"/spots/{file_stem(name)}"
        ns = fm.time_ns(t, topic)
        self._write(topic, "foxglove.SceneUpdate", ns, fm.spots_message(ns, name, anomalies, surface_z, footprint))

    def flush(self) -> None:
        """Finish the chunk in progress and push it to the operating system (nothing is lost if killed now)."""
        if self._writer is not None and not self._closed:
            self._writer.flush()
            self._last_flush = time.monotonic()

    def close(self) -> None:
        """Finish the file (last chunk, indexes, summary, footer). Calling it twice is harmless."""
        if self._closed:
            return
        self._closed = True
        if self._writer is None:
            return
        try:
            self._writer.finish()
        finally:
            self._stream.close()


def _check_sensor_id(sensor_id: str) -> str:
    if not isinstance(sensor_id, str) or not SENSOR_ID.match(sensor_id):
        raise ValidationError(
            f"sensor_id {sensor_id!r} cannot name a topic; use letters, digits, '_', '-' or '.'")
    return sensor_id
