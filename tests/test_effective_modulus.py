"""Depth-weighted effective modulus (sim.effective_modulus) and its use by the analytic and rigid fidelities."""

import numpy as np
import pytest
from scipy.integrate import quad

from palpate.core.errors import ValidationError
from palpate.core.session.sources import PressTarget
from palpate.core.world.scene import FingertipSpec, Inclusion, Layer, Material, ObjectSpec, Scene
from palpate.sim.analytic import hertz_sensel_pressure, run_analytic_press
from palpate.sim.controller import press_profile
from palpate.sim.effective_modulus import (
    depth_for_force,
    depth_weight_integral,
    effective_modulus,
    effective_modulus_table,
)
from palpate.sim.fingertip import sensel_bounds
from palpate.sim.hertz import hertz_force

R = 0.008
SOFT = Material("soft", 2e4, 0.3)
HARD = Material("hard", 2e5, 0.3)
H = 0.02


def _block(material=SOFT, height=H, layers=(), inclusions=(), width=0.1):
    return ObjectSpec("block", "box", (width, width, height), (0.0, 0.0), material, layers=tuple(layers),
                      inclusions=tuple(inclusions))


def _analytic(obj, depth=0.005, x=0.0, y=0.0):
    scene = Scene(objects=(obj,), fingertip=FingertipSpec(radius=R))
    profile = press_profile(PressTarget(x=x, y=y, depth=depth), obj.height, radius=R, timestep=0.002)
    return run_analytic_press(scene, obj, profile)


def _force_at(trace, depth):
    press = np.arange(len(trace.t)) <= int(np.argmax(trace.indentation))
    return float(np.interp(depth, trace.indentation[press], trace.force[press]))


# ---------------------------------------------------------------- the weight


@pytest.mark.parametrize("a", [1e-4, 3e-3, 6e-3])
def test_depth_weight_integral_matches_quadrature_of_the_axial_stress(a):
    for z in (0.3 * a, a, 4 * a, 25 * a):
        num, _ = quad(lambda t: 1.0 - t**3 / (a * a + t * t) ** 1.5, 0.0, z, epsabs=0, epsrel=1e-12)
        assert depth_weight_integral(z, a) == pytest.approx(num, rel=1e-9)
    assert depth_weight_integral(1e4 * a, a) == pytest.approx(2 * a, rel=1e-4)


# ---------------------------------------------------------------- homogeneous: exactly as before


@pytest.mark.parametrize("height", [0.002, 0.02, 0.1])
def test_homogeneous_object_of_any_thickness_gives_exactly_its_e_star(height):
    radii = np.array([0.0, 1e-4, 2e-3, 6e-3, 9e-3])
    for obj in (_block(HARD, height), ObjectSpec("c", "cylinder", (0.03, height), (0.0, 0.0), SOFT)):
        e = effective_modulus_table(obj, 0.001, -0.002, height, radii)
        assert np.all(e == obj.material.effective_modulus)
    # near an edge part of the footprint is off the object: still one material, still exact
    assert effective_modulus(_block(HARD), 0.049, 0.0, H, 6e-3) == HARD.effective_modulus


def test_analytic_press_on_one_material_is_bitwise_hertz_with_its_e_star():
    obj = _block(HARD)
    tr = _analytic(obj, depth=0.004)
    e = HARD.effective_modulus
    assert np.array_equal(tr.force, hertz_force(e, R, tr.indentation))
    tip = FingertipSpec(radius=R)
    assert np.array_equal(tr.sensel_pressure, hertz_sensel_pressure(tr.indentation, e, R, sensel_bounds(tip),
                                                                    np.zeros(2)))
    assert tr.meta["young_eff"] == e and tr.material == "hard"


def test_depth_for_force_on_one_material_is_exactly_the_hertz_depth():
    from palpate.sim.hertz import hertz_depth_for_force

    assert depth_for_force(_block(SOFT), 0.0, 0.0, H, R, 3.0) == hertz_depth_for_force(SOFT.effective_modulus, R, 3.0)


# ---------------------------------------------------------------- layers


def test_laterally_uniform_layer_is_the_series_average_of_the_depth_weight():
    t = 0.004
    obj = _block(HARD, layers=[Layer(SOFT, t)])
    a = 4e-3
    z_max = min(10 * a, H)
    f = depth_weight_integral(t, a) / depth_weight_integral(z_max, a)
    closed = 1.0 / (f / SOFT.effective_modulus + (1 - f) / HARD.effective_modulus)
    # only the depth cell that straddles the interface is misassigned: converges with n
    coarse = effective_modulus(obj, 0.0, 0.0, H, a, n=48)
    fine = effective_modulus(obj, 0.0, 0.0, H, a, n=800)
    assert fine == pytest.approx(closed, rel=2e-3)
    assert abs(coarse / closed - 1) < 0.05


