"""rigid fidelity: MuJoCo-driven finger with the Hertz-shaped local contact law."""

import numpy as np
import pytest

from palpate.core.errors import FitError
from palpate.core.perception.fit import fit_power_law
from palpate.core.session.sources import PressTarget
from palpate.core.world.scene import Material, ObjectSpec, Scene, TaxelSensorSpec
from palpate.sim import simulate_press
from palpate.sim.analytic import hertz_sensel_pressure, law_sensel_pressure
from palpate.sim.contact.stack import object_law
from palpate.sim.controller import press_profile
from palpate.sim.fingertip import sensel_bounds
from palpate.sim.hertz import hertz_force, sneddon_sphere_force_at_depth
from palpate.sim.rigid import run_rigid_press
from palpate.sim.source import SimSource

R = 0.008


def _rigid_trace(young, depth=0.002, shape="box", height=0.03):
    size = (max(0.1, 3.5 * height),) * 2 + (height,) if shape == "box" else (0.05, height)
    obj = ObjectSpec("o", shape, size, (0.0, 0.0), Material("m", young))
    scene = Scene((obj,))
    prof = press_profile(PressTarget(0.0, 0.0, depth=depth), height, radius=R, timestep=0.002)
    return scene, obj, run_rigid_press(scene, obj, prof)


def test_force_on_a_thick_block_is_sneddons_sphere_with_exponent_three_halves():
    _, _, tr = _rigid_trace(2e5, height=0.6)
    d, f = tr.indentation, tr.force
    loading = np.arange(len(d)) < np.argmax(d)
    small = loading & (d > 1e-4) & (d < 1e-3)
    assert small.sum() > 20
    slope = np.polyfit(np.log(d[small]), np.log(f[small]), 1)[0]
    assert slope == pytest.approx(1.5, abs=0.05)
    np.testing.assert_allclose(f[small], sneddon_sphere_force_at_depth(2e5 / 0.91, R, d[small]), rtol=0.01)


def test_sensel_pressure_is_the_hertz_distribution_on_a_thick_block_and_the_analytic_law_on_a_thin_one():
    scene, _, tr = _rigid_trace(2e5, depth=0.001, height=0.6)
    i = int(np.argmax(tr.indentation))
    ref = hertz_sensel_pressure(tr.indentation[i:i + 1], 2e5 / 0.91, R, sensel_bounds(scene.fingertip))[0]
    np.testing.assert_allclose(tr.sensel_pressure[i], ref, rtol=0, atol=0.03 * ref.max())
    assert np.all(tr.sensel_pressure >= 0)
    scene, obj, tr = _rigid_trace(2e5, depth=0.003, height=0.008)
    i = int(np.argmax(tr.indentation))
    law = object_law(obj, 0.0, 0.0, obj.height, R, 0.004)
    same = law_sensel_pressure(law, tr.indentation[i:i + 1], sensel_bounds(scene.fingertip))[0]
    np.testing.assert_allclose(tr.sensel_pressure[i], same, rtol=0, atol=0.02 * same.max())
    # along the whole press, not only at its deepest step (the pressures are interpolated in a height table)
    touching = tr.indentation > 0
    every = law_sensel_pressure(law, tr.indentation[touching], sensel_bounds(scene.fingertip))
    np.testing.assert_allclose(tr.sensel_pressure[touching], every, rtol=0, atol=0.02 * same.max())
    assert tr.force[i] == pytest.approx(float(law.force_at(tr.indentation[i])), rel=0.005)


def test_finger_tracks_the_commanded_depth():
    _, _, tr = _rigid_trace(2e4, depth=0.004)
    assert tr.indentation.max() == pytest.approx(0.004, abs=2e-4)
    assert tr.indentation[-1] == 0.0 and tr.force[-1] == 0.0  # released


def test_same_seed_gives_the_same_stream():
    a = simulate_press(2e5, fidelity="rigid", variability="human", seed=4)
    b = simulate_press(2e5, fidelity="rigid", variability="human", seed=4)
    np.testing.assert_array_equal(a.truth.force, b.truth.force)
    assert all(np.array_equal(x.counts, y.counts) for x, y in zip(a.frames, b.frames, strict=True))
    assert all(np.array_equal(x.position, y.position) for x, y in zip(a.poses, b.poses, strict=True))


