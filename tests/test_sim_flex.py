"""The `flex` fidelity: MuJoCo trilinear flexcomp block pressed by the fingertip."""

from __future__ import annotations

import json

import numpy as np
import pytest

pytest.importorskip("mujoco")

from palpate.core.errors import SimulationDiverged, ValidationError  # noqa: E402
from palpate.core.world.scene import FingertipSpec, Layer, Material, ObjectSpec
from palpate.sim import flex, flex_model  # noqa: E402
from palpate.sim.flex_calibrate import hertz_ratio
from palpate.sim.flex_calibration import CAL_RANGE, load_calibration, modulus_factor
from palpate.sim.hertz import hertz_force

R = 0.008


def _press_part(tr):
    press = tr.t <= tr.meta["press_end"]
    return tr.indentation[press], tr.force[press]


def _exponent(d, f, lo=CAL_RANGE[0], hi=CAL_RANGE[1]):
    sel = (d >= lo) & (d <= hi) & (f > 0)
    return float(np.polyfit(np.log(d[sel]), np.log(f[sel]), 1)[0])


# ---------------------------------------------------------------- fast: geometry, skin model, calibration file


def test_grid_centres_a_node_under_the_press_and_pins_cut_faces():
    obj = ObjectSpec("b", "box", (0.1, 0.04, 0.02), (0.0, 0.0), Material("m", 1e5))
    g = flex_model.flex_grid(obj, 0.0, 0.0, resolution=0.0065, window=0.04)
    assert g.cells[0] % 2 == 0 and g.cells[1] % 2 == 0
    np.testing.assert_allclose(g.lower[:2] + g.size[:2] / 2, [0.0, 0.0])
    # 100 mm long in x: the 40 mm window cuts through the material there; y edges are the object's free faces
    assert g.pinned == (True, True, False, False)
    # near the +x edge the window is clipped to stay inside the object
    g2 = flex_model.flex_grid(obj, 0.049, 0.0, resolution=0.0065, window=0.04)
    assert g2.lower[0] + g2.size[0] == pytest.approx(0.05)
    assert g2.pinned[1] is False
    c = g.cell_centres()
    assert c.shape == (np.prod(g.cells), 3)
    # MuJoCo's cell order: z fastest, x slowest
    assert c[1, 2] > c[0, 2] and c[1, 0] == c[0, 0] and c[-1, 0] > c[0, 0]


def test_mesh_objects_are_refused_with_a_clear_error():
    obj = ObjectSpec("m", "mesh", (1, 1, 1), (0, 0), Material("m", 1e5), mesh_path="x.stl")
    with pytest.raises(ValidationError, match="'box' and 'cylinder'"):
        flex_model.flex_grid(obj, 0, 0)
    with pytest.raises(ValidationError, match="resolution"):
        flex_model.flex_grid(ObjectSpec("b", "box", (0.04, 0.04, 0.02), (0, 0), Material("m", 1e5)), 0, 0, -1.0)


def test_pad_coordinates_wrap_by_arc_length():
    theta = np.array([0.0, 0.3, 1.0])
    phi = np.array([0.0, 0.7, 2.0])
    pts = R * np.column_stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), -np.cos(theta)])
    xy = flex.pad_coordinates(pts, R)
    np.testing.assert_allclose(np.linalg.norm(xy, axis=1), R * theta, atol=1e-15)
    np.testing.assert_allclose(np.arctan2(xy[1:, 1], xy[1:, 0]), phi[1:])


def test_skin_spreads_a_point_force_symmetrically_and_conserves_it():
    tip = FingertipSpec(radius=R, pitch=0.004, sensel_size=0.004)  # sensels tile the pad without gaps
    p = flex.sensel_pressure(np.zeros((1, 2)), np.array([2.0]), tip, skin_sigma=0.001)
    np.testing.assert_allclose(p, p[::-1, :])
    np.testing.assert_allclose(p, p[:, ::-1])
    np.testing.assert_allclose(p, p.T)
    # the pad covers +-8 mm = 8 sigma: the whole force lands on it
    assert p.sum() * tip.sensel_area == pytest.approx(2.0, rel=1e-9)
    # a corner sensel (centre (6, 6) mm, spanning 4-8 mm) of a centred point load: exact Gaussian mass
    from scipy.special import ndtr

    corner = (ndtr(8.0) - ndtr(4.0)) ** 2 * 2.0 / tip.sensel_area
    assert p[0, 0] == pytest.approx(corner, rel=1e-9)
    assert np.all(flex.sensel_pressure(np.zeros((0, 2)), np.zeros(0), tip, 0.001) == 0)


def test_shipped_calibration_is_valid_and_interpolates(tmp_path):
    tab = load_calibration()
    assert np.all(tab["factor"] > 1.0)  # the trilinear block is stiffer than Hertz at every measured resolution
    x0 = tab["cell_over_radius"][0]
    f, extra = modulus_factor(x0 * R, R, tab)
    assert f == pytest.approx(tab["factor"][0]) and not extra
    _, extra = modulus_factor(10 * R, R, tab)
    assert extra


@pytest.mark.parametrize(
    "content, match",
    [
        ("{not json", "not valid JSON"),
        (json.dumps({"version": 9, "points": []}), "version"),
        (json.dumps({"version": 1, "points": [{"cell_over_radius": 1.0}]}), r"points\[0\]"),
        (json.dumps({"version": 1, "points": [{"cell_over_radius": 1.0, "factor": -2}]}), "factor > 0"),
    ],
)
def test_bad_calibration_files_name_the_problem(tmp_path, content, match):
    path = tmp_path / "cal.json"
    path.write_text(content)
    with pytest.raises(ValidationError, match=match):
        load_calibration(path)
    with pytest.raises(ValidationError, match="not found"):
        load_calibration(tmp_path / "missing.json")