def test_soft_skin_over_hard_base_feels_the_skin_shallow_and_the_base_deep():
    skin = 0.0015
    obj = _block(HARD, layers=[Layer(SOFT, skin)])
    radii = np.linspace(0.0, np.sqrt(R * 0.006), 30)
    e = effective_modulus_table(obj, 0.0, 0.0, H, radii)
    # while the cut-off (10 a) stays inside the skin only the skin is felt, exactly
    assert np.all(e[10 * radii <= skin * 0.9] == SOFT.effective_modulus)
    assert np.all(np.diff(e) >= 0) and e[-1] > 2.0 * SOFT.effective_modulus
    assert np.all(e < HARD.effective_modulus)

    soft_tr, hard_tr, layered = _analytic(_block(SOFT)), _analytic(_block(HARD)), _analytic(obj)
    # the tip follows the same profile exactly: compare sample by sample while loading
    assert np.array_equal(soft_tr.indentation, layered.indentation)
    load = (np.arange(len(layered.t)) <= int(np.argmax(layered.indentation))) & (layered.indentation > 0)
    fs, fh, fl = soft_tr.force[load], hard_tr.force[load], layered.force[load]
    assert np.all((fs <= fl) & (fl < fh))
    ratio = fl / fs
    assert np.all(np.diff(ratio) >= 0) and ratio[-1] > 2.0  # stiffer as the press goes deeper
    d = layered.indentation[load]
    e_at = effective_modulus_table(obj, 0.0, 0.0, H, np.sqrt(R * d[[0, -1]]))
    np.testing.assert_allclose(ratio[[0, -1]], e_at / SOFT.effective_modulus, rtol=0.02)
    assert layered.material == "soft" and layered.meta["young_eff_surface"] == SOFT.effective_modulus


def test_thin_stiff_skin_over_soft_base_is_softer_than_the_skin_alone():
    # documented limit: series averaging has no plate bending, so this is a lower bound of the true stiffness
    obj = _block(SOFT, layers=[Layer(HARD, 0.001)])
    e = effective_modulus(obj, 0.0, 0.0, H, np.sqrt(R * 0.004))
    assert SOFT.effective_modulus < e < 0.5 * HARD.effective_modulus


def test_layer_ratio_orders_like_flex_for_the_flex_test_configuration():
    # tests/test_sim_flex.py: a 4 mm 20 kPa layer over a 10x base, 20 mm high, pressed 2.5 mm: flex > 1.5x the
    # soft bulk (and < 2x at 1 mm). The first-order average must order the same way.
    obj = ObjectSpec("block", "box", (0.06, 0.06, 0.02), (0, 0), Material("bulk", 2e5), layers=(Layer(SOFT, 0.004),))
    deep = effective_modulus(obj, 0.0, 0.0, 0.02, np.sqrt(R * 0.0025)) / SOFT.effective_modulus
    shallow = effective_modulus(obj, 0.0, 0.0, 0.02, np.sqrt(R * 0.001)) / SOFT.effective_modulus
    assert deep > 1.5 and shallow < 2.0 and shallow < deep


# ---------------------------------------------------------------- inclusions


def test_hard_lump_under_the_surface_stiffens_the_press_above_it_only():
    lump = Inclusion(HARD, "sphere", (0.0, 0.0, H - 0.005), (0.004,))
    obj = _block(SOFT, inclusions=[lump])
    a = np.sqrt(R * 0.004)
    above = effective_modulus(obj, 0.0, 0.0, H, a)
    beside = effective_modulus(obj, 0.006, 0.0, H, a)
    away = effective_modulus(obj, 0.02, 0.0, H, a)
    assert above > 1.3 * SOFT.effective_modulus
    assert SOFT.effective_modulus < beside < above  # an inclusion beside the axis counts in part
    assert away == SOFT.effective_modulus
    fa = _force_at(_analytic(obj, 0.004), 0.004)
    fw = _force_at(_analytic(obj, 0.004, x=0.02), 0.004)
    assert fa > 1.3 * fw and fw == pytest.approx(hertz_force(SOFT.effective_modulus, R, 0.004), rel=1e-12)


def test_press_inside_the_edge_of_a_hard_column_stays_hard():
    # columns act in parallel: the soft foam at the rim of the footprint must not halve a hard column's modulus
    col = Inclusion(HARD, "column", (0.0, 0.0, 0.0), (0.02, 0.02))
    obj = _block(SOFT, inclusions=[col])
    e = effective_modulus(obj, 0.0, 0.005, H, np.sqrt(R * 0.005))
    assert e > 0.75 * HARD.effective_modulus


