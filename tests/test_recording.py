"""MCAP recordings: exact round trip, metadata, crash safety under SIGKILL, truncated/corrupt files, validation."""

from __future__ import annotations

import base64
import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from mcap.records import Chunk, Footer
from mcap.stream_reader import StreamReader, breakup_chunk
from mcap.writer import Writer

from palpate.core.errors import RecordingError, ValidationError
from palpate.core.io.mcap_reader import read_recording
from palpate.core.io.mcap_writer import RecordingWriter
from palpate.core.io.recording import Annotation, recording_to_press_recording
from palpate.core.perception.streams import PoseSample, TaxelFrame

META = {"scenario": {"name": "three_pads", "seed": 7, "depth_m": 0.004}, "sources": ["sim"], "note": None}


def _write_example(path, rng, n=60, chunk_size=512):
    frames = [TaxelFrame(0.01 * i + 1e-7 * rng.random(), rng.integers(0, 256, (4, 4), dtype=np.uint8), 2.6e-5, s)
              for i in range(n) for s in ("index", "thumb")]
    poses = [PoseSample(0.004 * i, rng.normal(size=3), rng.normal(size=4), "tip") for i in range(n)]
    joints = [(0.02 * i, ["mcp", "pip"], rng.normal(size=2), rng.normal(size=2), rng.normal(size=2))
              for i in range(n // 2)]
    truth = [(0.01 * i, float(rng.random()), 1e-3 * rng.random()) for i in range(n)]
    with RecordingWriter(path, META, chunk_size=chunk_size) as w:
        for i in range(n):
            w.write_taxel(frames[2 * i])
            w.write_taxel(frames[2 * i + 1])
            w.write_pose(poses[i])
            if i < len(joints):
                w.write_joint_state(*joints[i])
            w.write_truth(*truth[i], material="silicone_A")
        w.write_annotation(0.1, "press_start", {"label": "Region_3", "target": [0.01, 0.02]})
        w.write_annotation(0.5, "press_end", {})
    return frames, poses, joints, truth


def test_round_trip_every_field_equal(tmp_path, rng):
    path = tmp_path / "rec.mcap"
    frames, poses, joints, truth = _write_example(path, rng)
    rec = read_recording(path)
    assert not rec.salvaged
    assert rec.metadata == META
    assert len(rec.frames) == len(frames)
    for a, b in zip(rec.frames, frames, strict=False):
        assert a.t == b.t and a.sensor_id == b.sensor_id and a.sensel_area == b.sensel_area
        assert a.counts.dtype == np.uint8 and np.array_equal(a.counts, b.counts)
    for a, b in zip(rec.poses, poses, strict=True):
        assert a.t == b.t and a.sensor_id == b.sensor_id
        assert np.array_equal(a.position, b.position) and np.array_equal(a.quaternion, b.quaternion)
    for a, (t, names, p, v, c) in zip(rec.joints, joints, strict=True):
        assert a.t == t and a.names == tuple(names)
        assert np.array_equal(a.position, p) and np.array_equal(a.velocity, v) and np.array_equal(a.current, c)
    assert rec.annotations == [Annotation(0.1, "press_start", {"label": "Region_3", "target": [0.01, 0.02]}),
                               Annotation(0.5, "press_end", {})]
    t, force, ind = (np.array(x) for x in zip(*truth, strict=True))
    assert np.array_equal(rec.truth.t, t) and np.array_equal(rec.truth.force, force)
    assert np.array_equal(rec.truth.indentation, ind) and rec.truth.material == "silicone_A"


def _is_data(topic: str) -> bool:
    """A channel replay reads (the others are views for Foxglove)."""
    return topic.startswith("/palpate/") or topic in ("/truth", "/joints")


def test_versions_and_foxglove_readable_channels(tmp_path, rng):
    path = tmp_path / "rec.mcap"
    frames, poses, *_ = _write_example(path, rng, n=5)
    rec = read_recording(path)
    assert rec.versions["numpy"] == np.__version__ and "palpate" in rec.versions
    with open(path, "rb") as f:
        recs = list(StreamReader(f).records)
    channels = {r.topic: r for r in recs if type(r).__name__ == "Channel"}
    schemas = {r.id: r for r in recs if type(r).__name__ == "Schema"}
    # palpate's data on its own channels; Foxglove's well-known schemas for the views, so its panels know what to draw
    expected = {"/palpate/taxels/index": "palpate.TaxelFrame", "/palpate/taxels/thumb": "palpate.TaxelFrame",
                "/palpate/pose/tip": "palpate.PoseSample", "/palpate/annotations": "palpate.Annotation",
                "/truth": "palpate.GroundTruthSeries", "/joints": "palpate.JointState",
                "/taxels/index": "foxglove.RawImage", "/taxels/thumb": "foxglove.RawImage",
                "/pose/tip": "foxglove.FrameTransform", "/annotations": "foxglove.Log"}
    assert {topic: schemas[ch.schema_id].name for topic, ch in channels.items()} == expected
    for ch in channels.values():
        schema = schemas[ch.schema_id]
        assert ch.message_encoding == "json"
        assert schema.encoding == "jsonschema" and json.loads(schema.data)["type"] == "object"
    topic_of = {ch.id: topic for topic, ch in channels.items()}
    msgs = [(topic_of[r.channel_id], r, json.loads(r.data)) for r in recs if type(r).__name__ == "Message"]
    for topic, m, body in msgs:
        if _is_data(topic):
            t = body["t"][0] if isinstance(body["t"], list) else body["t"]
            assert m.log_time == round(t * 1e9)
        else:
            assert body["timestamp"]["sec"] * 10**9 + body["timestamp"]["nsec"] == m.log_time
    # each view carries the data message written just before it: the same counts, the same pose
    images = [b for topic, _, b in msgs if topic == "/taxels/index"]
    data = [b for topic, _, b in msgs if topic == "/palpate/taxels/index"]
    assert len(images) == len(data) == 5
    for image, frame, written in zip(images, data, frames[::2], strict=True):
        assert image["encoding"] == "mono8" and image["frame_id"] == "index"
        assert list(base64.b64decode(image["data"])) == frame["counts"] == written.counts.reshape(-1).tolist()
    tfs = [b for topic, _, b in msgs if topic == "/pose/tip"]
    for tf, written in zip(tfs, poses, strict=True):
        assert tf["parent_frame_id"] == "world" and tf["child_frame_id"] == "tip"
        assert [tf["translation"][k] for k in "xyz"] == written.position.tolist()
        assert [tf["rotation"][k] for k in "wxyz"] == written.quaternion.tolist()


def test_press_recording_picks_one_pad(tmp_path, rng):
    path = tmp_path / "rec.mcap"
    _write_example(path, rng, n=10)
    rec = read_recording(path)
    with pytest.raises(ValidationError, match="several taxel sensors"):
        recording_to_press_recording(rec)
    pr = recording_to_press_recording(rec, taxel_sensor="thumb")
    assert len(pr.frames) == 10 and {f.sensor_id for f in pr.frames} == {"thumb"}
    assert len(pr.poses) == 10 and pr.truth is rec.truth
    assert pr.meta["scenario"] == META["scenario"] and pr.meta["annotations"][0]["kind"] == "press_start"
    with pytest.raises(ValidationError, match="no taxel sensor 'ring'"):
        recording_to_press_recording(rec, taxel_sensor="ring")


def test_writer_rejects_bad_input(tmp_path):
    with pytest.raises(ValidationError, match="not JSON-serialisable"):
        RecordingWriter(tmp_path / "a.mcap", {"scenario": object()})
    with RecordingWriter(tmp_path / "b.mcap", {}) as w:
        with pytest.raises(ValidationError, match="t must be a finite time >= 0"):
            w.write_taxel(TaxelFrame(-1.0, np.zeros((4, 4), np.uint8), 1e-5))
        with pytest.raises(ValidationError, match="cannot name a topic"):
            w.write_pose(PoseSample(0.0, [0, 0, 0], sensor_id="a b"))
        with pytest.raises(ValidationError, match="force and indentation must be finite"):
            w.write_truth(0.0, float("nan"), 0.0)
        with pytest.raises(ValidationError, match="one value per joint"):
            w.write_joint_state(0.0, ["a", "b"], [1.0], [0.0, 0.0], [0.0, 0.0])
    with pytest.raises(RecordingError, match="after the recording was closed"):
        w.write_annotation(0.0, "late", {})


def _chunk_message_ends(path, data_only=False):
    """(start byte, end byte, cumulative messages) of each chunk, read independently with mcap's own records; with
    ``data_only``, only messages on the channels replay reads."""
    ends, total, topics = [], 0, {}
    with open(path, "rb") as f:
        records = StreamReader(f, emit_chunks=True).records
        while True:
            start = f.tell()
            r = next(records)
            if isinstance(r, Chunk):
                for rr in breakup_chunk(r):
                    if type(rr).__name__ == "Channel":
                        topics[rr.id] = rr.topic
                    elif type(rr).__name__ == "Message":
                        total += not data_only or _is_data(topics[rr.channel_id])
                ends.append((start, f.tell(), total))
            if isinstance(r, Footer):
                return ends


@pytest.mark.parametrize("fraction", [0.3, 0.75, 0.999])
def test_truncated_file_error_and_salvage(tmp_path, rng, fraction):
    full = tmp_path / "full.mcap"
    frames, *_ = _write_example(full, rng)
    data = full.read_bytes()
    cut = int(len(data) * fraction)
    path = tmp_path / "cut.mcap"
    path.write_bytes(data[:cut])
    # Expected salvage: every message of each chunk whose record (and message indexes) ended before the cut.
    expected = max([n for _, end, n in _chunk_message_ends(full) if end <= cut], default=0)
    with pytest.raises(RecordingError, match="truncated") as err:
        read_recording(path)
    assert err.value.salvaged == expected > 0
    assert f"{expected} messages" in str(err.value)
    rec = read_recording(path, salvage=True)
    assert rec.salvaged and rec.metadata == META
    got = len(rec.frames) + len(rec.poses) + len(rec.joints) + len(rec.annotations) + len(rec.truth.t)
    assert got == max([n for _, end, n in _chunk_message_ends(full, data_only=True) if end <= cut], default=0)
    for a, b in zip(rec.frames, frames, strict=False):
        assert a.t == b.t and np.array_equal(a.counts, b.counts)


def test_corrupt_chunk_is_reported_with_salvage(tmp_path, rng):
    path = tmp_path / "rec.mcap"
    _write_example(path, rng)
    ends = _chunk_message_ends(path)
    data = bytearray(path.read_bytes())
    start, end, _ = ends[2]
    data[(start + end) // 2] ^= 0xFF  # inside the third chunk's compressed payload
    path.write_bytes(bytes(data))
    with pytest.raises(RecordingError, match="corrupt") as err:
        read_recording(path)
    assert err.value.salvaged == ends[1][2]
    assert read_recording(path, salvage=True).salvaged


@pytest.mark.parametrize("content", [b"", b"hello world, not mcap at all\n" * 10])
def test_not_mcap(tmp_path, content):
    path = tmp_path / "x.mcap"
    path.write_bytes(content)
    with pytest.raises(RecordingError, match="not a readable palpate recording"):
        read_recording(path)
    with pytest.raises(RecordingError, match="cannot open"):
        read_recording(tmp_path / "missing.mcap")


def _raw_mcap(path, messages, metadata=True):
    with open(path, "wb") as f:
        w = Writer(f)
        w.start()
        if metadata:
            w.add_metadata("palpate", {"format_version": "1"})
        sid = w.register_schema("palpate.TaxelFrame", "jsonschema", b"{}")
        cid = w.register_channel("/taxels/pad", "json", sid)
        for i, m in enumerate(messages):
            w.add_message(cid, log_time=i, data=json.dumps(m).encode(), publish_time=i)
        w.finish()


def test_message_missing_field_names_topic_and_index(tmp_path):
    good = {"t": 0.0, "sensor_id": "pad", "rows": 1, "cols": 2, "sensel_area": 1e-5, "counts": [1, 2]}
    bad = {k: v for k, v in good.items() if k != "counts"}
    path = tmp_path / "m.mcap"
    _raw_mcap(path, [good, good, bad])
    with pytest.raises(RecordingError, match=r"/taxels/pad message 2: missing field 'counts'"):
        read_recording(path)
    for bad, pattern in [({**good, "counts": [1, 300]}, "integers 0..255"), ({**good, "counts": [1]}, "rows\\*cols"),
                         ({**good, "t": "zero"}, "'t' must be a number"), ({**good, "counts": [1.5, 2]}, "0..255")]:
        _raw_mcap(path, [bad])
        with pytest.raises(RecordingError, match=r"/taxels/pad message 0: .*" + pattern):
            read_recording(path)
    _raw_mcap(path, [good], metadata=False)
    with pytest.raises(RecordingError, match="not a palpate recording"):
        read_recording(path)


WRITER = """
import sys, numpy as np
from palpate.core.io.mcap_writer import RecordingWriter
from palpate.core.perception.streams import TaxelFrame
w = RecordingWriter(sys.argv[1], {"scenario": "crash"}, chunk_size=300, flush_interval=1e9)
i = 0
while True:
    w.write_taxel(TaxelFrame(0.01 * i, np.full((4, 4), i % 256, np.uint8), 1e-5, "pad"))
    i += 1
    if i == 200:
        print("running", flush=True)
"""


def test_sigkill_mid_write_keeps_complete_chunks(tmp_path):
    path = tmp_path / "crash.mcap"
    proc = subprocess.Popen([sys.executable, "-c", WRITER, str(path)], stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline().strip() == "running"
        time.sleep(0.05)  # let it write on, so the kill lands mid-loop at an arbitrary point
    finally:
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
        proc.stdout.close()
    assert proc.returncode == -signal.SIGKILL
    with pytest.raises(RecordingError, match="truncated") as err:
        read_recording(path)
    rec = read_recording(path, salvage=True)
    n = len(rec.frames)
    assert n >= 190  # all but the unfinished chunk of the first 200 frames at least
    # each frame is two messages, its data then its image: a chunk may end between the two
    assert err.value.salvaged in (2 * n - 1, 2 * n)
    assert rec.metadata == {"scenario": "crash"}
    t = np.array([f.t for f in rec.frames])
    assert np.array_equal(t, 0.01 * np.arange(n))
    assert all(np.all(f.counts == i % 256) for i, f in enumerate(rec.frames))


def test_every_cut_point_reads_back_a_prefix(tmp_path, rng):
    full = tmp_path / "full.mcap"
    frames, *_ = _write_example(full, rng, n=12, chunk_size=256)
    data = full.read_bytes()
    ends = _chunk_message_ends(full)
    path = tmp_path / "cut.mcap"
    for cut in range(0, len(data) - 1, 173):  # a prime stride lands at every kind of offset within records
        path.write_bytes(data[:cut])
        expected = max([n for _, end, n in ends if end <= cut], default=0)
        with pytest.raises(RecordingError, match="truncated|not a readable") as err:
            read_recording(path)
        assert err.value.salvaged == expected, cut
        if "recording is truncated" in str(err.value):
            rec = read_recording(path, salvage=True)
            assert rec.salvaged and rec.metadata == META
            assert all(a.t == b.t and np.array_equal(a.counts, b.counts)
                       for a, b in zip(rec.frames, frames, strict=False))
