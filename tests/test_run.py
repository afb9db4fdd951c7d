"""The run job end to end on a small analytic scenario: summary schema, outputs, determinism, replay."""

import json
import tomllib

import numpy as np
import pytest

from palpate.core.cli import main
from palpate.core.mapping.grids import Grid2D
from palpate.core.world.haptic_material import HapticMaterialMap
from palpate.core.world.scenario_file import parse_scenario

SMALL = """
[scenario]
name = "small"
seed = 3
fidelity = "analytic"

[[materials]]
name = "soft"
young_kpa = 20
[[materials]]
name = "medium"
young_kpa = 115
poisson = 0.45
[[materials]]
name = "hard"
young_kpa = 450
poisson = 0.4
[[materials]]
name = "foam"
young_kpa = 25
reference = false
like = "soft"

[fingertip]
pitch_mm = 2.5
sensel_mm = 2.2

[sensors.taxels]
gain_counts_per_kpa = 1.2

[training]
presses_per_material = 5
depth_mm = 5.0
max_force_n = 10.0

[exploration]
policy = "predefined"
presses_per_region = 2

[[objects]]
name = "slab"
size_mm = [60, 40, 40]
position_mm = [30, 20]
material = "foam"
regions = [[2, 2], [5, 3]]

[[objects.inclusions]]
material = "hard"
shape = "column"
center_mm = [45, 20]
size_mm = [20, 40]

[outputs]
render_3d = false
attainable_accuracy = true
"""


@pytest.fixture(scope="module")
def small_run(tmp_path_factory):
    from palpate.core.session.run import run_scenario

    out = tmp_path_factory.mktemp("run")
    scenario = parse_scenario(tomllib.loads(SMALL), "small.toml")
    summary = run_scenario(scenario, out, record=out / "run.mcap")
    return scenario, summary, out


def test_summary_follows_the_documented_schema(small_run):
    _, summary, out = small_run
    on_disk = json.loads((out / "summary.json").read_text())
    assert on_disk == json.loads(json.dumps(summary))
    assert summary["format"] == "palpate-run-summary" and summary["version"] == 1
    assert summary["materials"] == ["soft", "medium", "hard"]
    # the iteration limit solver warnings were counted against: left out of the scenario, MuJoCo's default
    assert summary["scenario"]["flex_iterations"] is None
    for key in ("scenario", "seed", "memory", "crossval", "training", "objects", "figures", "timing", "versions"):
        assert key in summary, key
    cv = summary["crossval"]
    assert np.asarray(cv["confusion"]).shape == (3, 3)
    np.testing.assert_allclose(np.asarray(cv["mean_posterior"]).sum(axis=1), 1.0, atol=1e-9)
    (obj,) = summary["objects"]
    assert obj["presses"] == 4 and len(obj["per_press"]) == 4
    assert len(obj["posterior_per_cycle"]) == 2 and len(obj["posterior_per_cycle"][0]) == 2
    for row in obj["per_press"]:
        assert {"k", "cell", "target_m", "location_m", "depth_m", "fit", "posterior", "mean_entropy",
                "accuracy_explored", "rejected"} <= set(row)
    assert set(obj["accuracy"]) == {"explored_before_postprocessing", "all_cells_before_postprocessing",
                                    "all_cells_after_postprocessing", "by_walls_after_postprocessing"}
    assert set(summary["timing"]) == {"training_s", "exploration_s", "attainable_accuracy_s", "maps_s", "figures_s"}
    cpu = summary["cpu"]
    assert set(cpu) == set(summary["timing"]) | {"presses", "per_press_s"}
    # every press counted: 3 materials x 5 training presses, 4 exploration presses, 24 for the ceiling (6 x 4 cells)
    assert cpu["presses"] == 15 + 4 + 24
    spent = cpu["training_s"] + cpu["exploration_s"] + cpu["attainable_accuracy_s"]
    assert cpu["per_press_s"] == pytest.approx(spent / 43, abs=1e-5) and cpu["per_press_s"] > 0


