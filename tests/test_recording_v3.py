"""Recording format 3: every message on a ``foxglove.*`` channel holds exactly the fields of Foxglove's well-known
schema, and each schema written under a Foxglove name lists exactly Foxglove's fields and types; palpate's data
rides on its own ``/palpate/...`` channels and reads back bit for bit; the reader picks decoders by the file's
format version; the live view is sent what the file holds."""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap.writer import Writer

from palpate.core.errors import RecordingError
from palpate.core.io.mcap_reader import read_recording
from palpate.core.io.mcap_writer import RecordingWriter
from palpate.core.mapping.geometry import MapGeometry
from palpate.core.perception.streams import PoseSample, TaxelFrame
from palpate.core.world.scenario_file import parse_scenario

SMALL = (Path(__file__).parent / "test_run.py").read_text().split('SMALL = """', 1)[1].split('"""', 1)[0]

# Foxglove's well-known schemas (github.com/foxglove/foxglove-sdk, schemas/jsonschema/*.json): field names and JSON
# types, transcribed. "enum:N" is an integer enumeration of the values 0..N-1; a list holds the shape of its items.
TIME = {"sec": "integer", "nsec": "integer"}
VEC2 = {"x": "number", "y": "number"}
VEC3 = {"x": "number", "y": "number", "z": "number"}
QUAT = {"x": "number", "y": "number", "z": "number", "w": "number"}
POSE = {"position": VEC3, "orientation": QUAT}
COLOR = {"r": "number", "g": "number", "b": "number", "a": "number"}
PACKED_FIELD = {"name": "string", "offset": "integer", "type": "enum:9"}  # NumericType UNKNOWN..FLOAT64
ENTITY = {"timestamp": TIME, "frame_id": "string", "id": "string", "lifetime": TIME, "frame_locked": "boolean",
          "metadata": [{"key": "string", "value": "string"}],
          "cubes": [{"pose": POSE, "size": VEC3, "color": COLOR}],
          "cylinders": [{"pose": POSE, "size": VEC3, "bottom_scale": "number", "top_scale": "number",
                         "color": COLOR}],
          "texts": [{"pose": POSE, "billboard": "boolean", "font_size": "number", "scale_invariant": "boolean",
                     "color": COLOR, "text": "string"}]}
# SceneEntity's other primitive arrays: Foxglove's schema requires them; palpate writes them empty
ENTITY_UNUSED = {"arrows", "spheres", "lines", "triangles", "models"}
ENTITY |= {k: ["object"] for k in ENTITY_UNUSED}
FOXGLOVE = {
    "foxglove.RawImage": {"timestamp": TIME, "frame_id": "string", "width": "integer", "height": "integer",
                          "encoding": "string", "step": "integer", "data": "string"},
    "foxglove.FrameTransform": {"timestamp": TIME, "parent_frame_id": "string", "child_frame_id": "string",
                                "translation": VEC3, "rotation": QUAT},
    "foxglove.Log": {"timestamp": TIME, "level": "enum:6", "message": "string", "name": "string", "file": "string",
                     "line": "integer"},
    "foxglove.Grid": {"timestamp": TIME, "frame_id": "string", "pose": POSE, "column_count": "integer",
                      "cell_size": VEC2, "row_stride": "integer", "cell_stride": "integer", "fields": [PACKED_FIELD],
                      "data": "string"},
    "foxglove.VoxelGrid": {"timestamp": TIME, "frame_id": "string", "pose": POSE, "row_count": "integer",
                           "column_count": "integer", "cell_size": VEC3, "slice_stride": "integer",
                           "row_stride": "integer", "cell_stride": "integer", "fields": [PACKED_FIELD],
                           "data": "string"},
    "foxglove.SceneUpdate": {"deletions": [{"timestamp": TIME, "type": "enum:2", "id": "string"}],
                             "entities": [ENTITY]},
}
# palpate's data messages: format 1's shapes
PALPATE = {
    "palpate.TaxelFrame": {"t": "number", "sensor_id": "string", "rows": "integer", "cols": "integer",
                           "sensel_area": "number", "counts": ["integer"]},
    "palpate.PoseSample": {"t": "number", "sensor_id": "string", "position": VEC3, "orientation": QUAT},
}


