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
    with pytest.raises(SimulationDiverged, match=r"timestep \(now 0\.02 s\).*young=1e\+11"):
        simulate_press(1e11, fidelity="rigid", depth=0.002, timestep=0.02)


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