def test_summary_reports_calibration_and_attainable_accuracy(small_run):
    from palpate.core.mapping.calibration import DEFAULT_CALIBRATION

    scenario, summary, out = small_run
    assert summary["map_calibration"] == DEFAULT_CALIBRATION.to_dict() == scenario.exploration.calibration.to_dict()
    assert summary["map_postprocessing"] == {"extrapolation_passes": 1, "voxel_lateral": False}
    (obj,) = summary["objects"]
    cal = obj["calibration"]
    # every cell of the 6 x 4 map has a truth: counted, or left out because its top two materials tie
    assert cal["cells"] + cal["undecided_cells_left_out"] == 24 and cal["cells"] == sum(cal["count"])
    # the ECE recomputed from the reported bins
    count, conf, acc = (np.asarray(cal[k]) for k in ("count", "mean_confidence", "accuracy"))
    assert cal["ece"] == pytest.approx(float(np.sum(count * np.abs(acc - conf)) / count.sum()))
    assert summary["calibration"] == cal  # one object: the pooled table is its own
    ceiling = obj["attainable_accuracy"]
    # the predefined run pressed 4 cells; the ceiling pressed all 24 again and scored like the run
    assert ceiling["ceiling_presses"] == 24 and not ceiling["ceiling_is_this_run"]
    assert 0.5 < ceiling["ceiling"] <= 1.0
    acc_run = [r["accuracy_all_cells_postprocessed"] for r in obj["per_press"]]
    level = ceiling["level"] * ceiling["ceiling"]
    expected = next((k + 1 for k, a in enumerate(acc_run) if a >= level - 1e-12), None)
    assert ceiling["presses_to_level_of_ceiling"] == expected
    from palpate.core.cli.run import format_report

    text = format_report(summary, out)
    assert f"attainable accuracy (every column pressed once, same physics) {100 * ceiling['ceiling']:.0f}%" in text
    assert f"calibration error (ECE) of the post-processed map {cal['ece']:.3f} over {cal['cells']} cells" in text
    fine = obj["fine_map"]["area_accuracy"]["fine_map"]
    assert f"fine map (1 mm): {100 * fine:.0f}% of the area right" in text


def test_run_writes_every_output(small_run):
    _, summary, out = small_run
    assert (out / "memory.json").is_file()
    for name in ("slab.npz", "slab.json", "slab_postprocessed.npz", "slab_postprocessed.json"):
        assert (out / "maps" / name).is_file(), name
    for rel in summary["figures"]:
        assert (out / rel).stat().st_size > 1000, rel
    assert {"figures/training_series.png", "figures/interaction_profiles.png", "figures/slab_map.png",
            "figures/slab_entropy.png", "figures/exploration_progress.png"} <= set(summary["figures"])
    manifest = json.loads((out / "haptic_materials" / "slab" / "manifest.json").read_text())
    assert "rate_hardness" in manifest["maps"] and "kinetic_friction" in manifest["absent"]


def test_explored_regions_are_classified_as_their_material(small_run):
    _, summary, _ = small_run
    (obj,) = summary["objects"]
    final = np.asarray(obj["posterior_per_cycle"][-1])
    # region (2, 2) is foam (like soft), region (5, 3) lies in the hard column
    assert final[0].argmax() == 0 and final[1].argmax() == 2
    assert obj["accuracy"]["explored_before_postprocessing"] == 1.0
    ent = obj["mean_entropy_after_each_press"]
    assert ent[-1] < ent[0] and obj["mean_entropy_after_postprocessing"] < ent[-1]


