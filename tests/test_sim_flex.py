"""The `flex` fidelity: MuJoCo trilinear flexcomp window pressed by the fingertip, against the reference."""

from __future__ import annotations

import json

import numpy as np
import pytest

pytest.importorskip("mujoco")

from palpate.core.errors import ValidationError  # noqa: E402
from palpate.core.world.scene import FingertipSpec, Layer, Material, ObjectSpec, Scene  # noqa: E402
from palpate.sim.contact.law import solve_contact_law  # noqa: E402
from palpate.sim.flex import element as flex_element  # noqa: E402
from palpate.sim.flex import grid as flex_grid  # noqa: E402
from palpate.sim.flex import mixing as flex_mixing  # noqa: E402
from palpate.sim.flex import model as flex_model  # noqa: E402
from palpate.sim.flex import press as flex  # noqa: E402
from palpate.sim.flex.calibrate import loading_ratio  # noqa: E402
from palpate.sim.flex.calibration import load_calibration, mesh_factor  # noqa: E402
from palpate.sim.reference.sample import AxisymmetricSample  # noqa: E402

R = 0.008


def _press_part(tr):
    press = tr.t <= tr.meta["press_end"]
    return tr.indentation[press], tr.force[press]


# ---------------------------------------------------------------- fast: geometry, skin model, calibration file


def test_grid_centres_a_node_under_the_press_and_pins_cut_faces():
    obj = ObjectSpec("b", "box", (0.1, 0.04, 0.02), (0.0, 0.0), Material("m", 1e5))
    g = flex_grid.flex_grid(obj, 0.0, 0.0, resolution=0.0065, window=0.04)
    assert g.cells[0] % 2 == 0 and g.cells[1] % 2 == 0
    np.testing.assert_allclose(g.lower[:2] + g.size[:2] / 2, [0.0, 0.0])
    # 100 mm long in x: the 40 mm window cuts through the material there; y edges are the object's free faces
    assert g.pinned == (True, True, False, False)
    # near the +x edge the window is clipped to stay inside the object
    g2 = flex_grid.flex_grid(obj, 0.049, 0.0, resolution=0.0065, window=0.04)
    assert g2.lower[0] + g2.size[0] == pytest.approx(0.05)
    assert g2.pinned[1] is False
    c = g.cell_centres()
    assert c.shape == (np.prod(g.cells), 3)
    # MuJoCo's cell order: z fastest, x slowest
    assert c[1, 2] > c[0, 2] and c[1, 0] == c[0, 0] and c[-1, 0] > c[0, 0]


def test_mesh_objects_are_refused_with_a_clear_error():
    obj = ObjectSpec("m", "mesh", (1, 1, 1), (0, 0), Material("m", 1e5), mesh_path="x.stl")
    with pytest.raises(ValidationError, match="'box' and 'cylinder'"):
        flex_grid.flex_grid(obj, 0, 0)
    with pytest.raises(ValidationError, match="resolution"):
        flex_grid.flex_grid(ObjectSpec("b", "box", (0.04, 0.04, 0.02), (0, 0), Material("m", 1e5)), 0, 0, -1.0)


def test_pad_coordinates_wrap_by_arc_length():
    theta = np.array([0.0, 0.3, 1.0])
    phi = np.array([0.0, 0.7, 2.0])
    pts = R * np.column_stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), -np.cos(theta)])
    xy = flex.pad_coordinates(pts, R)
    np.testing.assert_allclose(np.linalg.norm(xy, axis=1), R * theta, atol=1e-15)
    np.testing.assert_allclose(np.arctan2(xy[1:, 1], xy[1:, 0]), phi[1:])


