"""Divergence is detected and reported with the parameter to change."""

import mujoco
import numpy as np
import pytest

from palpate.core.errors import SimulationDiverged
from palpate.core.world.scene import Material, ObjectSpec, Scene
from palpate.sim import simulate_press
from palpate.sim.scene import build_press_model
from palpate.sim.stability import check_run, check_warnings


def test_huge_stiffness_with_a_large_timestep_is_reported_naming_timestep_and_stiffness():
    # the rung halves the step for a stiff contact at most four times (0.02 s -> 1.25 ms); 1e11 Pa is beyond that
    with pytest.raises(SimulationDiverged, match=r"timestep \(now 0\.00125 s\).*young=1e\+11"):
        simulate_press(1e11, fidelity="rigid", depth=0.002, timestep=0.02)


def test_a_stiff_contact_gets_a_step_it_can_hold_and_a_soft_one_keeps_the_step_asked_for():
    from palpate.sim.contact.law import solve_contact_law
    from palpate.sim.reference.sample import AxisymmetricSample
    from palpate.sim.rigid import STABLE_OMEGA_DT, stable_timestep
    from palpate.sim.scene import FingerDrive

    drive = FingerDrive()
    steps = {}
    for young, depth in ((4.347e8, 3e-5), (2e5, 3e-3)):  # the main job's hard foam; a soft block
        law = solve_contact_law(AxisymmetricSample(bulk=Material("m", young, 0.4), thickness=0.04), 0.008, depth)
        omega = np.sqrt(float(law.stiffness_at(depth)) / (drive.armature + drive.mass))
        steps[young] = dt = stable_timestep(0.002, law, depth, drive)
        assert omega * dt <= STABLE_OMEGA_DT
    assert steps[2e5] == 0.002 and steps[4.347e8] in (0.001, 0.0005, 0.00025)


def test_a_training_session_whose_hard_foam_presses_overshot_now_finishes():
    # seed 1002's Material_3 presses (the foam's ~11 um share of a human press) overshot their depth by 10% at the
    # 2 ms step (omega dt ~1.8) and stopped the session with PressShortfall
    from palpate.core.world.resources import scenarios_dir
    from palpate.core.world.scenario_file import load_scenario
    from palpate.sim.realism.calibrate import simulate_seed
    from palpate.sim.realism.profile_file import resolve_profile

    scenario = load_scenario(scenarios_dir() / "thesis_ch6.toml")
    run = simulate_seed(scenario, resolve_profile(scenario.realism.profile), 1002, "rigid")
    assert len(run.table.of("Material_3")) == scenario.training.presses_per_material


def test_the_same_material_is_stable_at_the_default_timestep():
    rec = simulate_press(2e6, fidelity="rigid", depth=0.001)
    assert np.all(np.isfinite(rec.truth.force)) and rec.truth.force.max() > 1.0


def test_mujoco_state_warnings_are_not_silently_skipped():
    obj = ObjectSpec("b", "box", (0.1, 0.1, 0.03), (0.0, 0.0), Material("m", 2e5))
    model, data = build_press_model(Scene((obj,)), np.array([0.0, 0.0, 0.04]), np.array([0.0, 0.0, 1.0]),
                                    timestep=0.002)
    check_warnings(model, data, timestep=0.002)  # a fresh run is clean
    data.qfrc_applied[0] = 1e300  # MuJoCo flags the acceleration and resets the state
    mujoco.mj_step(model, data)
    mujoco.mj_step(model, data)
    assert np.isfinite(data.qpos[0])  # the reset hides the blow-up from the state alone
    with pytest.raises(SimulationDiverged, match="BADQACC.*timestep"):
        check_warnings(model, data, timestep=0.002)


def test_nan_runaway_penetration_and_speed_each_name_what_to_change():
    t = np.linspace(0, 1, 11)
    ok = dict(t=t, max_depth=0.004, speed=0.01, timestep=0.002, young=2e5)
    check_run(indentation=np.full(11, 0.003), velocity=np.full(11, 0.01), **ok)
    with pytest.raises(SimulationDiverged, match="NaN.*timestep"):
        check_run(indentation=np.where(t > 0.5, np.nan, 0.001), velocity=np.zeros(11), **ok)
    with pytest.raises(SimulationDiverged, match="penetration.*press speed"):
        check_run(indentation=np.where(t > 0.5, 0.02, 0.001), velocity=np.zeros(11), **ok)
    with pytest.raises(SimulationDiverged, match="speed.*stiffness"):
        check_run(indentation=np.zeros(11), velocity=np.where(t > 0.5, 5.0, 0.0), **ok)