def test_hertz_ratio_recovers_a_scaled_hertz_curve():
    d = np.linspace(0, 0.003, 50)
    f = 1.7 * hertz_force(2e5 / (1 - 0.3**2), R, d)
    assert hertz_ratio(d, f, 2e5, 0.3, R) == pytest.approx(1.7)


def test_layer_cells_get_their_own_lame_stiffness():
    soft, hard = Material("soft", 2e4, 0.3), Material("hard", 2e6, 0.45)
    obj = ObjectSpec("b", "box", (0.02, 0.02, 0.02), (0, 0), hard, layers=(Layer(soft, 0.01),))
    from palpate.core.world.scene import Scene

    scene = Scene((obj,))
    g = flex_model.flex_grid(obj, 0, 0, resolution=0.01, window=0.02)
    model, info = flex_model.build_flex_model(scene, obj, g, 0, 0, 0.03)
    ncell = int(np.prod(g.cells))
    stiff = model.flex_stiffness.reshape(ncell, -1)
    k_lam, k_mu = flex_model._cell_basis(g.cell, 2)
    mats = {"soft": soft, "hard": hard}
    for c, name in enumerate(info["cell_material"]):
        lam, mu = flex_model._lame(mats[name].young, mats[name].poisson)
        np.testing.assert_allclose(stiff[c], lam * k_lam + mu * k_mu, rtol=1e-9, atol=1e-12 * mu)
    # top cells soft, bottom cells hard (z is the fastest cell index)
    assert info["cell_material"][:2] == ["hard", "soft"]


def test_smoke_press_is_finite_deterministic_and_pushes_back():
    kw = dict(young=2e5, resolution=0.01, window=0.02, height=0.01, depth=0.0015, speed=0.02)
    a = flex.reference_press(**kw)
    b = flex.reference_press(**kw)
    for name in ("t", "tip_position", "sensel_pressure", "force", "indentation"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    assert a.meta["fidelity"] == "flex" and a.material == "bulk"
    assert a.sensel_pressure.shape == (len(a.t), 4, 4) and np.all(a.sensel_pressure >= 0)
    assert a.indentation.max() == pytest.approx(0.0015, abs=2e-4)
    assert a.force[0] == 0 and a.force.max() > 0.1
    # force rises with indentation during the press
    d, f = _press_part(a)
    deep, shallow = np.argmax(d), np.argmax(d > 0.0005)
    assert f[deep] > f[shallow] > 0


# ---------------------------------------------------------------- physics (seconds each)


@pytest.mark.physics
def test_exponent_near_three_halves_at_small_indentation():
    tr = flex.reference_press(young=2e5, depth=0.003)
    d, f = _press_part(tr)
    assert 1.3 <= _exponent(d, f) <= 1.6


@pytest.mark.physics
def test_calibrated_force_matches_hertz_at_small_indentation():
    """Least-squares over 0.3-1.5 mm within 10% at the calibration material, 20% at 20 kPa and 2 MPa."""
    for young, tol in ((2e5, 0.10), (2e4, 0.20), (2e6, 0.20)):
        tr = flex.reference_press(young=young, depth=0.002)
        d, f = _press_part(tr)
        assert abs(hertz_ratio(d, f, young, 0.3, R) - 1.0) < tol, young


@pytest.mark.physics
def test_three_materials_are_ordered_and_separable():
    from palpate.core.perception.fit import fit_power_law

    fits = []
    peak = []
    for young in (2e4, 2e5, 2e6):
        tr = flex.reference_press(young=young, depth=0.002)
        d, f = _press_part(tr)
        sel = d > 0
        # cutaneous law: total pressure over the pad against contact area (sensels above 1 kPa)
        p = tr.sensel_pressure[tr.t <= tr.meta["press_end"]][sel]
        area = (p > 1e3).sum(axis=(1, 2)) * 0.0035**2
        n_fit = fit_power_law(d[sel] * 1e3, f[sel])
        a_fit = fit_power_law(area[area > 0] * 1e6, p.sum(axis=(1, 2))[area > 0])
        fits.append((n_fit.k1, a_fit.k1))
        peak.append(f.max())
    assert peak[0] < peak[1] < peak[2]
    n1 = np.array([x[0] for x in fits])
    assert np.all(np.diff(np.log(n1)) > np.log(3.0))  # a decade of modulus gives well over 3x in n1
    a1 = np.array([x[1] for x in fits])
    assert np.all(np.diff(a1) > 0)


@pytest.mark.physics
def test_soft_layer_over_hard_base_is_stiffer_at_depth_than_soft_bulk():
    # 3 mm into a 20 kPa block: deeper, the 5 mm flex mesh lets the tip sink between surface vertices and the
    # divergence check stops the press (the force falls while the indentation grows).
    soft = Material("soft", 2e4)
    bulk = flex.reference_press(young=2e4, depth=0.003, resolution=0.005)
    layered = flex.reference_press(young=2e5, depth=0.003, resolution=0.005, layers=(Layer(soft, 0.004),))
    assert layered.meta["materials"] == ["bulk", "soft"]
    db, fb = _press_part(bulk)
    dl, fl = _press_part(layered)
    # shallow: both feel the soft layer (within a factor 2); deep: the stiffer base shows
    shallow = 0.001
    assert np.interp(shallow, dl, fl) < 2.0 * np.interp(shallow, db, fb)
    deep = 0.0025
    assert np.interp(deep, dl, fl) > 1.5 * np.interp(deep, db, fb)


@pytest.mark.physics
def test_unstable_setting_raises_simulation_diverged_naming_the_fix():
    with pytest.raises(SimulationDiverged, match="timestep"):
        flex.reference_press(young=2e9, timestep=0.02, depth=0.003)