def test_each_contact_force_covers_its_vertex_patch_and_is_conserved():
    tip = FingertipSpec(radius=R, pitch=0.004, sensel_size=0.004)  # sensels tile the pad without gaps
    p = flex.sensel_pressure(np.zeros((1, 2)), np.array([2.0]), tip, patch=0.0025)
    np.testing.assert_allclose(p, p[::-1, :])
    np.testing.assert_allclose(p, p[:, ::-1])
    np.testing.assert_allclose(p, p.T)
    assert p.sum() * tip.sensel_area == pytest.approx(2.0, rel=1e-12)
    # a centred 2.5 mm patch lies inside the four central 4 mm sensels, a quarter in each
    assert p[1, 1] == pytest.approx(0.5 / tip.sensel_area, rel=1e-12) and p[0, 0] == 0.0
    # a patch straddling a sensel edge splits in proportion to its overlap (exact)
    q = flex.sensel_pressure(np.array([[0.001, 0.001]]), np.array([1.0]), tip, patch=0.0025)
    assert q[1, 2] * tip.sensel_area == pytest.approx(1.0 * (2.25 / 2.5) ** 2, rel=1e-12)
    assert np.all(flex.sensel_pressure(np.zeros((0, 2)), np.zeros(0), tip, 0.001) == 0)


def test_shipped_calibration_is_valid_and_interpolates():
    cal = load_calibration()
    t, free = (next(tb for tb in cal.tables if tb.sides == sides) for sides in ("pinned", "free"))
    c_r, ac, hs = t.cell_over_radius, t.contact_over_cell, t.thickness
    # the trilinear grid is stiffer than the continuum wherever a press is allowed (a >= 0.25 cells) on a block
    # thicker than the validity table's thinnest layers
    usable = ac >= 0.25
    assert np.all(t.factor[:, hs >= 0.014][:, :, usable] > 1.0)
    j = int(np.argmin(np.abs(hs - 0.03)))  # the 30 mm block, and the 70 mm one after it
    assert hs[j] == pytest.approx(0.03) and hs[j + 1] == pytest.approx(0.07)
    at = mesh_factor(ac[8], t.poisson[1], c_r, cal, hs[j])
    assert at.kappa == pytest.approx(t.factor[1, j, 8]) and not at.extrapolated
    mid = 0.5 * (ac[8] + ac[9])
    k_mid = mesh_factor(mid, t.poisson[1], c_r, cal, hs[j]).kappa
    assert min(t.factor[1, j, 8:10]) <= k_mid <= max(t.factor[1, j, 8:10])
    # between two calibrated thicknesses: between their factors (linear in log thickness)
    k_h = mesh_factor(ac[8], t.poisson[1], c_r, cal, float(np.sqrt(hs[j] * hs[j + 1]))).kappa
    assert k_h == pytest.approx(0.5 * (t.factor[1, j, 8] + t.factor[1, j + 1, 8]))
    assert mesh_factor(0.5, 0.3, 2.0 * c_r, cal, hs[j]).extrapolated  # another cell size: flagged
    assert mesh_factor(0.5, 0.3, c_r, cal, 2.0 * hs[-1]).extrapolated  # thicker than measured: flagged
    assert mesh_factor(1.2, 0.3, c_r, cal, hs[0]).extrapolated  # deeper than the thin block was pressed: flagged
    # a window with free sides: the free table's factor; half its sides pinned: halfway
    assert mesh_factor(ac[8], t.poisson[1], c_r, cal, hs[j], 0.0).kappa == pytest.approx(free.factor[1, j, 8])
    half = mesh_factor(ac[8], t.poisson[1], c_r, cal, hs[j], 0.5).kappa
    assert half == pytest.approx(0.5 * (t.factor[1, j, 8] + free.factor[1, j, 8]))
    # the pinned window's sides stiffen a 30 mm block pressed over a cell wide: the free factor is smaller
    assert free.factor[1, j, -1] < t.factor[1, j, -1]
    with pytest.raises(ValidationError, match="pinned_fraction"):
        mesh_factor(0.5, 0.3, c_r, cal, hs[j], 1.5)