def test_replay_reproduces_the_maps_exactly(small_run, tmp_path):
    _, _, out = small_run
    code = main(["replay", str(out / "run.mcap"), "--memory", str(out / "memory.json"), "--out", str(tmp_path),
                 "--quiet"])
    assert code == 0
    for name in ("slab", "slab_postprocessed"):
        ran = Grid2D.load(out / "maps" / f"{name}.npz")
        replayed = Grid2D.load(tmp_path / "maps" / f"{name}.npz")
        np.testing.assert_array_equal(replayed.probabilities, ran.probabilities)
        np.testing.assert_array_equal(replayed.explored, ran.explored)


def test_same_seed_same_summary(small_run, tmp_path):
    from palpate.core.session.run import run_scenario

    scenario, summary, _ = small_run
    again = run_scenario(scenario, tmp_path)
    assert again["objects"] == summary["objects"]
    assert again["crossval"] == summary["crossval"]


def test_bad_scenario_exits_2_naming_the_key(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text(SMALL.replace('fidelity = "analytic"', 'fidelity = "quantum"'))
    assert main(["run", str(bad), "--out", str(tmp_path / "o"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "bad.toml" in err and "scenario.fidelity" in err


def test_replay_of_a_recording_without_annotations_finds_every_press_and_reads_it_the_same(small_run, tmp_path):
    """The other replay path (a Tekscan import, a Liberty + finger session): no press annotations and no map
    geometry, so the whole stream is segmented. The run's recording stripped of its annotations and metadata
    must give back one press per recorded press, each where it was planned and read as the run read it."""
    from palpate.core.io.mcap_reader import read_recording
    from palpate.core.io.mcap_writer import RecordingWriter
    from palpate.core.perception.memory import HapticMemory
    from palpate.core.session.replay import replay_recording

    _, summary, out = small_run
    rec = read_recording(out / "run.mcap")
    plain = tmp_path / "plain.mcap"
    with RecordingWriter(plain, {"source": "test: annotations removed"}) as w:
        for f in rec.frames:
            w.write_taxel(f)
        for p in rec.poses:
            w.write_pose(p)
    assert read_recording(plain).annotations == []

    windows = [a for a in rec.annotations if a.kind == "press"]
    replayed = replay_recording(plain, HapticMemory.load(out / "memory.json"), tmp_path / "replay", figures=False)
    (obj,) = replayed["objects"]
    assert obj["name"] == "recording" and obj["presses"] == len(windows)
    rows = obj["per_press"]
    explore = [i for i, a in enumerate(windows) if a.data["phase"] == "exploration"]
    ran = summary["objects"][0]["per_press"]
    assert len(explore) == len(ran)
    for i, row in zip(explore, ran, strict=True):
        np.testing.assert_allclose(rows[i]["location_m"], row["target_m"], atol=2e-3)
        assert int(np.argmax(rows[i]["posterior"])) == int(np.argmax(row["posterior"]))
    grid = Grid2D.load(tmp_path / "replay" / "maps" / "recording.npz")
    assert grid.explored.sum() >= 2 and np.all(np.isfinite(grid.probabilities))


def test_run_writes_a_fine_map_and_replay_rebuilds_it_bit_for_bit(small_run, tmp_path):
    _, summary, out = small_run
    (obj,) = summary["objects"]
    fine = obj["fine_map"]
    assert fine["resolution_m"] == pytest.approx(0.001) and fine["presses_read"] == 4
    assert fine["sides_named_by"] == "modulus"  # the references' training presses were read too
    assert 0.0 <= fine["area_accuracy"]["fine_map"] <= 1.0
    assert "figures/slab_fine_map.png" in summary["figures"]
    with np.load(out / "maps" / "slab_fine.npz", allow_pickle=False) as ran:
        p = ran["probabilities"]
        assert p.shape == (40, 60, 3) and float(ran["resolution_m"]) == pytest.approx(0.001)
        np.testing.assert_allclose(p.sum(axis=-1), 1.0)
        assert list(ran["materials"]) == ["soft", "medium", "hard"]
        assert main(["replay", str(out / "run.mcap"), "--memory", str(out / "memory.json"), "--out", str(tmp_path),
                     "--quiet"]) == 0
        with np.load(tmp_path / "maps" / "slab_fine.npz", allow_pickle=False) as replayed:
            np.testing.assert_array_equal(replayed["probabilities"], p)
        again = json.loads((tmp_path / "summary.json").read_text())["objects"][0]["fine_map"]
        assert isinstance(fine["stiffness_anomalies"], list)
        assert again["stiffness_anomalies"] == fine["stiffness_anomalies"]
        # and in seed 002's format at its own resolution, read back by palpate's own reader
        hm = HapticMaterialMap.read(out / "haptic_materials" / "slab_fine")
        assert hm.cell_size == pytest.approx(0.001) and hm.probabilities.shape == p.shape
        np.testing.assert_allclose(hm.probabilities, p, atol=1 / 255 + 1e-9)


def test_the_recorded_pad_hangs_in_the_transform_tree_under_the_fingertip(small_run):
    from mcap.reader import make_reader

    _, _, out = small_run
    tf, parents = [], {}
    with open(out / "run.mcap", "rb") as f:
        for schema, channel, message in make_reader(f).iter_messages():
            msg = json.loads(message.data)
            if channel.topic.startswith("/tf/"):
                assert schema.name == "foxglove.FrameTransform"
                tf.append(msg)
            elif channel.topic.startswith("/pose/"):
                parents[msg["child_frame_id"]] = msg["parent_frame_id"]
            elif channel.topic.startswith("/taxels/"):
                pad = msg["frame_id"]
    (pad_tf,) = tf  # once per pad
    # exactly Foxglove's FrameTransform fields
    assert set(pad_tf) == {"timestamp", "parent_frame_id", "child_frame_id", "translation", "rotation"}
    assert pad_tf["child_frame_id"] == pad and parents[pad_tf["parent_frame_id"]] == "world"
    assert pad_tf["translation"] == {"x": 0.0, "y": 0.0, "z": -0.008}  # the sphere's bottom: the default 8 mm tip
    assert pad_tf["rotation"] == {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}


def test_the_recording_shows_the_fine_map_at_its_own_resolution(small_run):
    from mcap.reader import make_reader

    _, _, out = small_run
    with open(out / "run.mcap", "rb") as f:
        grids = [json.loads(m.data) for _, c, m in make_reader(f).iter_messages(topics=["/map/slab_fine"])]
    (grid,) = grids  # once, when the object's exploration ends
    assert grid["cell_size"] == {"x": 0.001, "y": 0.001} and grid["column_count"] == 60


def test_a_boundary_policy_run_replays_its_off_centre_presses_bit_for_bit(tmp_path):
    from palpate.core.session.run import run_scenario

    text = SMALL.replace('policy = "predefined"\npresses_per_region = 2', 'policy = "boundary"\nbudget = 8')
    text = text.replace("attainable_accuracy = true", "attainable_accuracy = false\nfigures = false")
    out = tmp_path / "run"
    summary = run_scenario(parse_scenario(tomllib.loads(text), "small.toml"), out, record=out / "run.mcap")
    (obj,) = summary["objects"]
    assert obj["policy"] == "boundary" and obj["presses"] == 8 and obj["fine_map"]["presses_read"] == 8
    # the cell size is 10 mm and the grid starts at the block's corner: a centre lies at 5 mm + 10 mm k
    assert any(abs((v * 1e3 - 5) / 10 - round((v * 1e3 - 5) / 10)) > 0.05 for r in obj["per_press"]
               for v in r["target_m"])
    assert main(["replay", str(out / "run.mcap"), "--memory", str(out / "memory.json"), "--out",
                 str(tmp_path / "replay"), "--quiet"]) == 0
    for name in ("slab.npz", "slab_fine.npz"):
        with np.load(out / "maps" / name, allow_pickle=False) as ran, \
                np.load(tmp_path / "replay" / "maps" / name, allow_pickle=False) as replayed:
            np.testing.assert_array_equal(replayed["probabilities"], ran["probabilities"])
