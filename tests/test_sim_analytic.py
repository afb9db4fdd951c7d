"""analytic fidelity: Hertz force, contact radius and sensel pressure; controller; fidelity choice."""

import numpy as np
import pytest

from palpate.core.errors import ValidationError
from palpate.core.session.sources import PressTarget
from palpate.core.world.scene import FingertipSpec, Inclusion, Material, ObjectSpec, Scene, TaxelSensorSpec
from palpate.sim import simulate_press
from palpate.sim.analytic import hertz_sensel_pressure, run_analytic_press
from palpate.sim.controller import HUMAN, ROBOT, press_profile
from palpate.sim.fingertip import sensel_bounds
from palpate.sim.hertz import (
    hertz_contact_radius,
    hertz_depth_for_force,
    hertz_force,
    sneddon_sphere_force_at_depth,
)
from palpate.sim.reference.bonded_layer import dimitriadis_factor
from palpate.sim.source import SimSource
from palpate.sim.validity.choice import choose_fidelity

R = 0.008
E_STAR = 2e5 / (1 - 0.3**2)


def _brute_force_mean(depth, bounds, centre, n=1601):
    """Independent midpoint-rule mean of p0 sqrt(1 - r^2/a^2) over each sensel (slow, coarse)."""
    a = np.sqrt(R * depth)
    p0 = 3 * hertz_force(E_STAR, R, depth) / (2 * np.pi * a**2)
    out = np.zeros(bounds.shape[:2])
    for i, j in np.ndindex(out.shape):
        x0, x1, y0, y1 = bounds[i, j]
        xs = x0 + (x1 - x0) * (np.arange(n) + 0.5) / n
        ys = y0 + (y1 - y0) * (np.arange(n) + 0.5) / n
        gx, gy = np.meshgrid(xs - centre[0], ys - centre[1])
        out[i, j] = np.mean(p0 * np.sqrt(np.maximum(1 - (gx**2 + gy**2) / a**2, 0.0)))
    return out


@pytest.mark.parametrize("depth", [1e-4, 1e-3, 4e-3])
def test_pressure_integrates_to_the_hertz_force_to_machine_precision(depth):
    one_big = np.array([[[-0.02, 0.02, -0.02, 0.02]]])
    p = hertz_sensel_pressure(np.array([depth]), E_STAR, R, one_big, centre=np.array([0.0013, -0.0007]))
    force = p[0, 0, 0] * 0.04**2
    assert force == pytest.approx(hertz_force(E_STAR, R, depth), rel=1e-12)
    assert hertz_depth_for_force(E_STAR, R, force) == pytest.approx(depth, rel=1e-12)


def test_pressure_vanishes_exactly_outside_the_hertz_contact_radius():
    depth = 2e-3
    a = float(hertz_contact_radius(R, depth))
    assert a == pytest.approx(np.sqrt(R * depth))
    tiny = 1e-6
    just_out = np.array([[[a * (1 + 1e-6), a * (1 + 1e-6) + tiny, -tiny / 2, tiny / 2]]])
    just_in = np.array([[[a * (1 - 1e-3), a * (1 - 1e-3) + tiny, -tiny / 2, tiny / 2]]])
    assert hertz_sensel_pressure(np.array([depth]), E_STAR, R, just_out)[0, 0, 0] == 0.0
    inside = hertz_sensel_pressure(np.array([depth]), E_STAR, R, just_in)[0, 0, 0]
    p0 = 3 * hertz_force(E_STAR, R, depth) / (2 * np.pi * a**2)
    r = a * (1 - 1e-3) + tiny / 2
    assert inside == pytest.approx(p0 * np.sqrt(1 - r**2 / a**2), rel=1e-3)


@pytest.mark.parametrize("centre", [(0.0, 0.0), (0.0011, -0.0004)])
def test_sensel_means_match_an_independent_brute_force_integral(centre):
    bounds = sensel_bounds(FingertipSpec())
    depth = 3e-3
    fast = hertz_sensel_pressure(np.array([depth]), E_STAR, R, bounds, centre=np.array(centre))[0]
    slow = _brute_force_mean(depth, bounds, centre)
    np.testing.assert_allclose(fast, slow, rtol=0, atol=2e-4 * slow.max())
    # the shared-symmetry shortcut and the per-sensel path agree
    plain = hertz_sensel_pressure(np.array([depth]), E_STAR, R, bounds, np.array(centre), share_symmetric=False)[0]
    np.testing.assert_allclose(fast, plain, rtol=0, atol=1e-10 * plain.max())