def test_the_mesh_correction_reduced_once_per_press_is_the_tables_trilinear_interpolation():
    """A press reduces the tables to kappa against a / cell once (mesh_curve) and reads it at every step; off the
    tables' points in a / cell, thickness and Poisson ratio, and past their ends, that is each table interpolated
    linearly in a / cell, then log thickness, then Poisson ratio (clamped), weighted by the pinned fraction."""
    from palpate.sim.flex.calibration import mesh_curve

    cal = load_calibration()
    tables = {tb.sides: tb for tb in cal.tables}

    def by_hand(tb, c, nu, h):
        per = [[np.interp(c, tb.contact_over_cell, row) for row in rows] for rows in tb.factor]
        return np.interp(nu, tb.poisson, [np.interp(np.log(h), np.log(tb.thickness), row) for row in per])

    rng = np.random.default_rng(7)
    for nu, h, pinned in ((0.41, 0.021, 0.5), (0.2, 0.0012, 1.0), (0.495, 0.2, 0.25)):
        curve = mesh_curve(nu, tables["pinned"].cell_over_radius, cal, h, pinned)
        for c in rng.uniform(0.1, 1.5, 12):
            want = pinned * by_hand(tables["pinned"], c, nu, h) + (1 - pinned) * by_hand(tables["free"], c, nu, h)
            assert curve.at(c).kappa == pytest.approx(want, rel=1e-12)


_TABLE = {"sides": "pinned", "cell_over_radius": 0.6, "poisson": [0.3], "thickness": [0.02], "contact_over_cell": [0.5],
          "measured_to": [[0.5]]}


@pytest.mark.parametrize(
    "content, match",
    [
        ("{not json", "not valid JSON"),
        (json.dumps({"version": 3, "tables": []}), "version"),
        (json.dumps({"version": 4, "tables": []}), "tables"),
        (json.dumps({"version": 4, "tables": [{**_TABLE, "sides": "open", "factor": [[[1.5]]]}]}), "sides must be"),
        (json.dumps({"version": 4, "tables": [{**_TABLE, "factor": [[[1.5, 2.0]]]}]}),
         r"tables\[0\].factor must be 1 x 1 x 1"),
        (json.dumps({"version": 4, "tables": [{**_TABLE, "factor": [[1.5]]}]}), r"tables\[0\].factor must be a .*3-D"),
        (json.dumps({"version": 4, "tables": [{**_TABLE, "factor": [[[-1.0]]]}]}), "factors > 0"),
    ],
)
def test_bad_calibration_files_name_the_problem(tmp_path, content, match):
    path = tmp_path / "cal.json"
    path.write_text(content)
    with pytest.raises(ValidationError, match=match):
        load_calibration(path)
    with pytest.raises(ValidationError, match="not found"):
        load_calibration(tmp_path / "missing.json")


def test_layer_cells_get_their_own_lame_stiffness_and_pins_hold_the_bottom():
    soft, hard = Material("soft", 2e4, 0.3), Material("hard", 2e6, 0.45)
    # a 10 mm skin on 10 mm cells: each cell one material
    obj = ObjectSpec("b", "box", (0.04, 0.04, 0.02), (0, 0), hard, layers=(Layer(soft, 0.01),))
    g = flex_grid.flex_grid(obj, 0, 0, resolution=0.01, window=0.02)
    fm = flex_model.build_flex_model(Scene((obj,)), obj, g, timestep=0.005)
    ncell = int(np.prod(g.cells))
    stiff = fm.model.flex_stiffness[:ncell * 576].reshape(ncell, 24, 24)
    _, lam_centre, dev = flex_element.hex_bases(g.cell_corners()[0])
    mats = {"soft": soft, "hard": hard}
    for c, name in enumerate(fm.cell_material):
        lam, mu = flex_element.lame(mats[name].young, mats[name].poisson)
        np.testing.assert_allclose(stiff[c], lam * lam_centre + mu * dev, rtol=1e-9, atol=1e-12 * mu)
    assert fm.cell_material[:2] == ["hard", "soft"]  # z is the fastest cell index
    # pinned nodes carry no joint: the free nodes' 3 dofs and the tip's one are all there is
    free = (g.cells[0] + 1) * (g.cells[1] + 1) * (g.cells[2] + 1) - len(g.pinned_nodes())
    assert fm.model.nv == 3 * free + 1