def test_cylinder_rim_press_runs_rigid_and_sees_less_force_than_the_centre():
    obj = ObjectSpec("c", "cylinder", (0.02, 0.03), (0.0, 0.0), Material("m", 2e5))
    src = SimSource(Scene((obj,)), fidelity="auto")
    centre = src.press(PressTarget(0.0, 0.0, depth=0.002))
    rim = src.press(PressTarget(0.0185, 0.0, depth=0.002))
    # the centre's contact is flat and far from the rim (analytic, the cheapest within tolerance); at the rim the
    # contact crosses the edge, which only rigid (and flex) follow
    assert centre.meta["fidelity"] == "analytic" and rim.meta["fidelity"] == "rigid"
    assert rim.truth.force.max() < 0.8 * centre.truth.force.max()  # part of the tip hangs over the edge


def _press_params(rec):
    """(n1, a1) from the press phase: c_P = sum of counts, c_D = true indentation, c_A = active area."""
    t = np.array([f.t for f in rec.frames])
    counts = np.stack([f.counts for f in rec.frames]).astype(float)
    c_p = counts.reshape(len(t), -1).sum(axis=1)
    c_a = (counts > 0).reshape(len(t), -1).sum(axis=1) * rec.frames[0].sensel_area
    c_d = np.interp(t, rec.truth.t, rec.truth.indentation)
    t0, t1 = rec.meta["phases"]["press"]
    sel = (t >= t0) & (t <= t1) & (c_p > 0)
    n1 = fit_power_law(c_d[sel], c_p[sel]).k1
    try:
        a1 = fit_power_law(c_a[sel], c_p[sel]).k1
    except FitError:  # c_A never changes: the contact stays inside the same sensels for the whole press
        a1 = np.inf
    return n1, a1


def test_three_reference_materials_give_ordered_separable_interaction_parameters():
    from palpate.sim.hertz import hertz_depth_for_force

    params = {}
    for young in (2e4, 2e5, 2e6):
        depth = min(0.004, hertz_depth_for_force(young / 0.91, R, 5.0))
        params[young] = np.array([
            _press_params(simulate_press(young, fidelity="rigid", depth=depth, variability="human", seed=s,
                                         taxels=TaxelSensorSpec()))
            for s in range(3)
        ])
    n1 = {y: p[:, 0] for y, p in params.items()}
    a1 = {y: p[:, 1] for y, p in params.items()}
    for soft, hard in ((2e4, 2e5), (2e5, 2e6)):
        assert n1[soft].max() < n1[hard].min()  # separable, not just ordered on average
        assert n1[hard].mean() > 3 * n1[soft].mean()
        assert a1[soft].max() < a1[hard].min()
    assert np.all(np.isfinite(a1[2e4])) and np.all(np.isfinite(a1[2e5]))
    # a 2 MPa press to 5 N has a contact radius < 2.5 mm: it never reaches the outer ring of sensels (4.25 mm
    # from the axis), so c_A barely changes and a1 is huge or undefined: the 4x4 pad's resolution limit
    assert a1[2e6].min() > 10 * a1[2e5].max()


def test_mesh_ball_is_pressed_along_its_normal_and_is_softer_than_a_flat_top(tmp_path):
    trimesh = pytest.importorskip("trimesh")
    path = tmp_path / "ball.stl"
    trimesh.creation.icosphere(subdivisions=3, radius=0.5).export(path)  # unit extent: size = scale = extent
    ball = ObjectSpec("ball", "mesh", (0.06, 0.06, 0.06), (0.0, 0.0), Material("m", 2e5), mesh_path=str(path))
    src = SimSource(Scene((ball,)), fidelity="auto")
    top = src.press(PressTarget(0.0, 0.0, depth=0.002))
    side = src.press(PressTarget(0.015, 0.0, depth=0.002))
    assert top.meta["fidelity"] == "rigid"
    normal = np.array(side.meta["profile"]["normal"])
    assert normal[0] == pytest.approx(0.5, abs=0.08)  # sin(30 deg) at x = r/2 on the ball, faceted
    d = top.truth.indentation.max()
    f = top.truth.force.max()
    r_eff = 1.0 / (1.0 / R + 1.0 / 0.03)
    assert hertz_force(2e5 / 0.91, r_eff, d) * 0.75 < f < hertz_force(2e5 / 0.91, R, d)
    with pytest.raises(Exception, match="not on mesh object"):
        src.press(PressTarget(0.029, 0.029))