def test_sensel_integral_is_exact_against_adaptive_quadrature():
    """The closed-form footprint integral against nested adaptive quadrature of the Hertz pressure (each integral
    over the chord of the disc only, the outer one split where the chord's ends cross the footprint's edges), on
    footprints inside, across and outside the contact (corners beyond the circle, slivers at its rim, footprints
    larger than the contact), to 1e-10 of the disc's scale."""
    from scipy.integrate import quad

    def reference(a, x0, x1, y0, y1):
        def column(x):
            c = np.sqrt(max(a * a - x * x, 0.0))
            lo, hi = max(y0, -c), min(y1, c)
            return quad(lambda y: np.sqrt(max(c * c - y * y, 0.0)), lo, hi, epsabs=1e-16, epsrel=1e-13,
                        limit=200)[0] if hi > lo else 0.0
        lo, hi = max(x0, -a), min(x1, a)
        if hi <= lo:
            return 0.0
        kinks = sorted({k for y in (y0, y1) if abs(y) < a for k in (-np.sqrt(a * a - y * y), np.sqrt(a * a - y * y))
                        if lo < k < hi})
        edges = [lo, *kinks, hi]
        pieces = zip(edges[:-1], edges[1:], strict=True)
        return sum(quad(column, u, v, epsabs=1e-16, epsrel=1e-13, limit=200)[0] for u, v in pieces)

    rng = np.random.default_rng(7)
    a = 2.5e-3
    cases = [(-0.004, 0.004, -0.004, 0.004), (0.001, 0.0035, 0.0015, 0.004), (a - 1e-5, a + 1e-3, -1e-4, 1e-4),
             (-0.003, -0.0022, 0.0005, 0.0011), (0.0026, 0.003, 0.0, 0.001)]
    cases += [tuple(np.sort(rng.uniform(-0.004, 0.004, 2)).tolist() + np.sort(rng.uniform(-0.004, 0.004, 2)).tolist())
              for _ in range(12)]
    depth = a * a / R
    bounds = np.array(cases)[None]  # (1, P, 4): one row of footprints
    got = hertz_sensel_pressure(np.array([depth]), E_STAR, R, bounds, centre=np.zeros((1, 2)))[0, 0]
    area = (bounds[0, :, 1] - bounds[0, :, 0]) * (bounds[0, :, 3] - bounds[0, :, 2])
    scale = 2.0 * E_STAR / (np.pi * R)
    for (x0, x1, y0, y1), p, s in zip(cases, got, area, strict=True):
        exact = reference(a, x0, x1, y0, y1)
        assert p * s / scale == pytest.approx(exact, rel=0, abs=1e-10 * a**3)


def test_centred_press_on_a_thick_block_gives_symmetric_counts_and_sneddons_sphere():
    quiet = TaxelSensorSpec(noise_std=0.0, threshold=0)
    # 0.6 m thick and 2 m wide: no edge within reach; the rigid table stiffens it by ~0.7% (a / h < 0.01)
    rec = simulate_press(2e5, fidelity="analytic", depth=0.003, taxels=quiet, size=2.0, thickness=0.6)
    counts = np.stack([f.counts for f in rec.frames]).astype(int)
    assert counts.max() > 50  # the press registers
    for view in (counts[:, ::-1, :], counts[:, :, ::-1], counts.transpose(0, 2, 1)):
        np.testing.assert_array_equal(counts, view)
    truth = rec.truth
    touching = truth.indentation > 2e-4
    d = truth.indentation[touching]
    exact = sneddon_sphere_force_at_depth(E_STAR, R, d) * dimitriadis_factor(np.sqrt(R * d) / 0.6, 0.3)
    np.testing.assert_allclose(truth.force[touching], exact, rtol=2e-3)
    # the sphere is softer than Hertz's paraboloid by ~2.5% at 3 mm deep: the law is not Hertz
    assert truth.force.max() < 0.985 * hertz_force(E_STAR, R, 0.003)
    assert truth.indentation.max() == pytest.approx(0.003, rel=1e-9)
    assert rec.meta["fidelity"] == "analytic"


@pytest.mark.parametrize(("thickness", "base", "poisson"), [(0.01, "bonded", 0.3), (0.012, "bonded", 0.49),
                                                             (0.02, "bonded", 0.45)])
def test_a_thin_block_stiffens_as_the_bonded_layer_series_says(thickness, base, poisson):
    """Against Dimitriadis et al. 2002 (independent, published) where it holds: contact radius < half the layer."""
    rec = simulate_press(2e5, poisson, fidelity="analytic", depth=0.002, thickness=thickness)
    d, f = rec.truth.indentation, rec.truth.force
    sel = (d > 2e-4) & (np.sqrt(R * d) < 0.5 * thickness)
    e_star = 2e5 / (1 - poisson**2)
    series = dimitriadis_factor(np.sqrt(R * d[sel]) / thickness, poisson, base)
    exact_sphere = sneddon_sphere_force_at_depth(e_star, R, d[sel]) / hertz_force(e_star, R, d[sel])
    np.testing.assert_allclose(f[sel], hertz_force(e_star, R, d[sel]) * series * exact_sphere, rtol=0.025)
    assert f[sel][-1] > 1.08 * sneddon_sphere_force_at_depth(e_star, R, d[sel][-1])  # the table is felt


