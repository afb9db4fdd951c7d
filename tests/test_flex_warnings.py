"""MuJoCo's own warnings in a flex press are never silent: those that invalidate the force are errors, the M + K
solve running out of iterations (mjWARN_INERTIA) is counted, in the trace, the recording, the press result, the
recording's press annotation and the run summary, with what to change."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

pytest.importorskip("mujoco")

import mujoco  # noqa: E402

from palpate.core.errors import SimulationDiverged, ValidationError  # noqa: E402
from palpate.core.io.mcap_reader import read_recording  # noqa: E402
from palpate.core.perception.press import perceive_press  # noqa: E402
from palpate.core.perception.streams import PressRecording, solver_warning_steps  # noqa: E402
from palpate.core.session.press_log import PressLog  # noqa: E402
from palpate.core.session.report import solver_warning, solver_warnings  # noqa: E402
from palpate.core.session.sources import PressTarget, scenario_source_maker  # noqa: E402
from palpate.core.world.scenario_file import parse_scenario  # noqa: E402
from palpate.core.world.scene import FingertipSpec, Layer, Material, ObjectSpec, Scene  # noqa: E402
from palpate.sim import simulate_press  # noqa: E402
from palpate.sim.controller import press_profile  # noqa: E402
from palpate.sim.flex import press as flex  # noqa: E402
from palpate.sim.source import SimSource  # noqa: E402
from palpate.sim.stability import SolverWarnings, check_dropped, inertia_warnings  # noqa: E402

R = 0.008


def _stiff_skin(skin: float = 0.002) -> ObjectSpec:
    """A 2 MPa skin over a 100 kPa base, 30 mm in all: the validity table's skin_stiff family."""
    return ObjectSpec(name="skin", shape="box", size=(0.1, 0.1, 0.03), position=(0.0, 0.0),
                      material=Material("base", 1e5, 0.45), layers=(Layer(Material("skin", 2e6, 0.4), skin),))


def _press(obj: ObjectSpec, depth: float, **kw):
    scene = Scene(objects=(obj,), fingertip=FingertipSpec(radius=R))
    target = PressTarget(0.0, 0.0, depth=depth, speed=0.01)
    profile = press_profile(target, obj.height, radius=R, timestep=0.002)
    return flex.run_flex_press(scene, obj, target, profile, **kw)


def test_a_stiff_skin_press_counts_its_inertia_warnings_and_a_block_counts_none():
    skin = _press(_stiff_skin(), 0.002)
    counted = skin.meta["solver_warnings"]
    assert counted["steps"] == len(skin.t) - 1 and counted["iterations"] == flex.SOLVER_ITERATIONS
    # counted, not silent: most of the steps in contact ran out of iterations on this skin
    in_contact = int(np.count_nonzero(skin.force > 0))
    assert 0 < counted["inertia_steps"] <= counted["steps"]
    assert counted["inertia_steps"] >= in_contact // 2
    block = _press(ObjectSpec(name="b", shape="box", size=(0.1, 0.1, 0.02), position=(0.0, 0.0),
                              material=Material("m", 2e5, 0.45)), 0.002)
    assert block.meta["solver_warnings"]["inertia_steps"] == 0
    assert SolverWarnings(**block.meta["solver_warnings"]).to_dict() == block.meta["solver_warnings"]


def test_the_count_is_the_steps_on_which_mujocos_counter_grew():
    models: dict = {}
    tr = _press(_stiff_skin(), 0.002, models=models)
    _, data = next(iter(models.values()))
    # MuJoCo's own counter after the press: at least one warning per counted step, none on uncounted ones
    assert inertia_warnings(data) >= tr.meta["solver_warnings"]["inertia_steps"] > 0


@pytest.mark.physics
def test_more_iterations_clear_the_warning_and_leave_the_force():
    """1000 iterations converge the M + K solve on the 2 mm skin (no warning); the force, the constraint
    solver's, stays within 1.5% of the default's from 0.5 mm on (measured: <= 0.25%; 0.9% at 0.2 mm)."""
    default = _press(_stiff_skin(), 0.002)
    many = _press(_stiff_skin(), 0.002, iterations=1000)
    assert many.meta["solver_warnings"]["inertia_steps"] == 0 < default.meta["solver_warnings"]["inertia_steps"]
    d = np.array([0.5e-3, 1e-3, 1.9e-3])
    f = [np.interp(d, tr.indentation[: np.argmax(tr.indentation) + 1], tr.force[: np.argmax(tr.indentation) + 1])
         for tr in (default, many)]
    np.testing.assert_allclose(f[0], f[1], rtol=0.015)


