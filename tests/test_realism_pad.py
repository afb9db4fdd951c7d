"""The pad's side of realism: sensels that turn on at their own pressures, and the shape of the pressure over the
two-body patch, checked against closed forms (Hertz's integral, the force the distribution carries)."""

from dataclasses import replace

import numpy as np
import pytest

from palpate.core.session.sources import PressTarget
from palpate.core.world.scene import Material, ObjectSpec, PoseSensorSpec, Scene, TaxelSensorSpec
from palpate.sim.analytic import hertz_sensel_pressure
from palpate.sim.hertz import hertz_force
from palpate.sim.realism.patch import _quadrature, patch_sensel_pressure, press_exponent
from palpate.sim.realism.profile import IDEAL, FingerPulp, TaxelRealism
from palpate.sim.realism.taxels import TaxelResponse, activation_map
from palpate.sim.source import SimSource

FULL_SCALE = 255.0 / 1.2e-3


def _active_counts(realism, activation, pressures):
    """Active sensels of a 4x4 pad under a uniform pressure at each of ``pressures`` (Pa)."""
    p = np.broadcast_to(pressures[:, None, None], (len(pressures), 4, 4)).copy()
    out = TaxelResponse(realism, np.ones((4, 4)), FULL_SCALE, activation)(np.zeros(len(pressures)), p)
    return (out > 0).reshape(len(pressures), -1).sum(axis=1)


def test_the_turn_on_pressures_are_a_mean_one_lognormal_map_with_the_asked_spread(rng):
    m = activation_map(TaxelRealism(activation=2000.0, activation_cv=0.4), (300, 300), rng)
    assert m.mean() == pytest.approx(2000.0, rel=0.01)
    assert m.std() / m.mean() == pytest.approx(0.4, rel=0.05)
    assert m.min() > 0
    # without a spread every sensel has the pad's one turn-on pressure and nothing is drawn
    state = rng.bit_generator.state
    assert np.all(activation_map(TaxelRealism(activation=2000.0), (4, 4), rng) == 2000.0)
    assert rng.bit_generator.state == state


def test_with_a_spread_the_active_count_grows_gradually_and_without_one_it_is_todays_step(rng):
    pressures = np.linspace(0.0, 8000.0, 161)
    one = TaxelRealism(activation=3000.0)
    spread = TaxelRealism(activation=3000.0, activation_cv=0.5)
    step = _active_counts(one, None, pressures)
    assert set(step.tolist()) == {0, 16}  # one turn-on pressure: all sensels at once
    # a spread of 0 gives exactly the response of one turn-on pressure
    same = activation_map(one, (4, 4), rng)
    np.testing.assert_array_equal(_active_counts(one, same, pressures), step)
    grows = _active_counts(spread, activation_map(spread, (4, 4), rng), pressures)
    assert np.all(np.diff(grows) >= 0)  # monotone in pressure
    assert grows[0] == 0 and grows[-1] > 12
    assert len(set(grows.tolist()) - {0, 16}) >= 6  # many intermediate counts where one threshold has none
    # each sensel still reads its whole pressure once on
    p = np.full((1, 4, 4), 5000.0)
    turn_on = np.full((4, 4), 4000.0)
    turn_on[0, 0] = 6000.0
    out = TaxelResponse(spread, np.ones((4, 4)), FULL_SCALE, turn_on)(np.zeros(1), p)
    assert out[0, 0, 0] == 0.0 and out[0, 1, 1] == pytest.approx(5000.0)


def _grid_bounds(n, cell):
    """An n x n grid of touching square cells of side ``cell`` m centred on the axis (no gaps between them)."""
    edges = (np.arange(n + 1) - n / 2) * cell
    x0, y0 = np.meshgrid(edges[:-1], edges[:-1], indexing="ij")
    return np.stack([x0, x0 + cell, y0, y0 + cell], axis=-1)


@pytest.mark.parametrize("k", [0.5, 1.0, 2.0])
def test_every_shape_carries_the_force_it_is_given(k):
    bounds = _grid_bounds(8, 1e-3)  # 8 mm square around a 3 mm patch: the whole distribution lands on it
    a2 = np.array([(3e-3) ** 2, (2e-3) ** 2])
    force = np.array([2.0, 0.5])
    p = _quadrature(a2, force, np.full(2, k), bounds, np.array([2e-4, -1e-4]))
    np.testing.assert_allclose(p.sum(axis=(1, 2)) * 1e-6, force, rtol=0.01)


