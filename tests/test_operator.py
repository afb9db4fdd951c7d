"""The human-operator actuator played by a script: prompted target, answered press, streams taken; in the loop."""

from __future__ import annotations

import io

import numpy as np
import pytest

from palpate.core.errors import PalpateError, RecordingError, ValidationError
from palpate.core.perception.streams import PressRecording
from palpate.core.session.operator import HumanOperator, recordings_from_files, text_grid
from palpate.core.session.sources import PressTarget


def _stream(calls):
    def take(target, k):
        calls.append((round(target.x, 6), round(target.y, 6), k))
        return PressRecording([], [], None, {"k": k})

    return take


def test_operator_is_shown_the_target_answers_and_the_press_streams_are_taken(tmp_path):
    calls = []
    out = io.StringIO()
    op = HumanOperator((0.0, 0.0), 0.01, (4, 3), _stream(calls), input=io.StringIO("\n"), output=out,
                       figure_dir=tmp_path / "figs")
    rec = op.press(PressTarget(0.015, 0.025, depth=0.004, force=5.0))
    text = out.getvalue()
    assert "Press 1: cell column 2, row 3 (x = 15.0 mm, y = 25.0 mm), about 4.0 mm deep, at most 5.0 N" in text
    # Row 3 is printed first (top), the X in its second column.
    grid_lines = [ln for ln in text.splitlines() if ln[:4].strip() in ("1", "2", "3")]
    assert grid_lines[0].split() == ["3", ".", "X", ".", "."]
    assert calls == [(0.015, 0.025, 0)]
    assert rec.meta["source"] == "operator" and rec.meta["cell"] == [2, 3]
    assert op.figures[0].name == "operator_press_001.png" and op.figures[0].read_bytes()[:4] == b"\x89PNG"


def test_operator_reprompts_on_an_unclear_answer_and_stops_on_q_or_end_of_input():
    out = io.StringIO()
    op = HumanOperator((0.0, 0.0), 0.01, (2, 2), _stream([]), input=io.StringIO("maybe\nyes\nq\n"), output=out)
    op.press(PressTarget(0.005, 0.005))
    assert "did not understand 'maybe'" in out.getvalue()
    with pytest.raises(PalpateError, match="operator stopped"):
        op.press(PressTarget(0.015, 0.005))
    with pytest.raises(PalpateError, match="input ended"):
        op.press(PressTarget(0.015, 0.005))
    assert op.pressed == {(0, 0)}


def test_operator_rejects_targets_outside_its_grid_and_bad_streams(tmp_path):
    op = HumanOperator((0.0, 0.0), 0.01, (2, 2), lambda t, k: "not a recording", input=io.StringIO("\n"),
                       output=io.StringIO())
    with pytest.raises(ValidationError, match="outside the operator's 2x2 grid"):
        op.press(PressTarget(0.025, 0.005))
    with pytest.raises(ValidationError, match="returned str for press 1"):
        op.press(PressTarget(0.005, 0.005))
    files = HumanOperator((0.0, 0.0), 0.01, (2, 2), [], input=io.StringIO("\n"), output=io.StringIO())
    with pytest.raises(RecordingError, match="only 0 recording file"):
        files.press(PressTarget(0.005, 0.005))
    with pytest.raises(RecordingError, match="press 2 asked for, but only 1"):
        recordings_from_files([tmp_path / "a.mcap"])(PressTarget(0.0, 0.0), 1)


def test_text_grid_marks_estimates_in_upper_case_where_pressed():
    est = np.array([[0, 1, -1], [1, 1, 0]])
    s = text_grid((3, 2), (2, 1), {(0, 0)}, est, "SH")
    assert s.splitlines()[1].split() == ["2", "h", "h", "X"]
    assert s.splitlines()[2].split() == ["1", "S", "h", "."]


def test_operator_in_the_closed_loop_explores_an_object(tmp_path):
    """A script plays the operator: it confirms every prompt and 'presses' through the simulated finger."""
    import tomllib

    from palpate.core.session.explore import explore_object
    from palpate.core.session.progress import Progress
    from palpate.core.session.report import object_summary
    from palpate.core.session.sources import scenario_source_maker
    from palpate.core.session.training import train_memory
    from palpate.core.world.scenario_file import parse_scenario
    from palpate.core.world.workspace import map_geometries

    raw = tomllib.loads("""
[scenario]
name = "op"
seed = 2
fidelity = "analytic"
[[materials]]
name = "soft"
young_kpa = 20.0
[[materials]]
name = "hard"
young_kpa = 450.0
poisson = 0.4
[training]
presses_per_material = 5
depth_mm = 4.0
max_force_n = 10.0
[exploration]
policy = "info_gain"
budget = 3
depth_mm = 4.0
max_force_n = 10.0
variability = "robot"
[[objects]]
name = "slab"
size_mm = [30.0, 20.0, 40.0]
position_mm = [15.0, 10.0]
material = "soft"
[outputs]
figures = false
haptic_material = false
""")
    sc = parse_scenario(raw, "op.toml")
    sim = scenario_source_maker(sc)
    memory = train_memory(sc, sim, [5, 6], Progress(enabled=False)).memory
    geom = map_geometries(sc)["slab"]
    out = io.StringIO()

    def make(objects, seed, variability):
        finger = sim(objects, seed, variability)
        return HumanOperator(geom.origin, geom.cell_size, geom.plane_shape,
                             lambda target, k: finger.press(target), input=io.StringIO("\n" * 3), output=out,
                             figure_dir=tmp_path, materials=memory.materials)

    summary = object_summary(explore_object(sc, sc.objects[0], memory, make, 9, Progress(enabled=False)))
    assert summary["presses"] == 3
    assert out.getvalue().count("press the cell, then Enter") == 3
    assert "S = soft, H = hard" in out.getvalue()  # the loop showed the operator the map
    assert len(list(tmp_path.glob("operator_press_*.png"))) == 3
    assert all(r["posterior"] is not None and r["posterior"][0] > 0.9 for r in summary["per_press"])