def test_graded_grid_is_fine_at_the_press_and_mujoco_uses_its_cells():
    """MuJoCo's elastic force on a graded window equals -K u of the graded cells assembled here (so moving the
    compiled flex's nodes and replacing its blocks is the graded mesh), and its collision vertices follow."""
    import mujoco

    obj = ObjectSpec("b", "box", (0.1, 0.1, 0.02), (0, 0), Material("m", 2e5, 0.3))
    g = flex_grid.flex_grid(obj, 0.0021, 0.0, resolution=0.002, window=0.03, core=0.004, growth=1.6)
    dx = np.diff(g.x)
    assert g.finest == pytest.approx(0.002) and dx.max() > 2.5 * dx.min()
    assert 0.002 in np.round(g.x, 9) and g.z[-1] == pytest.approx(0.02)  # a node column under the (snapped) press
    np.testing.assert_allclose(np.diff(g.z)[-2:], 0.002)  # fine cells under the top
    fm = flex_model.build_flex_model(Scene((obj,)), obj, g, timestep=0.005)
    m, d = fm.model, mujoco.MjData(fm.model)
    nodes = g.nodes()
    body = m.flex_nodebodyid
    free = np.nonzero(body != body.min())[0]
    rng = np.random.default_rng(1)
    u = np.zeros_like(nodes)
    u[free] = rng.normal(size=(len(free), 3)) * 1e-7
    for n in free:
        d.qpos[m.jnt_qposadr[m.body_jntadr[body[n]]]:][:3] = u[n]
    mujoco.mj_forward(m, d)
    K = np.zeros((nodes.size, nodes.size))
    _, lam_centre, dev = flex_element.hex_bases(g.cell_corners())
    lam, mu = flex_element.lame(2e5, 0.3)
    nx, ny, nz = g.cells
    c = 0
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                corner = [((i + a) * (ny + 1) + j + b) * (nz + 1) + k + e
                          for a in (0, 1) for b in (0, 1) for e in (0, 1)]
                dofs = (3 * np.array(corner)[:, None] + np.arange(3)).ravel()
                K[np.ix_(dofs, dofs)] -= lam * lam_centre[c] + mu * dev[c]
                c += 1
    f = -(K @ u.ravel()).reshape(-1, 3)
    got = np.array([d.qfrc_passive[m.jnt_dofadr[m.body_jntadr[body[n]]]:][:3] for n in free])
    np.testing.assert_allclose(got, f[free], atol=1e-3 * np.abs(f).max())
    top = d.flexvert_xpos[np.isclose(d.flexvert_xpos[:, 2], 0.02, atol=1e-5)]
    assert np.min(np.abs(top[:, 0] - 0.002 - 0.001)) < 1e-5  # vertex midway in a fine cell: 1 mm spacing there


def test_a_skin_thinner_than_a_cell_mixes_into_it_in_series():
    soft, hard = Material("soft", 2e4, 0.3), Material("hard", 2e6, 0.3)
    obj = ObjectSpec("b", "box", (0.04, 0.04, 0.02), (0, 0), hard, layers=(Layer(soft, 0.0025),))
    g = flex_grid.flex_grid(obj, 0, 0, resolution=0.01, window=0.02)  # top cells 10 mm tall, a quarter skin
    young, poisson = flex_mixing.cell_moduli(obj, g)
    top = young[1::2]
    np.testing.assert_allclose(top, 1.0 / (0.25 / 2e4 + 0.75 / 2e6), rtol=1e-12)
    np.testing.assert_allclose(young[0::2], 2e6)
    np.testing.assert_allclose(poisson, 0.3)


