"""The exploration actuator of ``palpate run``: the scenario's [actuator] table and its command-line overrides,
a person (played by a script) pressing from a folder of recordings, the Dynamixel finger through the
physics-backed servo emulator, and grids the planar finger cannot press refused before anything moves."""

from __future__ import annotations

import argparse
import io
import json
import threading
import tomllib
from pathlib import Path

import numpy as np
import pytest

from palpate.core.errors import PalpateError, RecordingError, ValidationError
from palpate.core.io.mcap_writer import RecordingWriter
from palpate.core.session.actuators import open_actuators
from palpate.core.session.operator_actuator import OperatorOptions, folder_streams, recordings_folder
from palpate.core.session.run import run_scenario
from palpate.core.session.sources import PressTarget
from palpate.core.world.scenario import ActuatorSpec
from palpate.core.world.scenario_file import parse_actuator, parse_scenario
from palpate.core.world.scene import Scene
from palpate.core.world.workspace import map_geometries

# Two reference materials; a 30 x 10 mm foam slab whose last 10 mm (cell 3) is a hard column.
OPERATOR = """
[scenario]
name = "op"
seed = 5
fidelity = "analytic"
[[materials]]
name = "soft"
young_kpa = 20.0
[[materials]]
name = "hard"
young_kpa = 450.0
poisson = 0.4
[[materials]]
name = "foam"
young_kpa = 24.0
reference = false
like = "soft"
[training]
presses_per_material = 5
depth_mm = 5.0
max_force_n = 10.0
[exploration]
policy = "predefined"
presses_per_region = 1
depth_mm = 5.0
max_force_n = 10.0
[[objects]]
name = "slab"
size_mm = [30.0, 10.0, 40.0]
position_mm = [15.0, 5.0]
material = "foam"
regions = [[1, 1], [3, 1]]
[[objects.inclusions]]
material = "hard"
shape = "column"
center_mm = [25.0, 5.0]
size_mm = [10.0, 10.0]
[outputs]
figures = false
haptic_material = false
"""


def _scenario(text: str, actuator: dict | None = None, base: Path | None = None, **tables):
    raw = tomllib.loads(text)
    if actuator is not None:
        raw["actuator"] = actuator
    for name, changes in tables.items():
        raw[name] = {**raw.get(name, {}), **changes}
    return parse_scenario(raw, "x.toml", base_dir=base)


# ---- the [actuator] table ----------------------------------------------------------------------------------

def test_actuator_defaults_to_the_simulated_finger_and_reads_each_kind(tmp_path):
    assert _scenario(OPERATOR).actuator == ActuatorSpec()
    assert _scenario(OPERATOR).training.source == "sim"
    op = _scenario(OPERATOR, {"kind": "operator", "recordings_dir": "presses", "figures": False}, base=tmp_path)
    assert op.actuator.kind == "operator" and not op.actuator.options.figures
    assert op.actuator.options.recordings_dir == tmp_path.parent / "presses"  # resolved like every other path
    dyn = _scenario(OPERATOR, {"kind": "dynamixel", "finger": "f.toml", "emulate": True, "baud": 57600,
                               "pose_noise_mm": 0.05, "approach_mm": 3})
    a = dyn.actuator.options
    assert (dyn.actuator.kind, a.emulate, a.port, a.baud) == ("dynamixel", True, None, 57600)
    assert a.pose_noise == pytest.approx(5e-5) and a.approach_height == pytest.approx(0.003)
    real = parse_actuator({"kind": "dynamixel", "port": "/dev/ttyUSB0", "finger": "f.toml"}).options
    assert real.port == "/dev/ttyUSB0" and not real.emulate and real.baud == 1_000_000


@pytest.mark.parametrize("table, message", [
    ({"kind": "robot"}, "actuator.kind: must be one of sim, dynamixel, operator; got 'robot'"),
    ({"kind": "operator", "recordings_dir": "d", "speed": 1}, "actuator.speed: unknown key"),
    ({"kind": "operator", "recordings_dir": "d", "port": "/dev/x"},
     "actuator.port: is a key of kind 'dynamixel', but kind is 'operator'"),
    ({"recordings_dir": "d"}, "actuator.recordings_dir: is a key of kind 'operator', but kind is 'sim'"),
    ({"kind": "operator"}, "actuator.recordings_dir: missing"),
    ({"kind": "operator", "recordings_dir": "d", "figures": "yes"}, "actuator.figures: expected true or false"),
    ({"kind": "dynamixel", "finger": "f.toml"}, "actuator.port: missing: the servo bus's serial port"),
    ({"kind": "dynamixel", "finger": "f.toml", "emulate": True, "port": "/dev/x"}, "actuator.port: not used with"),
    ({"kind": "dynamixel", "emulate": True}, "actuator.finger: missing"),
    ({"kind": "dynamixel", "finger": "f.toml", "emulate": True, "pose_noise_mm": -1}, "pose_noise_mm: must be >= 0"),
    ({"kind": "dynamixel", "finger": "f.toml", "emulate": True, "baud": 0}, "actuator.baud: must be >= 1"),
])
def test_bad_actuator_tables_name_file_and_key(table, message):
    with pytest.raises(ValidationError, match="^x.toml: ") as info:
        _scenario(OPERATOR, table)
    assert message in str(info.value)


