"""The rigid rung steps its finger by MuJoCo's own step read as an affine map: the states are MuJoCo's to rounding,
a press through the map is the press MuJoCo steps, and a finger whose step is not affine is left to MuJoCo."""

from __future__ import annotations

import numpy as np
import pytest

from palpate.core.session.sources import PressTarget
from palpate.core.world.scene import FingertipSpec, Material, ObjectSpec, Scene
from palpate.sim import rigid
from palpate.sim.controller import press_profile
from palpate.sim.scene import FingerDrive

R = 0.008


def _scene(young: float = 2e5, damping: float = 0.0) -> Scene:
    block = ObjectSpec("block", "box", (0.1, 0.1, 0.03), (0.0, 0.0), Material("gel", young, 0.45, damping=damping))
    return Scene(objects=(block,), fingertip=FingertipSpec(radius=R))


@pytest.mark.parametrize("timestep", [0.002, 0.00025])
def test_the_finger_step_is_mujocos_step_of_the_press_model(timestep):
    import mujoco

    model, data, step = rigid.press_model(_scene(), np.array([0.0, 0.0, 0.04]), np.array([0.0, 0.0, 1.0]),
                                          timestep, FingerDrive())
    a00, a01, b0, e0, c0, a10, a11, b1, e1, c1, lim = step
    assert lim > 0.01  # the joint's 50 mm travel
    rng = np.random.default_rng(7)
    for q, v, u, f in zip(rng.uniform(-lim, lim, 50), rng.uniform(-0.1, 0.1, 50), rng.uniform(-lim, lim, 50),
                          rng.uniform(0.0, 80.0, 50), strict=True):
        mujoco.mj_resetData(model, data)
        data.qpos[0], data.qvel[0], data.ctrl[0], data.qfrc_applied[0] = q, v, u, f
        mujoco.mj_step(model, data)
        assert abs(a00 * q + a01 * v + b0 * u + e0 * f + c0 - data.qpos[0]) <= 1e-13 * (abs(q) + abs(v) + 1e-3)
        assert abs(a10 * q + a11 * v + b1 * u + e1 * f + c1 - data.qvel[0]) <= 1e-11 * (abs(q) + abs(v) + 1e-3)


def _press(scene, monkeypatch=None, lim=None, depth=0.003, speed=0.01):
    obj = scene.objects[0]
    profile = press_profile(PressTarget(0.0, 0.0, depth=depth, speed=speed), obj.height, radius=R, timestep=0.002)
    if monkeypatch is not None:
        real = rigid.finger_step
        monkeypatch.setattr(rigid, "finger_step", lambda model: real(model)[:-1] + (lim,))
    return rigid.run_rigid_press(scene, obj, profile)


@pytest.mark.parametrize("young, damping, depth, speed", [(2e5, 0.0, 0.003, 0.01), (2e5, 0.05, 0.003, 0.01),
                                                          (4e8, 0.0, 2e-5, 2e-4)])
def test_a_press_through_the_finger_step_is_the_press_mujoco_steps(monkeypatch, young, damping, depth, speed):
    scene = _scene(young, damping)
    mapped = _press(scene, depth=depth, speed=speed)
    with monkeypatch.context() as m:
        stepped = _press(scene, m, lim=0.0, depth=depth, speed=speed)  # MuJoCo steps every row
    with monkeypatch.context() as m:
        # the map within 1 mm of the start, MuJoCo beyond: states handed over both ways
        mixed = _press(scene, m, lim=0.001, depth=depth, speed=speed)
    if young > 1e8:
        assert stepped.meta["timestep"] < 0.002  # the hard block's halved step
    for trace in (mapped, mixed):
        assert np.array_equal(trace.t, stepped.t)
        for name, scale in (("force", np.max(stepped.force)), ("indentation", np.max(stepped.indentation)),
                            ("tip_position", 1e-3), ("sensel_pressure", np.max(stepped.sensel_pressure))):
            np.testing.assert_allclose(getattr(trace, name), getattr(stepped, name), rtol=0, atol=1e-9 * scale,
                                       err_msg=name)
    assert np.max(mapped.force) > 0.5 and np.any(np.abs(mapped.tip_position[:, 2] - mapped.tip_position[0, 2]) > 1e-3)


def test_a_finger_whose_step_is_not_affine_is_left_to_mujoco():
    import mujoco

    model, _, step = rigid.press_model(_scene(), np.array([0.0, 0.0, 0.04]), np.array([0.0, 0.0, 1.0]), 0.002,
                                       FingerDrive())
    assert step[-1] > 0
    model.dof_frictionloss[0] = 0.5  # dry friction in the joint: a step MuJoCo's constraint solver takes
    assert rigid.finger_step(model)[-1] == 0.0
    filtered = mujoco.MjModel.from_xml_string("""
        <mujoco><option gravity="0 0 0"/><worldbody><body><joint name="q" type="slide" range="-0.05 0.05"/>
        <geom type="sphere" size="0.008" mass="0.02"/></body></worldbody>
        <actuator><position joint="q" kp="5e4" kv="600" timeconst="0.01" ctrlrange="-0.05 0.05"/></actuator>
        </mujoco>""")
    assert filtered.na == 1  # the servo's filter is a state the step carries
    assert rigid.finger_step(filtered)[-1] == 0.0
    pulled = mujoco.MjModel.from_xml_string("""
        <mujoco><option gravity="0 0 -9.81"/><worldbody><body><joint name="q" type="slide" axis="0 0 1"
        range="-0.05 0.05"/><geom type="sphere" size="0.008" mass="0.02"/></body></worldbody>
        <actuator><position joint="q" kp="5e4" kv="600" ctrlrange="-0.05 0.05"/></actuator></mujoco>""")
    assert rigid.finger_step(pulled)[-1] > 0  # gravity along the slide: a constant, still affine