def test_the_quadrature_reproduces_hertz_closed_form_integration():
    bounds = _grid_bounds(4, 2.5e-3)
    radius, patch = 8e-3, np.array([0.5e-3, 1.5e-3])
    force = hertz_force(1.0, radius, patch)
    exact = hertz_sensel_pressure(patch, 1.0, radius, bounds, np.array([3e-4, 0.0]))
    approx = _quadrature(radius * patch, force, np.full(2, 0.5), bounds, np.array([3e-4, 0.0]))
    np.testing.assert_allclose(approx, exact, rtol=0.02, atol=0.02 * exact.max())


def test_a_more_peaked_shape_loads_the_centre_more_and_the_rim_less():
    bounds = _grid_bounds(4, 2.5e-3)
    radius, patch, force = 8e-3, np.array([2e-3]), np.array([1.0])
    hertz = patch_sensel_pressure(patch, force, np.array([0.5]), radius, bounds, np.zeros(2))[0]
    layer = patch_sensel_pressure(patch, force, np.array([2.0]), radius, bounds, np.zeros(2))[0]
    assert layer[1, 1] > 1.3 * hertz[1, 1] and layer[0, 0] < 0.5 * hertz[0, 0]
    # the centre of a small centred sensel reads the distribution's peak F (k + 1) / (pi a^2)
    tiny = np.array([[[-1e-5, 1e-5, -1e-5, 1e-5]]])
    peak = patch_sensel_pressure(patch, force, np.array([2.0]), radius, tiny, np.zeros(2))[0, 0, 0]
    assert peak == pytest.approx(3.0 / (np.pi * radius * patch[0]), rel=1e-3)


def test_the_exponent_follows_the_pulps_share_of_the_approach():
    k = press_exponent(2.0, np.array([0.0, 1e-3, 1e-3, 0.0]), np.array([1e-3, 1e-3, 0.0, 0.0]))
    np.testing.assert_allclose(k, [2.0, 1.25, 0.5, 0.5])
    assert np.all(press_exponent(0.5, np.array([1e-3, 0.0]), np.array([0.0, 1e-3])) == 0.5)


def _peak_pressure(young, exponent):
    """The sensel pressures at the deepest point of one robot press on a block, with a compliant finger."""
    block = ObjectSpec("b", "box", (0.08, 0.08, 0.04), (0.0, 0.0), Material("m", young, 0.4))
    taxels = TaxelSensorSpec(gain=6e-3, noise_std=0.0)  # 6 counts/kPa: the rim resolved, the centre unsaturated
    scene = Scene((block,), taxels=taxels, pose=PoseSensorSpec(noise_std=0.0, jitter=0.0))
    pulp = FingerPulp(compliant=True, stiffness=300.0, stiffening=2000.0, pressure_exponent=exponent)
    src = SimSource(scene, fidelity="analytic", seed=1, variability="robot", realism=replace(IDEAL, finger=pulp))
    rec = src.press(PressTarget(0.0, 0.0, depth=0.004, force=1.0, speed=0.01))
    counts = np.array([f.counts for f in rec.frames], dtype=float)
    return counts[int(np.argmax(counts.sum(axis=(1, 2))))]


def test_the_pulps_exponent_peaks_the_pad_on_stiff_objects_and_leaves_soft_ones_near_hertz():
    def spread(young, exponent):  # centre over the middle of the pad's edges
        frame = _peak_pressure(young, exponent)
        assert frame.max() < 255
        return frame[1:3, 1:3].mean() / frame[[0, 0, 3, 3, 1, 2, 1, 2], [1, 2, 1, 2, 0, 0, 3, 3]].mean()

    stiff, soft = 5e6, 8e3
    gain_stiff = spread(stiff, 2.0) / spread(stiff, 0.5)
    gain_soft = spread(soft, 2.0) / spread(soft, 0.5)
    assert gain_stiff > 1.5 and gain_stiff > gain_soft
