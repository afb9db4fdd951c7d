"""A Dynamixel finger with no tactile pad: its joint currents give the fingertip force through its Jacobian as
c_P (calibrated in N), the memory is trained on the force the finger would have measured and judges each press by
its kinesthetic model alone, and the map says so. Through the servo emulator backed by MuJoCo physics."""

from __future__ import annotations

import json
import tomllib

import numpy as np

from palpate.core.cli import main
from palpate.core.io.mcap_reader import read_recording
from palpate.core.mapping.grids import Grid2D
from palpate.core.perception.force_channel import FORCE_QUANTUM, SENSOR_ID
from palpate.core.perception.memory import HapticMemory
from palpate.core.session.run import run_scenario
from palpate.core.world.scenario_file import parse_scenario


def _scenario(repo_dir):
    raw = tomllib.loads((repo_dir / "scenarios" / "explore_dynamixel.toml").read_text())
    raw["exploration"].update(policy="predefined", presses_per_region=1)
    raw["objects"][0]["regions"] = [[1, 1], [5, 1]]
    raw["actuator"].update(approach_mm=3.0, pad=False)
    raw["outputs"].update(figures=False, haptic_material=False)
    return parse_scenario(raw, "explore_dynamixel.toml", base_dir=repo_dir / "scenarios")


def test_a_finger_without_a_pad_maps_by_its_joint_currents_and_the_kinesthetic_model(repo_dir, tmp_path):
    summary = run_scenario(_scenario(repo_dir), tmp_path, record=tmp_path / "run.mcap")
    (obj,) = summary["objects"]
    assert obj["features"] == ["kinesthetic"]  # the map says which features it used
    rows = obj["per_press"]
    assert [r["fit"]["features"] for r in rows] == ["kinesthetic", "kinesthetic"]
    assert rows[0]["posterior"][0] > 0.9 and rows[1]["posterior"][1] > 0.9  # foam reads soft, the hard end firm
    # the memory has no cutaneous model and says so in its file (version 2); it loads and audits
    doc = json.loads((tmp_path / "memory.json").read_text())
    assert doc["version"] == 2 and doc["features"] == "kinesthetic"
    assert HapticMemory.load(tmp_path / "memory.json").features == "kinesthetic"
    # c_P is the fingertip force: the current-based channel against the physics' true contact force
    run = read_recording(tmp_path / "run.mcap")
    windows = [(a.data["t_start"], a.data["t_end"]) for a in run.annotations
               if a.kind == "press" and a.data["phase"] == "exploration"]
    force = [(f.t, f.counts[0, 0] * FORCE_QUANTUM) for f in run.frames
             if f.sensor_id == SENSOR_ID and any(a <= f.t <= b for a, b in windows)]
    t, measured = np.array(force).T
    truth = np.interp(t, run.truth.t, run.truth.force)
    assert measured.max() > 3.0
    # a current step (2.69 mA) is ~0.1 N at the tip; the contact point sits a tip radius off the kinematic tip
    np.testing.assert_allclose(measured, truth, atol=0.15 + 0.1 * truth.max())
    # replayed, the recording gives the same map
    assert main(["replay", str(tmp_path / "run.mcap"), "--memory", str(tmp_path / "memory.json"), "--out",
                 str(tmp_path / "replay"), "--quiet"]) == 0
    ran, replayed = (Grid2D.load(d / "maps" / "Strip.npz") for d in (tmp_path, tmp_path / "replay"))
    np.testing.assert_array_equal(replayed.probabilities, ran.probabilities)