def test_training_source_cannot_be_an_exploration_actuator():
    with pytest.raises(ValidationError, match=r"x.toml: training.source: 'operator' is an exploration actuator"):
        _scenario(OPERATOR, training={"source": "operator"})


def test_command_line_options_override_the_actuator(tmp_path):
    from palpate.core.cli.run import with_actuator_options

    def args(**kw):
        return argparse.Namespace(**{"actuator": None, "recordings": None, "port": None, "emulate": False,
                                     "finger": None, **kw})

    sc = _scenario(OPERATOR, {"kind": "dynamixel", "finger": "f.toml", "emulate": True, "approach_mm": 4})
    assert with_actuator_options(sc, args()) is sc
    # same kind: the scenario's keys stay, --port replaces emulate
    real = with_actuator_options(sc, args(port="/dev/ttyUSB1")).actuator.options
    assert (real.port, real.emulate, real.approach_height) == ("/dev/ttyUSB1", False, pytest.approx(0.004))
    # another kind: only what the command line gives
    op = with_actuator_options(sc, args(actuator="operator", recordings=tmp_path)).actuator
    assert op == ActuatorSpec("operator", OperatorOptions(recordings_dir=tmp_path.resolve()))
    assert with_actuator_options(sc, args(actuator="sim")).actuator == ActuatorSpec()
    with pytest.raises(ValidationError, match="command line's actuator options: actuator.recordings_dir: missing"):
        with_actuator_options(sc, args(actuator="operator"))
    with pytest.raises(ValidationError, match="actuator.port: is a key of kind 'dynamixel', but kind is 'operator'"):
        with_actuator_options(sc, args(actuator="operator", recordings=tmp_path, port="/dev/x"))


# ---- a person at the actuator, played by a script ---------------------------------------------------------

def _record_presses(scenario, folder: Path, seed: int = 7) -> list[tuple[float, float]]:
    """What the person does: press each region (human-like variability), one MCAP file per press."""
    from palpate.sim.source import SimSource

    entry = scenario.objects[0]
    geom = map_geometries(scenario)[entry.spec.name]
    source = SimSource(Scene((entry.spec,), scenario.fingertip, scenario.taxels, scenario.pose),
                       fidelity="analytic", seed=seed, variability="human")
    folder.mkdir(parents=True, exist_ok=True)
    targets = []
    for k, (c, r) in enumerate(entry.regions):
        x = geom.origin[0] + (c - 0.5) * geom.cell_size
        y = geom.origin[1] + (r - 0.5) * geom.cell_size
        rec = source.press(PressTarget(x, y, depth=0.005, force=10.0))
        with RecordingWriter(folder / f"press_{k + 1:03d}.mcap", {"sources": ["tekscan", "liberty"]}) as w:
            for f in rec.frames:
                w.write_taxel(f)
            for p in rec.poses:
                w.write_pose(p)
        targets.append((x, y))
    return targets