def _check_message(value, shape, where: str) -> None:
    """``value`` (decoded JSON) has exactly the fields of ``shape``, each of its JSON type."""
    if isinstance(shape, dict):
        assert isinstance(value, dict) and set(value) == set(shape), (where, sorted(value), sorted(shape))
        for key, sub in shape.items():
            _check_message(value[key], sub, f"{where}.{key}")
    elif isinstance(shape, list):
        assert isinstance(value, list), where
        for i, item in enumerate(value):
            _check_message(item, shape[0], f"{where}[{i}]")
    elif shape.startswith("enum:"):
        assert type(value) is int and 0 <= value < int(shape[5:]), (where, value)
    else:
        kinds = {"integer": (int,), "number": (int, float), "string": (str,), "boolean": (bool,)}[shape]
        assert type(value) in kinds, (where, value, shape)


def _schema_shape(schema: dict):
    """The field names and JSON types a JSON schema declares, in the form of FOXGLOVE."""
    if "oneOf" in schema:
        consts = [o["const"] for o in schema["oneOf"]]
        assert consts == list(range(len(consts)))
        return f"enum:{len(consts)}"
    if schema["type"] == "object" and "properties" in schema:
        return {k: _schema_shape(v) for k, v in schema["properties"].items()}
    if schema["type"] == "array":
        return [_schema_shape(schema["items"])]
    return schema["type"]


def _messages(path) -> list[tuple[str, str, dict]]:
    with open(path, "rb") as f:
        return [(ch.topic, s.name, json.loads(m.data)) for s, ch, m in make_reader(f).iter_messages()]


def _schemas(path) -> dict[str, dict]:
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    return {s.name: json.loads(s.data) for s in summary.schemas.values()}


@pytest.fixture(scope="module")
def run_recording(tmp_path_factory) -> Path:
    from palpate.core.session.run import run_scenario

    out = tmp_path_factory.mktemp("run")
    raw = tomllib.loads(SMALL)
    raw["outputs"] = {"render_3d": False, "haptic_material": False, "figures": False}
    run_scenario(parse_scenario(raw, "small.toml"), out, record=out / "run.mcap")
    return out / "run.mcap"