def test_smoke_press_is_finite_deterministic_and_reuses_its_model():
    kw = dict(young=2e5, height=0.01, depth=0.0015, speed=0.02)
    models: dict = {}
    a = flex.reference_press(**kw, models=models)
    b = flex.reference_press(**kw, models=models)  # the same window, state reset
    assert len(models) == 1
    for name in ("t", "tip_position", "sensel_pressure", "force", "indentation"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    assert a.meta["fidelity"] == "flex" and a.material == "bulk"
    assert a.sensel_pressure.shape == (len(a.t), 4, 4) and np.all(a.sensel_pressure >= 0)
    assert a.indentation.max() == pytest.approx(0.0015, rel=0.02)
    assert a.force[0] == 0 and a.force.max() > 0.1
    d, f = _press_part(a)
    deep, shallow = np.argmax(d), np.argmax(d > 0.0005)
    assert f[deep] > f[shallow] > 0


def test_force_scales_with_the_modulus_exactly():
    """E-invariance: with mass scaling the same press on 20 kPa and 2 MPa gives forces in the ratio 1:100 (0.5%)
    at every indentation from 0.2 mm (the first contact step may fall one step apart: the solver's tolerances are
    absolute)."""
    soft = flex.reference_press(young=2e4, height=0.01, depth=0.002)
    hard = flex.reference_press(young=2e6, height=0.01, depth=0.002)
    d = np.linspace(2e-4, 1.9e-3, 12)
    f_soft = np.interp(d, *_press_part(soft))
    f_hard = np.interp(d, *_press_part(hard))
    np.testing.assert_allclose(f_hard, 100.0 * f_soft, rtol=5e-3)


def test_a_press_reads_the_tables_it_is_given_and_a_source_reads_them_once(monkeypatch):
    """The calibration tables a caller loaded once give the press it would read from disk, bit for bit (a stiff
    skin in the plate window: block and plate tables both read); doubled kappa halves the force exactly as it is
    divided (the drive sees the uncorrected force, so the motion is the same); a SimSource reads them once."""
    from dataclasses import replace

    from palpate.core.session.sources import PressTarget
    from palpate.sim import source
    from palpate.sim.flex import tables as flex_tables

    kw = dict(young=1e5, poisson=0.45, height=0.03, width=0.2, depth=0.002,
              layers=(Layer(Material("skin", 2e6, 0.4), 0.002),))
    tables = flex_tables.load_flex_tables()
    read = flex.reference_press(**kw)
    given = flex.reference_press(**kw, tables=tables)
    assert read.meta["plate_corrected"]
    for name in ("force", "sensel_pressure", "indentation"):
        np.testing.assert_array_equal(getattr(given, name), getattr(read, name))
    doubled = replace(tables, mesh=replace(tables.mesh, tables=tuple(
        replace(t, factor=2.0 * t.factor) for t in tables.mesh.tables)))
    np.testing.assert_allclose(flex.reference_press(**kw, tables=doubled).force, read.force / 2.0, rtol=1e-12)

    loads = []
    monkeypatch.setattr(source, "load_flex_tables", lambda: loads.append(1) or tables)
    obj = ObjectSpec("b", "box", (0.1, 0.1, 0.02), (0.0, 0.0), Material("m", 2e5, 0.3))
    sim = source.SimSource(Scene((obj,), fingertip=FingertipSpec(radius=R)), fidelity="flex")
    for x in (0.0, 0.01):
        sim.press(PressTarget(x, 0.0, depth=0.002, speed=0.01))
    assert len(loads) == 1


# ---------------------------------------------------------------- physics (seconds each)


@pytest.mark.physics
@pytest.mark.parametrize("poisson", [0.3, 0.45, 0.49])
def test_thick_block_is_within_ten_percent_of_the_reference_without_locking(poisson):
    """A 40 mm block (thick: its table stiffening is the reference's, not cancelled) from 0.5 to 3 mm."""
    tr = flex.reference_press(young=2e5, poisson=poisson, height=0.04, depth=0.0032)
    law = solve_contact_law(AxisymmetricSample(Material("m", 2e5, poisson), 0.04), R, 0.0035)
    ratio = loading_ratio(tr.indentation, tr.force, law, np.array([0.5, 1.0, 2.0, 3.0]) * 1e-3)
    np.testing.assert_allclose(ratio, 1.0, atol=0.10)


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


def test_a_step_too_long_for_the_press_or_over_the_budget_is_refused_naming_the_option():
    with pytest.raises(ValidationError, match="timestep"):
        flex.reference_press(young=2e9, timestep=0.05, depth=0.003, speed=0.05)
    obj = ObjectSpec("b", "box", (0.1, 0.1, 0.02), (0.0, 0.0), Material("m", 2e5))
    from palpate.core.session.sources import PressTarget
    from palpate.sim.controller import press_profile

    target = PressTarget(0.0, 0.0, depth=0.003, speed=0.0005)
    prof = press_profile(target, 0.02, radius=R, timestep=0.002)
    with pytest.raises(ValidationError, match="budget"):
        flex.run_flex_press(Scene((obj,)), obj, target, prof, timestep=1e-4, max_steps=1000)
    with pytest.raises(ValidationError, match="0.75 tip radii"):
        flex.reference_press(young=2e5, depth=0.007)


def test_the_physics_grid_lands_on_the_deepest_setpoint():
    """A profile sampled finer than the step (its samples are not a multiple of it) still gets a step at its
    deepest point, on a uniform grid inside the profile."""
    from palpate.core.session.sources import PressTarget
    from palpate.sim.controller import press_profile

    prof = press_profile(PressTarget(0.0, 0.0, depth=0.005, speed=0.2), 0.01, radius=R, timestep=0.002)
    assert not np.any(np.isclose(prof.t[0] + 0.002 * np.arange(40), prof.t[np.argmin(prof.z)]))  # the old grid
    times = prof.step_times(0.002)
    np.testing.assert_allclose(np.diff(times), 0.002)
    assert prof.t[0] <= times[0] < prof.t[0] + 0.002 and times[-1] <= prof.t[-1]
    assert np.min(np.abs(times - prof.t[np.argmin(prof.z)])) < 1e-12


@pytest.mark.parametrize("x", [0.0, 0.0195])
def test_a_fast_press_into_nearly_incompressible_foam_reaches_its_depth(x):
    """The stability matrix's cell (1 kPa, nu 0.49, 5 mm at 0.2 m/s in 2 ms steps) turned round at 4.72 mm and
    passed its reach check: the step grid missed the deepest setpoint and the drive braked a step early."""
    from palpate.core.session.sources import PressTarget
    from palpate.sim.controller import press_profile

    obj = ObjectSpec("b", "box", (0.04, 0.04, 0.01), (0.0, 0.0), Material("m", 1e3, 0.49))
    target = PressTarget(x, 0.0, depth=0.005, speed=0.2)
    prof = press_profile(target, 0.01, radius=R, timestep=0.002)
    tr = flex.run_flex_press(Scene((obj,)), obj, target, prof, timestep=0.002)
    assert tr.indentation.max() == pytest.approx(0.005, rel=0.01)
    # where the tip turns round the block pushes hardest
    assert abs(tr.t[np.argmax(tr.force)] - tr.t[np.argmax(tr.indentation)]) <= 0.002 + 1e-9


@pytest.mark.physics
def test_active_sensels_are_the_references_within_one_sensel():
    """From 0.5 to 3 mm on a 40 mm block, every sensel lit by flex and not by the reference pressure (the contact
    law, which the FE reference confirms), or the other way round, neighbours one both light."""
    from scipy.ndimage import binary_dilation

    from palpate.core.world.scene import TaxelSensorSpec
    from palpate.sim.analytic import law_sensel_pressure
    from palpate.sim.fingertip import sensel_bounds

    tr = flex.reference_press(young=2e5, height=0.04, depth=0.0031)
    law = solve_contact_law(AxisymmetricSample(Material("m", 2e5, 0.3), 0.04), R, 0.0035)
    spec = TaxelSensorSpec()
    loading = np.arange(len(tr.t)) <= np.argmax(tr.indentation)
    for depth in (0.5e-3, 1e-3, 1.5e-3, 2e-3, 3e-3):
        k = int(np.argmin(np.abs(np.where(loading, tr.indentation, np.inf) - depth)))
        ref = law_sensel_pressure(law, tr.indentation[k:k + 1], sensel_bounds(FingertipSpec()))[0]
        lit_flex = tr.sensel_pressure[k] * spec.gain > spec.threshold
        lit_ref = ref * spec.gain > spec.threshold
        both = lit_flex & lit_ref
        assert both.any(), depth
        near = binary_dilation(both, structure=np.ones((3, 3), dtype=bool))
        assert np.all(near[lit_flex != lit_ref]), (depth, lit_flex.astype(int), lit_ref.astype(int))