def test_an_operator_run_reads_one_recording_per_press_and_maps_the_object(tmp_path, monkeypatch, capsys):
    folder = tmp_path / "presses"
    _record_presses(_scenario(OPERATOR), folder)
    sc = _scenario(OPERATOR, {"kind": "operator", "recordings_dir": str(folder)})
    monkeypatch.setattr("sys.stdin", io.StringIO("\n\n"))  # the person confirms each press
    summary = run_scenario(sc, tmp_path / "out")
    prompts = capsys.readouterr().err
    (obj,) = summary["objects"]
    assert obj["presses"] == 2 and [r["cell"] for r in obj["per_press"]] == [[1, 1], [3, 1]]
    assert prompts.count("press the cell, then Enter") == 2
    assert "Press 2: cell column 3, row 1 (x = 25.0 mm, y = 5.0 mm)" in prompts
    # the foam cell reads as soft, the hard column as hard; post-processing fills the cell between them
    post = [r["posterior"] for r in obj["per_press"]]
    assert post[0][0] > 0.99 and post[1][1] > 0.99
    assert obj["accuracy"]["explored_before_postprocessing"] == 1.0
    assert summary["memory"]["trained"] and summary["crossval"] is not None  # trained in simulation
    assert summary["actuator"] == "operator"
    figs = sorted(p.name for p in (tmp_path / "out" / "figures" / "operator" / "slab").glob("*.png"))
    assert figs == ["operator_press_001.png", "operator_press_002.png"]
    assert json.loads((tmp_path / "out" / "summary.json").read_text())["objects"][0]["presses"] == 2

    # with a memory file the simulation is not needed at all: a source that does not exist is never loaded
    sc2 = _scenario(OPERATOR, {"kind": "operator", "recordings_dir": str(folder), "figures": False},
                    training={"memory": str(tmp_path / "out" / "memory.json"), "source": "no_such_source"})
    monkeypatch.setattr("sys.stdin", io.StringIO("\n\n"))
    again = run_scenario(sc2, tmp_path / "out2")
    assert not again["memory"]["trained"]
    assert [r["posterior"] for r in again["objects"][0]["per_press"]] == post
    # without one, a missing simulation is a clear error that says what to give instead
    sc3 = _scenario(OPERATOR, {"kind": "operator", "recordings_dir": str(folder)}, training={"source": "nope"})
    with pytest.raises(ValidationError, match=r"trained in simulation \(training.source = 'nope'\), which is "
                       r"unavailable: unknown source 'nope'.*Give training.memory"):
        run_scenario(sc3, tmp_path / "out3")


def test_operator_folder_problems_are_clear_errors(tmp_path):
    with pytest.raises(ValidationError, match="actuator.recordings_dir: .* is not a folder"):
        recordings_folder(tmp_path / "missing", "slab", 1)
    with pytest.raises(ValidationError, match=r"explores 2 objects, so each has a subfolder .*[/\\]slab is missing"):
        recordings_folder(tmp_path, "slab", 2)
    (tmp_path / "slab").mkdir()
    assert recordings_folder(tmp_path, "slab", 2) == tmp_path / "slab"
    # checked when the run starts, before training, with the scenario file named
    sc = _scenario(OPERATOR, {"kind": "operator", "recordings_dir": str(tmp_path / "missing")})
    with pytest.raises(ValidationError, match="^x.toml: actuator.recordings_dir"):
        run_scenario(sc, tmp_path / "out")
    assert not (tmp_path / "out" / "memory.json").exists()


def test_a_recording_that_arrives_during_the_session_is_waited_for(tmp_path):
    src = tmp_path / "recorded"
    _record_presses(_scenario(OPERATOR), src)
    folder = tmp_path / "session"
    folder.mkdir()
    out = io.StringIO()

    class Person:
        """Imports the press's recording only after being told it is missing, then confirms."""

        def __init__(self):
            self.calls = 0

        def readline(self):
            self.calls += 1
            (folder / "press_001.mcap").write_bytes((src / "press_001.mcap").read_bytes())
            return "\n"

    person = Person()
    take = folder_streams(folder, person, out)
    rec = take(PressTarget(0.005, 0.005), 0)
    assert person.calls == 1 and "no recording for press 1 in" in out.getvalue()
    assert len(rec.frames) > 10 and rec.meta["file"].endswith("press_001.mcap")
    with pytest.raises(RecordingError, match=r"press 2 needs its recording, but .* hold 1 press\(es\)"):
        folder_streams(folder, io.StringIO(""), out)(PressTarget(0.005, 0.005), 1)
    with pytest.raises(PalpateError, match="operator stopped"):
        folder_streams(folder, io.StringIO("q\n"), out)(PressTarget(0.005, 0.005), 1)


# ---- the Dynamixel finger --------------------------------------------------------------------------------

def _dynamixel_scenario(repo_dir: Path, **changes):
    raw = tomllib.loads((repo_dir / "scenarios" / "explore_dynamixel.toml").read_text())
    for table, values in changes.items():
        target = raw[table][0] if isinstance(raw[table], list) else raw[table]
        target.update(values)
    return parse_scenario(raw, "explore_dynamixel.toml", base_dir=repo_dir / "scenarios")


def _forbid_motion(monkeypatch):
    """Any attempt to start the emulator or open a bus fails the test."""
    def boom(*a, **k):
        raise AssertionError("the finger was started")

    monkeypatch.setattr("palpate.hardware.dynamixel.physics_bus.physics_bus", boom)
    monkeypatch.setattr("palpate.hardware.dynamixel.driver.DynamixelFinger", boom)