@pytest.fixture(scope="module")
def voxel_recording(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("voxel") / "voxel.mcap"
    geometry = MapGeometry("voxel", ("soft", "hard"), (0.0, 0.0), 0.01, (3, 2, 4), z_top=0.04)
    p = np.random.default_rng(5).dirichlet(np.ones(2), size=(3, 2, 4))
    with RecordingWriter(path, {}) as w:
        w.write_map(1.0, "block", p, p[..., 0] > 0.5, geometry, 0.04)
    return path


def test_every_foxglove_message_of_a_run_has_exactly_foxgloves_fields(run_recording, voxel_recording):
    msgs = _messages(run_recording) + _messages(voxel_recording)
    seen = {schema for _, schema, _ in msgs if schema.startswith("foxglove.")}
    assert seen == set(FOXGLOVE)  # a run writes every one of them (the voxel map from its own file)
    for topic, schema, msg in msgs:
        if schema.startswith("foxglove."):
            _check_message(msg, FOXGLOVE[schema], topic)
    # the views sit on the topics Foxglove panels are pointed at, the data on palpate's own
    by_topic = {topic: schema for topic, schema, _ in msgs}
    assert by_topic["/taxels/taxels"] == "foxglove.RawImage" and by_topic["/pose/pose"] == "foxglove.FrameTransform"
    assert by_topic["/annotations"] == "foxglove.Log" and by_topic["/tf/taxels"] == "foxglove.FrameTransform"
    assert by_topic["/palpate/taxels/taxels"] == "palpate.TaxelFrame"
    assert by_topic["/palpate/pose/pose"] == "palpate.PoseSample"
    assert by_topic["/palpate/annotations"] == "palpate.Annotation"


def test_every_schema_written_under_a_foxglove_name_lists_exactly_foxgloves_fields(run_recording, voxel_recording):
    schemas = {**_schemas(run_recording), **_schemas(voxel_recording)}
    assert {name for name in schemas if name.startswith("foxglove.")} == set(FOXGLOVE)
    for name, reference in FOXGLOVE.items():
        assert schemas[name]["type"] == "object" and schemas[name]["title"] == name
        assert _schema_shape(schemas[name]) == reference, name
        assert set(schemas[name]["required"]) == set(reference), name
    scene = [m for _, schema, m in _messages(run_recording) if schema == "foxglove.SceneUpdate"]
    assert scene and all(e[k] == [] for m in scene for e in m["entities"] for k in ENTITY_UNUSED)
    assert schemas["foxglove.Log"]["properties"]["level"]["oneOf"][2]["title"] == "INFO"
    # palpate's data schemas describe exactly what their messages hold
    for name, reference in PALPATE.items():
        assert _schema_shape(schemas[name]) == reference, name
    msgs = _messages(run_recording)
    for topic, schema, msg in msgs:
        if schema in PALPATE:
            _check_message(msg, PALPATE[schema], topic)
        elif schema == "palpate.Annotation":
            assert set(msg) == {"t", "kind", "data"} and set(schemas[schema]["properties"]) == set(msg)


def test_the_palpate_channels_round_trip_frames_poses_and_annotations_bit_for_bit(tmp_path):
    rng = np.random.default_rng(11)
    # times a timestamp in ns cannot hold: an arbitrary float (its last bits) must come back as it went in
    times = np.cumsum(rng.random(40)) + 0.1 + 0.2
    frames = [TaxelFrame(float(t), rng.integers(0, 256, (3, 5), dtype=np.uint8), float(1e-5 * (1 + rng.random())),
                         "pad") for t in times]
    poses = [PoseSample(float(t) + 1e-13, rng.normal(scale=0.05, size=3), rng.normal(size=4), "tip")
             for t in times]
    notes = [(float(t), "press", {"phase": "exploration", "k": i, "target_m": [float(x) for x in rng.random(2)]})
             for i, t in enumerate(times[::10])]
    path = tmp_path / "rec.mcap"
    with RecordingWriter(path, {"scenario": "v3"}) as w:
        for f, p in zip(frames, poses, strict=True):
            w.write_taxel(f)
            w.write_pose(p)
        for t, kind, data in notes:
            w.write_annotation(t, kind, data)
    assert any(round(f.t * 1e9) / 1e9 != f.t for f in frames)  # the ns timestamp alone would lose them
    rec = read_recording(path)
    assert len(rec.frames) == len(frames) and len(rec.poses) == len(poses)
    for a, b in zip(rec.frames, frames, strict=True):
        assert a.t == b.t and a.sensel_area == b.sensel_area and a.sensor_id == "pad"
        assert a.counts.dtype == np.uint8 and np.array_equal(a.counts, b.counts)
    for a, b in zip(rec.poses, poses, strict=True):
        assert a.t == b.t and a.position.tobytes() == b.position.tobytes()
        assert a.quaternion.tobytes() == b.quaternion.tobytes()
    assert [(a.t, a.kind, a.data) for a in rec.annotations] == notes
    with open(path, "rb") as f:
        (meta,) = [m for m in make_reader(f).iter_metadata() if m.name == "palpate"]
    assert meta.metadata["format_version"] == "3"


def _raw(path: Path, channel_first: bool, version: str, topic: str, schema: str, messages: list[dict]) -> None:
    """A recording written record by record (no chunks), its channel before or after the metadata record."""
    with open(path, "wb") as f:
        w = Writer(f, use_chunking=False)
        w.start()
        if not channel_first:
            w.add_metadata("palpate", {"format_version": version})
        cid = w.register_channel(topic, "json", w.register_schema(schema, "jsonschema", b"{}"))
        if channel_first:
            w.add_metadata("palpate", {"format_version": version})
        for i, m in enumerate(messages):
            w.add_message(cid, log_time=i, data=json.dumps(m).encode(), publish_time=i)
        w.finish()


FRAME_V1 = {"t": 0.5, "sensor_id": "pad", "rows": 1, "cols": 2, "sensel_area": 1e-5, "counts": [3, 4]}


def test_the_reader_picks_decoders_by_the_files_format_version(tmp_path):
    path = tmp_path / "r.mcap"
    # format 3: a foxglove.* view is skipped, even one that holds nothing palpate could read
    _raw(path, False, "3", "/taxels/pad", "foxglove.RawImage", [{"width": "garbage"}])
    assert read_recording(path).frames == []
    # formats 1 and 2 read the same topics as data
    _raw(path, False, "2", "/taxels/pad", "foxglove.RawImage", [{"width": "garbage"}])
    with pytest.raises(RecordingError, match=r"/taxels/pad message 0: missing field 'height'"):
        read_recording(path)
    _raw(path, False, "1", "/taxels/pad", "palpate.TaxelFrame", [FRAME_V1])
    assert [f.counts.tolist() for f in read_recording(path).frames] == [[[3, 4]]]
    # format 3's data channel
    _raw(path, False, "3", "/palpate/taxels/pad", "palpate.TaxelFrame", [FRAME_V1])
    (frame,) = read_recording(path).frames
    assert frame.t == 0.5 and frame.counts.tolist() == [[3, 4]]
    # a channel before the metadata record is read as formats 1 and 2 read it
    _raw(path, True, "3", "/taxels/pad", "palpate.TaxelFrame", [FRAME_V1])
    assert len(read_recording(path).frames) == 1
    _raw(path, False, "3", "/taxels/pad", "palpate.TaxelFrame", [FRAME_V1])
    assert read_recording(path).frames == []


def test_a_bad_message_on_a_palpate_channel_names_the_topic_index_and_field(tmp_path):
    path = tmp_path / "bad.mcap"
    bad = {k: v for k, v in FRAME_V1.items() if k != "sensel_area"}
    _raw(path, False, "3", "/palpate/taxels/pad", "palpate.TaxelFrame", [FRAME_V1, bad])
    with pytest.raises(RecordingError, match=r"bad.mcap: /palpate/taxels/pad message 1: missing field 'sensel_area'"):
        read_recording(path)
    pose = {"t": 0.1, "sensor_id": "tip", "position": {"x": 0.0, "y": 0.0, "z": 1e300},
            "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}}
    _raw(path, False, "3", "/palpate/pose/tip", "palpate.PoseSample", [pose])
    with pytest.raises(RecordingError, match=r"/palpate/pose/tip message 0: field 'position.z'"):
        read_recording(path)


def test_the_live_view_is_sent_what_the_file_holds(tmp_path):
    sent = []

    class Sink:
        def publish(self, topic, schema_name, schema, log_time, data) -> None:
            sent.append((topic, schema_name, json.loads(schema), log_time, json.loads(data)))

    path = tmp_path / "both.mcap"
    with RecordingWriter(path, {}, live=Sink(), pad_offset=(0.0, 0.0, -0.008)) as w:
        w.write_pose(PoseSample(0.25, [0.01, 0.02, 0.05], sensor_id="tip"))
        w.write_taxel(TaxelFrame(0.25, np.arange(16, dtype=np.uint8).reshape(4, 4), 1e-5, "pad"))
        w.write_annotation(0.3, "press", {"phase": "exploration"})
    with open(path, "rb") as f:
        written = [(c.topic, s.name, json.loads(s.data), m.log_time, json.loads(m.data))
                   for s, c, m in make_reader(f).iter_messages(log_time_order=False)]
    assert sent == written
    assert [topic for topic, *_ in sent] == ["/palpate/pose/tip", "/pose/tip", "/palpate/taxels/pad", "/taxels/pad",
                                             "/tf/pad", "/palpate/annotations", "/annotations"]
