"""Recording formats: format-1 (palpate.* schemas) and format-2 (Foxglove schemas with palpate's extra fields)
recordings still replay to their run's maps; the Foxglove views hold what they claim (the map after every press,
the objects, log lines); a run's recording is complete before its figures are drawn; a truncated recording
replays with --salvage to the run's own presses."""

from __future__ import annotations

import base64
import json
import tomllib
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader

from palpate.core.cli import main
from palpate.core.io.figures import palette
from palpate.core.io.mcap_reader import read_recording
from palpate.core.io.mcap_writer import RecordingWriter
from palpate.core.mapping.grids import Grid2D
from palpate.core.perception.memory import HapticMemory
from palpate.core.session.replay import replay_recording
from palpate.core.world.scenario_file import parse_scenario

V1 = Path(__file__).parent / "data" / "recording_v1"
V2 = Path(__file__).parent / "data" / "recording_v2"
SMALL = (Path(__file__).parent / "test_run.py").read_text().split('SMALL = """', 1)[1].split('"""', 1)[0]


@pytest.fixture(scope="module")
def small_run(tmp_path_factory):
    from palpate.core.session.run import run_scenario

    out = tmp_path_factory.mktemp("run")
    raw = tomllib.loads(SMALL)
    raw["outputs"] = {"render_3d": False, "haptic_material": False, "figures": False}
    summary = run_scenario(parse_scenario(raw, "small.toml"), out, record=out / "run.mcap")
    return summary, out


def _replays_to_the_v1_maps(recording: Path, out: Path) -> None:
    replay_recording(recording, HapticMemory.load(V1 / "memory.json"), out, figures=False)
    for name in ("slab", "slab_postprocessed"):
        ran, replayed = Grid2D.load(V1 / f"{name}.npz"), Grid2D.load(out / "maps" / f"{name}.npz")
        np.testing.assert_array_equal(replayed.explored, ran.explored)
        np.testing.assert_allclose(replayed.probabilities, ran.probabilities, rtol=0, atol=1e-12)


def test_format_1_recording_still_replays_to_the_maps_its_run_built(tmp_path):
    rec = read_recording(V1 / "run.mcap")
    assert len(rec.frames) > 50 and len(rec.poses) > 20 and rec.truth is not None
    assert [a.data["phase"] for a in rec.annotations] == ["exploration"] * 4
    _replays_to_the_v1_maps(V1 / "run.mcap", tmp_path)


def test_format_2_recording_still_reads_and_replays_to_the_maps_of_the_same_run(tmp_path):
    with open(V2 / "run.mcap", "rb") as f:
        reader = make_reader(f)
        assert reader.get_summary() is not None
        (meta,) = [m for m in reader.iter_metadata() if m.name == "palpate"]
        schemas = {s.name for s in reader.get_summary().schemas.values()}
    assert meta.metadata["format_version"] == "2"
    assert {"foxglove.RawImage", "foxglove.FrameTransform", "foxglove.Log"} <= schemas
    assert not any(name in schemas for name in ("palpate.TaxelFrame", "palpate.PoseSample", "palpate.Annotation"))
    v1, v2 = read_recording(V1 / "run.mcap"), read_recording(V2 / "run.mcap")
    assert v2.metadata == v1.metadata and v2.annotations == v1.annotations
    assert all(a.t == b.t and a.sensor_id == b.sensor_id and np.array_equal(a.counts, b.counts)
               and a.sensel_area == b.sensel_area for a, b in zip(v2.frames, v1.frames, strict=True))
    assert all(a.t == b.t and np.array_equal(a.position, b.position) and np.array_equal(a.quaternion, b.quaternion)
               for a, b in zip(v2.poses, v1.poses, strict=True))
    assert np.array_equal(v2.truth.t, v1.truth.t) and np.array_equal(v2.truth.force, v1.truth.force)
    _replays_to_the_v1_maps(V2 / "run.mcap", tmp_path)


def test_format_1_and_format_3_of_the_same_streams_replay_identically(tmp_path):
    old = read_recording(V1 / "run.mcap")
    new = tmp_path / "v3.mcap"
    with RecordingWriter(new, old.metadata) as w:
        for a in old.annotations:
            w.write_annotation(a.t, a.kind, a.data)
        for f in old.frames:
            w.write_taxel(f)
        for p in old.poses:
            w.write_pose(p)
        w.write_truth(old.truth.t, old.truth.force, old.truth.indentation, old.truth.material)
    again = read_recording(new)
    assert again.metadata == old.metadata and again.annotations == old.annotations
    assert all(a.t == b.t and np.array_equal(a.counts, b.counts) and a.sensel_area == b.sensel_area
               for a, b in zip(again.frames, old.frames, strict=True))
    assert all(a.t == b.t and np.array_equal(a.position, b.position) and np.array_equal(a.quaternion, b.quaternion)
               for a, b in zip(again.poses, old.poses, strict=True))
    assert np.array_equal(again.truth.t, old.truth.t) and np.array_equal(again.truth.force, old.truth.force)
    memory = HapticMemory.load(V1 / "memory.json")
    replay_recording(V1 / "run.mcap", memory, tmp_path / "a", figures=False)
    replay_recording(new, memory, tmp_path / "b", figures=False)
    for name in ("slab", "slab_postprocessed"):
        a, b = (Grid2D.load(tmp_path / d / "maps" / f"{name}.npz") for d in ("a", "b"))
        np.testing.assert_array_equal(a.probabilities, b.probabilities)