@pytest.mark.parametrize("objects, message", [
    # a 2-row grid: the second row is 10 mm off planar2's plane y = 0
    ({"grid_origin_mm": [45.0, -5.0], "grid_cells": [5, 2]},
     r"5 of the 10 cells the exploration may press lie off the plane of finger 'planar2' .*planar2.toml\), "
     r"y = 0.0 mm: cell\(s\) \[1, 2\] at y = 10.0 mm, \[2, 2\] at y = 10.0 mm, \[3, 2\] at y = 10.0 mm and 2 more\. "
     r"A planar finger presses one row: give the object grid_cells = \[N, 1\] and grid_origin_mm = \[x0, -5.0\]"),
    # a row beyond the finger's reach (links 70 + 50 mm from a base 100 mm up)
    ({"size_mm": [200.0, 20.0, 30.0], "position_mm": [100.0, 0.0], "grid_origin_mm": [95.0, -5.0],
      "grid_cells": [5, 1]}, r"cell \[\d, 1\] at x = 1\d\d.0 mm cannot be pressed 4.0 mm deep .*out of reach"),
])
def test_a_grid_the_finger_cannot_press_is_refused_before_anything_moves(repo_dir, tmp_path, monkeypatch,
                                                                         objects, message):
    _forbid_motion(monkeypatch)
    sc = _dynamixel_scenario(repo_dir, objects=objects)
    with pytest.raises(ValidationError, match=message) as info:
        run_scenario(sc, tmp_path)
    assert str(info.value).startswith("explore_dynamixel.toml: actuator dynamixel, object 'Strip'")
    assert not (tmp_path / "memory.json").exists()  # refused before training


def test_a_real_bus_without_a_tactile_array_is_refused_before_anything_moves(repo_dir, tmp_path, monkeypatch):
    _forbid_motion(monkeypatch)
    sc = _dynamixel_scenario(repo_dir)
    from dataclasses import replace

    sc = replace(sc, actuator=replace(sc.actuator, options=replace(sc.actuator.options, emulate=False,
                                                                   port="/dev/ttyUSB0", taxels=None)))
    with pytest.raises(ValidationError, match=r"actuator.taxels: missing: the finger on '/dev/ttyUSB0' needs the "
                       r"tactile array's serial port"):
        run_scenario(sc, tmp_path)
    assert not (tmp_path / "memory.json").exists()


def test_the_emulated_finger_explores_through_the_wire_and_closes_the_bus(repo_dir, tmp_path):
    """The live Dynamixel + taxel loop to a map: dynamixel-sdk -> pty -> servo emulator -> MuJoCo physics, and
    pyserial -> a second pty -> tactile array emulator -> the same physics' pad, driven by run_scenario: two
    presses."""
    sc = _dynamixel_scenario(repo_dir, exploration={"policy": "predefined", "presses_per_region": 1},
                             objects={"regions": [[1, 1], [5, 1]]},
                             actuator={"approach_mm": 3.0}, outputs={"figures": False, "haptic_material": False})
    threads = threading.active_count()
    summary = run_scenario(sc, tmp_path, record=tmp_path / "run.mcap")
    assert threading.active_count() == threads  # the emulator's thread stopped, the port closed
    assert summary["actuator"] == "dynamixel"
    (obj,) = summary["objects"]
    rows = obj["per_press"]
    assert [r["cell"] for r in rows] == [[1, 1], [5, 1]]
    for r in rows:
        assert r["rejected"] == [] and r["fit"] is not None
        # the press happened where it was planned: the fingertip's measured location is on the target
        np.testing.assert_allclose(r["location_m"], r["target_m"], atol=5e-4)
    # foam (like soft) pressed to the 4 mm depth (the servos run on a little under load); the hard end stops at
    # the 8 N force first
    assert 0.0033 < rows[0]["depth_m"] < 0.0055 and rows[1]["depth_m"] < 0.003
    assert rows[0]["posterior"][0] > 0.99 and rows[1]["posterior"][1] > 0.99
    assert obj["accuracy"]["explored_before_postprocessing"] == 1.0
    # the presses' taxel frames came from the tactile array's wire (50 Hz frames, timed by their counters)
    from palpate.core.io.mcap_reader import read_recording

    run = read_recording(tmp_path / "run.mcap")
    windows = [(a.data["t_start"], a.data["t_end"]) for a in run.annotations
               if a.kind == "press" and a.data["phase"] == "exploration"]
    explored = [f for f in run.frames if any(t0 <= f.t <= t1 for t0, t1 in windows)]
    assert len(windows) == 2 and len(explored) > 40 and max(int(f.counts.max()) for f in explored) > 20
    steps = np.diff([f.t for f in explored if windows[0][0] <= f.t <= windows[0][1]]) * 50.0
    np.testing.assert_allclose(steps, np.round(steps), atol=1e-6)  # on the array's 50 Hz counter grid
    # the recorded run (simulated training, finger exploration: one pose stream) replays to the same map
    from palpate.core.cli import main
    from palpate.core.mapping.grids import Grid2D

    assert main(["replay", str(tmp_path / "run.mcap"), "--memory", str(tmp_path / "memory.json"), "--out",
                 str(tmp_path / "replay"), "--quiet"]) == 0
    ran, replayed = (Grid2D.load(d / "maps" / "Strip.npz") for d in (tmp_path, tmp_path / "replay"))
    np.testing.assert_array_equal(replayed.probabilities, ran.probabilities)