def test_analytic_trace_follows_the_profile_exactly():
    obj = ObjectSpec("b", "box", (0.1, 0.1, 0.03), (0.0, 0.0), Material("m", 2e5))
    prof = press_profile(PressTarget(0.0, 0.0, depth=0.002, hold=0.1), 0.03, radius=R, timestep=0.001)
    trace = run_analytic_press(Scene((obj,)), obj, prof)
    np.testing.assert_allclose(trace.indentation, np.maximum(0.038 - prof.at(trace.t), 0.0), atol=1e-15)
    assert trace.material == "m"


def test_robot_profile_is_exact_and_human_profile_is_seeded():
    target = PressTarget(0.01, -0.02, depth=0.004, speed=0.01, hold=0.2)
    robot = press_profile(target, 0.03, radius=R, timestep=0.001, variability=ROBOT, seed=5)
    assert (robot.x, robot.y) == (0.01, -0.02)
    assert robot.indentation().max() == pytest.approx(0.004, rel=1e-12)
    press = robot.meta["phases"]["press"]
    assert press[1] - press[0] == pytest.approx(0.004 / 0.01, rel=1e-9)  # constant speed
    assert robot.meta["phases"]["hold"][1] - robot.meta["phases"]["hold"][0] == pytest.approx(0.2)
    assert np.all(np.diff(robot.t) > 0) and np.all(np.diff(robot.t) <= 0.001 + 1e-12)
    h1 = press_profile(target, 0.03, radius=R, timestep=0.001, variability=HUMAN, seed=5)
    h2 = press_profile(target, 0.03, radius=R, timestep=0.001, variability=HUMAN, seed=5)
    h3 = press_profile(target, 0.03, radius=R, timestep=0.001, variability=HUMAN, seed=6)
    np.testing.assert_array_equal(h1.z, h2.z)
    assert (h1.x, h1.y) == (h2.x, h2.y)
    assert h1.meta["depth"] != h3.meta["depth"] and (h1.x, h1.y) != (h3.x, h3.y)
    assert abs(h1.x - 0.01) < 0.002 and abs(h1.meta["depth"] - 0.004) < 0.002
    # a human press's contact and lift times are where its minimum-jerk path meets the surface (to 10 nm)
    for h in (h1, h3):
        for when in (h.meta["phases"]["press"][0], h.meta["phases"]["release"][1]):
            assert abs(0.03 + R - float(h.at(np.array([when]))[0])) < 1e-8


def test_force_target_uses_the_inverse_law_and_needs_it():
    target = PressTarget(0.0, 0.0, depth=None, force=5.0)
    with pytest.raises(ValidationError, match="depth_for_force"):
        press_profile(target, 0.03, radius=R, timestep=0.001)
    prof = press_profile(target, 0.03, radius=R, timestep=0.001,
                         depth_for_force=lambda f: hertz_depth_for_force(E_STAR, R, f))
    assert hertz_force(E_STAR, R, prof.indentation().max()) == pytest.approx(5.0, rel=1e-9)


def test_auto_fidelity_follows_the_validity_table_and_the_geometry():
    soft = Material("soft", 2e4)
    hard = Material("hard", 2e6)
    thick = ObjectSpec("thick", "box", (0.1, 0.1, 0.04), (0.0, 0.0), soft)
    thin = ObjectSpec("thin", "box", (0.1, 0.1, 0.005), (0.0, 0.0), soft)
    lump = ObjectSpec("lump", "box", (0.1, 0.1, 0.04), (0.0, 0.0), soft,
                      inclusions=(Inclusion(hard, "sphere", (0.0, 0.0, 0.03), (0.005,)),))
    centre = PressTarget(0.0, 0.0, depth=0.002)
    # the contact law is within 1% of the reference on thick and thin blocks and on-axis lumps: analytic, the
    # cheapest, wherever the top under the contact is flat
    for obj in (thick, thin, lump):
        assert choose_fidelity(obj, centre, R) == "analytic", obj.name
    # the contact reaching a free edge: only rigid and flex follow the real top
    assert choose_fidelity(thick, PressTarget(0.049, 0.0, depth=0.002), R) == "rigid"


def test_bad_requests_are_rejected_with_their_name():
    scene = Scene((ObjectSpec("b", "box", (0.1, 0.1, 0.03), (0.0, 0.0), Material("m", 2e5)),))
    with pytest.raises(ValidationError, match="fidelity"):
        SimSource(scene, fidelity="fem")
    with pytest.raises(ValidationError, match="no object under"):
        SimSource(scene, fidelity="analytic").press(PressTarget(0.5, 0.5))
    with pytest.raises(ValidationError, match="unknown scene option"):
        simulate_press(2e5, fidelity="analytic", thikness=0.02)
    with pytest.raises(ValidationError, match="timestep"):
        press_profile(PressTarget(0, 0), 0.03, radius=R, timestep=0.0)