def test_bad_iteration_limits_are_refused():
    for bad in (0, -3, 2.5, True, None):
        with pytest.raises(ValidationError, match="iterations"):
            _press(_stiff_skin(), 0.001, iterations=bad)


def test_dropped_contacts_or_constraints_are_errors():
    class Warn:
        def __init__(self, n):
            self.number = n

    class Data:
        time = 0.1

        def __init__(self, which):
            self.warning = [Warn(0) for _ in range(8)]
            self.warning[int(which)] = Warn(3)

    check_dropped(Data(mujoco.mjtWarning.mjWARN_INERTIA), timestep=0.01)  # not a dropped row: no error
    for which in (mujoco.mjtWarning.mjWARN_CONTACTFULL, mujoco.mjtWarning.mjWARN_CNSTRFULL):
        # the advice names what a scenario can change (its depth, its fidelity), not run_flex_press internals
        with pytest.raises(SimulationDiverged, match="dropped.*less deep.*fidelity 'analytic' or 'rigid'"):
            check_dropped(Data(which), timestep=0.01)


def test_the_count_reaches_the_recording_the_press_result_the_annotation_and_the_summary(tmp_path):
    scene = Scene(objects=(_stiff_skin(),), fingertip=FingertipSpec(radius=R))
    rec = SimSource(scene, fidelity="flex").press(PressTarget(0.0, 0.0, depth=0.002, speed=0.01))
    steps = rec.meta["physics"]["solver_warnings"]["inertia_steps"]
    assert steps > 0 and rec.meta["solver_warning_steps"] == steps
    res = perceive_press(rec)
    assert res.solver_warning_steps == steps
    clean = perceive_press(simulate_press(2e5, fidelity="flex", depth=0.002, thickness=0.02))
    assert clean.solver_warning_steps == 0
    counted = solver_warnings([res, clean])
    assert (counted.presses, counted.warned_presses, counted.warned_steps) == (2, 1, steps)
    message = solver_warning("Skin", counted)
    assert "1 of 2 presses" in message and str(steps) in message and "iterations" in message
    assert solver_warning("Block", solver_warnings([clean])) is None
    log = PressLog(tmp_path / "r.mcap", {"scenario": "t"})
    log.add(rec, {"phase": "exploration", "k": 1})
    log.close()
    press = [a for a in read_recording(tmp_path / "r.mcap").annotations if a.kind == "press"][0]
    assert press.data["solver_warning_steps"] == steps


def test_recordings_without_the_count_read_zero_and_bad_counts_are_refused():
    assert solver_warning_steps({}) == 0 and solver_warning_steps(None) == 0
    sim = simulate_press(2e5, fidelity="analytic", depth=0.002)
    assert perceive_press(PressRecording(frames=sim.frames, poses=sim.poses, meta={})).solver_warning_steps == 0
    for bad in (-1, 2.5, "3", True):
        with pytest.raises(ValidationError, match="solver_warning_steps"):
            solver_warning_steps({"solver_warning_steps": bad})


def test_the_scenario_names_the_flex_iteration_limit_the_advice_names():
    """The run's advice names a key a scenario has: ``flex_iterations`` reaches the source and MuJoCo's limit;
    left out, the simulator's default; bad values are refused with the key's name."""
    raw = {"scenario": {"name": "t", "fidelity": "flex", "flex_iterations": 250},
           "exploration": {"policy": "raster"},
           "materials": [{"name": "a", "young_kpa": 200.0}, {"name": "b", "young_kpa": 20.0}],
           "objects": [{"name": "o", "shape": "box", "size_mm": [100.0, 100.0, 20.0], "position_mm": [0.0, 0.0],
                        "material": "a"}]}
    sc = parse_scenario(raw)
    src = scenario_source_maker(sc)((sc.objects[0].spec,), 0, "robot")
    assert src.flex_iterations == 250
    rec = src.press(PressTarget(0.0, 0.0, depth=0.001, speed=0.01))
    assert rec.meta["physics"]["solver_warnings"]["iterations"] == 250
    assert "flex_iterations" in solver_warning("o", solver_warnings([SimpleNamespace(solver_warning_steps=3)]))
    del raw["scenario"]["flex_iterations"]
    sc = parse_scenario(raw)
    assert sc.flex_iterations is None
    assert scenario_source_maker(sc)((sc.objects[0].spec,), 0, "robot").flex_iterations == flex.SOLVER_ITERATIONS
    for bad in (0, -5, 2.5, True):
        raw["scenario"]["flex_iterations"] = bad
        with pytest.raises(ValidationError, match="flex_iterations"):
            parse_scenario(raw)
    with pytest.raises(ValidationError, match="flex_iterations"):
        simulate_press(2e5, fidelity="flex", flex_iterations=0)