def test_depth_for_force_reaches_the_force_on_a_layered_block():
    from palpate.sim.hertz import hertz_depth_for_force

    obj = _block(HARD, layers=[Layer(SOFT, 0.0015)])
    force = 2.0
    d = depth_for_force(obj, 0.0, 0.0, H, R, force)
    assert hertz_depth_for_force(HARD.effective_modulus, R, force) < d < hertz_depth_for_force(
        SOFT.effective_modulus, R, force)
    e = effective_modulus(obj, 0.0, 0.0, H, np.sqrt(R * d))
    assert hertz_force(e, R, d) == pytest.approx(force, rel=0.01)


# ---------------------------------------------------------------- rigid fidelity


def test_rigid_press_on_a_layered_block_scales_with_the_effective_modulus():
    pytest.importorskip("mujoco")
    from palpate.sim.rigid import run_rigid_press

    layered = _block(HARD, layers=[Layer(SOFT, 0.0015)])
    traces = {}
    for name, obj in (("soft", _block(SOFT)), ("hard", _block(HARD)), ("layered", layered)):
        scene = Scene(objects=(obj,), fingertip=FingertipSpec(radius=R))
        profile = press_profile(PressTarget(x=0.0, y=0.0, depth=0.004, speed=0.02), H, radius=R, timestep=0.002)
        traces[name] = run_rigid_press(scene, obj, profile, timestep=0.002, rings=48, sectors=12)
    d = 0.003
    fs, fh, fl = (_force_at(traces[k], d) for k in ("soft", "hard", "layered"))
    assert fs < fl < fh
    # the kernel is linear in E*: the layered force is the soft force times E*_eff(sqrt(R d)) / E*_soft
    e = effective_modulus(layered, 0.0, 0.0, H, np.sqrt(R * d))
    assert fl / fs == pytest.approx(e / SOFT.effective_modulus, rel=0.03)
    assert traces["layered"].material == "soft"
    tr = traces["layered"]
    deep = int(np.argmax(tr.indentation))
    # sensel pressures follow the force: their sum times the sensel area stays below the total force
    assert 0 < tr.sensel_pressure[deep].sum() * FingertipSpec().sensel_area <= tr.force[deep] * 1.05


# ---------------------------------------------------------------- bad input


def test_bad_input_is_refused_with_a_clear_error():
    obj = _block(SOFT)
    with pytest.raises(ValidationError, match="contact radii"):
        effective_modulus(obj, 0.0, 0.0, H, -1e-3)
    with pytest.raises(ValidationError, match="contact radii"):
        effective_modulus(obj, 0.0, 0.0, H, float("nan"))
    with pytest.raises(ValidationError, match="'block' has no material under"):
        effective_modulus(obj, 0.2, 0.0, H, 1e-3)
    with pytest.raises(ValidationError, match="surface_z"):
        effective_modulus(obj, 0.0, 0.0, 0.0, 1e-3)
    with pytest.raises(ValidationError, match="n, rings, sectors"):
        effective_modulus(obj, 0.0, 0.0, H, 1e-3, n=0)


@pytest.mark.physics
def test_layer_stiffening_agrees_with_flex_within_15_percent():
    # measured: flex 1.56 / 1.78 / 1.98 / 2.04 against E*_eff 1.56 / 1.70 / 1.82 / 1.92 at 1 / 1.5 / 2 / 2.5 mm
    pytest.importorskip("mujoco")
    from palpate.sim import flex

    def press_part(tr):
        press = tr.t <= tr.meta["press_end"]
        return tr.indentation[press], tr.force[press]

    bulk = flex.reference_press(young=2e4, depth=0.003, resolution=0.005)
    layered = flex.reference_press(young=2e5, depth=0.003, resolution=0.005, layers=(Layer(SOFT, 0.004),))
    db, fb = press_part(bulk)
    dl, fl = press_part(layered)
    obj = ObjectSpec("block", "box", (0.06, 0.06, 0.02), (0, 0), Material("bulk", 2e5), layers=(Layer(SOFT, 0.004),))
    for d in (0.001, 0.0015, 0.002, 0.0025):
        flex_ratio = np.interp(d, dl, fl) / np.interp(d, db, fb)
        eff_ratio = effective_modulus(obj, 0.0, 0.0, 0.02, np.sqrt(R * d)) / SOFT.effective_modulus
        assert eff_ratio == pytest.approx(flex_ratio, rel=0.15), d