def _messages(path) -> list[tuple[str, str, dict]]:
    with open(path, "rb") as f:
        return [(ch.topic, schema.name, json.loads(m.data)) for schema, ch, m in make_reader(f).iter_messages()]


def test_the_map_after_every_press_is_a_foxglove_grid_of_the_run_map(small_run):
    summary, out = small_run
    msgs = _messages(out / "run.mcap")
    maps = [m for topic, schema, m in msgs if topic == "/map/slab"]
    assert {schema for topic, schema, _ in msgs if topic == "/map/slab"} == {"foxglove.Grid"}
    assert len(maps) == summary["objects"][0]["presses"] == 4
    final = maps[-1]
    grid = Grid2D.load(out / "maps" / "slab.npz")
    ny, nx, m = grid.probabilities.shape
    assert final["column_count"] == nx and final["row_stride"] == nx * final["cell_stride"]
    fields = {f["name"]: f for f in final["fields"]}
    assert {"red", "green", "blue", "alpha", "P_soft", "P_medium", "P_hard", "entropy", "explored"} == set(fields)
    dtype = np.dtype({"names": list(fields), "formats": ["u1" if f["type"] == 1 else "<f4" for f in fields.values()],
                      "offsets": [f["offset"] for f in fields.values()], "itemsize": final["cell_stride"]})
    cells = np.frombuffer(base64.b64decode(final["data"]), dtype=dtype).reshape(ny, nx)
    for j, name in enumerate(("soft", "medium", "hard")):
        np.testing.assert_allclose(cells[f"P_{name}"], grid.probabilities[..., j], rtol=1e-6)
    np.testing.assert_array_equal(cells["explored"].astype(bool), grid.explored)
    # the colours the figures use: each material's palette colour weighted by its probability
    rgb = np.clip(grid.probabilities @ palette(3), 0, 1)
    for i, channel in enumerate(("red", "green", "blue")):
        np.testing.assert_allclose(cells[channel], np.round(255 * rgb[..., i]), atol=1)
    pose = final["pose"]["position"]
    geo = summary["objects"][0]["grid"]
    assert (pose["x"], pose["y"]) == tuple(geo["origin_m"]) and pose["z"] == pytest.approx(0.040, abs=1e-3)


def test_scene_and_log_lines(small_run):
    _, out = small_run
    msgs = _messages(out / "run.mcap")
    (scene,) = [m for topic, _, m in msgs if topic == "/scene"]
    (entity,) = scene["entities"]
    cube = entity["cubes"][0]
    assert entity["id"] == "object/slab" and entity["texts"][0]["text"] == "slab"
    assert (cube["size"]["x"], cube["size"]["y"], cube["size"]["z"]) == pytest.approx((0.06, 0.04, 0.04))
    events = [m for topic, _, m in msgs if topic == "/palpate/annotations"]
    logs = [m for topic, schema, m in msgs if topic == "/annotations" and schema == "foxglove.Log"]
    assert len(logs) == len(events) == 19  # one Log line per annotation
    explore = [i for i, m in enumerate(events) if m["kind"] == "press" and m["data"]["phase"] == "exploration"]
    assert len(explore) == 4 and all(logs[i]["message"].startswith("press: phase=exploration object=slab")
                                     and logs[i]["level"] == 2 for i in explore)


def test_the_recording_is_complete_when_exploration_ends(tmp_path, monkeypatch):
    from palpate.core.session import run as run_module

    seen = []
    write_maps = run_module.write_maps

    def maps(*args):  # the first thing after exploration, before the wait for figures
        seen.append(read_recording(tmp_path / "run.mcap"))  # raises if the file were still open or truncated
        return write_maps(*args)

    monkeypatch.setattr(run_module, "write_maps", maps)
    raw = tomllib.loads(SMALL)
    raw["outputs"] = {"render_3d": False, "haptic_material": False}
    run_module.run_scenario(parse_scenario(raw, "small.toml"), tmp_path / "out", record=tmp_path / "run.mcap")
    (rec,) = seen
    assert not rec.salvaged and sum(a.kind == "press" for a in rec.annotations) == 19


def test_a_truncated_recording_replays_with_salvage(small_run, tmp_path, capsys):
    summary, out = small_run
    data = (out / "run.mcap").read_bytes()
    cut = tmp_path / "cut.mcap"
    n_ran = summary["objects"][0]["presses"]
    for end in range(len(data) - 1, 0, -(len(data) // 60)):  # cut where some exploration presses are complete
        cut.write_bytes(data[:end])
        rec = read_recording(cut, salvage=True)
        last = min(rec.frames[-1].t, rec.poses[-1].t)
        complete = [a for a in rec.annotations if a.data["phase"] == "exploration" and a.data["t_end"] <= last]
        if 1 <= len(complete) < n_ran:
            break
    args = [str(cut), "--memory", str(out / "memory.json"), "--no-figures"]
    assert main(["replay", *args, "--out", str(tmp_path / "a")]) == 2
    assert "palpate replay --salvage" in capsys.readouterr().err
    assert main(["replay", *args, "--out", str(tmp_path / "b"), "--salvage", "--quiet"]) == 0
    replayed = json.loads((tmp_path / "b" / "summary.json").read_text())
    assert replayed["salvaged"] is True
    rows, ran = replayed["objects"][0]["per_press"], summary["objects"][0]["per_press"]
    assert 1 <= len(rows) < len(ran)  # the presses the damage cut off are left out, the others are the run's own
    for got, want in zip(rows, ran, strict=False):
        assert got["posterior"] == want["posterior"] and got["fit"] == want["fit"]