def test_the_command_line_switches_the_finger_to_a_real_port_and_needs_its_tactile_array(repo_dir, tmp_path,
                                                                                        monkeypatch, capsys):
    from palpate.core.cli import main

    _forbid_motion(monkeypatch)
    code = main(["run", str(repo_dir / "scenarios" / "explore_dynamixel.toml"), "--port", "/dev/ttyUSB7",
                 "--out", str(tmp_path), "--quiet"])
    err = capsys.readouterr().err
    assert code == 2
    assert "explore_dynamixel.toml: actuator.taxels: missing: the finger on '/dev/ttyUSB7'" in err
    assert not (tmp_path / "memory.json").exists()
    code = main(["run", str(repo_dir / "scenarios" / "explore_dynamixel.toml"), "--emulate", "--taxels", "/dev/x",
                 "--out", str(tmp_path), "--quiet"])
    assert code == 2 and "actuator.taxels: not used with emulate = true" in capsys.readouterr().err


def test_travel_between_cells_stays_above_the_object(repo_dir):
    from palpate.core.session.actuators import actuator_requests
    from palpate.hardware.dynamixel.actuator_source import dynamixel_actuator
    from palpate.hardware.dynamixel.finger import forward_kinematics, inverse_kinematics

    sc = _dynamixel_scenario(repo_dir, actuator={"approach_mm": 3.0})
    request = actuator_requests(sc, map_geometries(sc))["Strip"]
    top = request.obj.height
    session = dynamixel_actuator(request)  # powered on 3 mm above cell 1 (x = 50 mm)
    try:
        driver = session.actuator.driver
        finger = driver.finger
        t0 = driver.clock()
        session.travel_to(0.09)
        t1 = driver.clock()
        tip = forward_kinematics(finger, driver.read_state().position)[0]
        _, truth = session.actuator.streams(t0, t1)
    finally:
        session.close()
    assert tip[0] == pytest.approx(0.09, abs=1e-3) and tip[2] == pytest.approx(top + 0.003, abs=1e-3)
    assert len(truth.t) > 20 and not truth.force.any()  # 40 mm along the strip without touching it
    # one joint move would have swept the tip into the strip half-way
    qa, qb = (inverse_kinematics(finger, x, top + 0.003) for x in (0.05, 0.09))
    assert forward_kinematics(finger, (qa + qb) / 2)[0][2] < top - 0.001


def test_open_actuators_closes_each_objects_actuator_when_the_next_is_made(tmp_path, monkeypatch):
    """The maker hands out one actuator at a time and closes it after its object (and at the end)."""
    closed = []

    class Fake:
        def __init__(self, name):
            self.name = name

        def press(self, target):  # pragma: no cover - not pressed here
            raise AssertionError

        def close(self):
            closed.append(self.name)

    calls = []

    def factory(request, *, check_only=False):
        calls.append((request.obj.name, check_only, request.seed))
        return None if check_only else Fake(request.obj.name)

    raw = tomllib.loads(OPERATOR)
    raw["objects"].append({**raw["objects"][0], "name": "slab2", "inclusions": []})
    for name in ("slab", "slab2"):
        (tmp_path / name).mkdir()
    raw["actuator"] = {"kind": "operator", "recordings_dir": str(tmp_path)}
    sc = parse_scenario(raw, "x.toml")
    monkeypatch.setattr("palpate.core.session.actuators.load_actuator", lambda kind: factory)
    with open_actuators(sc, tmp_path, map_geometries(sc), lambda: None) as (_, make):
        assert calls == [("slab", True, 0), ("slab2", True, 0)]  # every object checked first
        a = make((sc.objects[0].spec,), 11, "human")
        assert closed == [] and a.name == "slab"
        make((sc.objects[1].spec,), 12, "human")
        assert closed == ["slab"]
    assert closed == ["slab", "slab2"] and calls[2:] == [("slab", False, 11), ("slab2", False, 12)]
