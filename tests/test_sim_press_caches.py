"""What the analytic and rigid rungs keep between presses, and the shortcuts of their hot paths, give the numbers the
plain evaluations give, bit for bit; a cache is keyed on what it depends on (a changed input misses it)."""

from __future__ import annotations

import numpy as np
import pytest

from palpate.core.session.sources import PressTarget
from palpate.core.world.scene import FingertipSpec, Material, ObjectSpec, Scene
from palpate.sim import analytic, rigid
from palpate.sim.contact.stack import object_law
from palpate.sim.controller import press_profile
from palpate.sim.fingertip import sensel_bounds

R = 0.008


def _block(young: float = 2e5, poisson: float = 0.45) -> ObjectSpec:
    return ObjectSpec("block", "box", (0.1, 0.1, 0.03), (0.0, 0.0), Material("gel", young, poisson))


@pytest.fixture(scope="module")
def law():
    return object_law(_block(), 0.0, 0.0, 0.03, R, 0.004)


def _dense_law_pressure(law, depth, r_eq):
    """Every (depth, radius) pair of the law's Hertz-profile sum, as a plain broadcast evaluates it."""
    d = np.maximum(depth, 0.0)
    over = d > law.max_depth
    basis = law.basis_at(np.minimum(d, law.max_depth))
    scale = np.ones_like(d)
    scale[over] = np.sqrt(d[over] / law.max_depth)
    b, c = basis.radii * scale[:, None], basis.coeffs
    shape = (len(d),) + (1,) * r_eq.ndim
    rr = r_eq[None, ..., None] ** 2
    p = np.sum(c.reshape(shape + (-1,)) * np.sqrt(np.maximum(b.reshape(shape + (-1,)) ** 2 - rr, 0.0)), axis=-1)
    return p * scale.reshape(shape)


def test_law_pressure_equals_the_dense_evaluation_and_leaves_unasked_rows_zero(law):
    rng = np.random.default_rng(3)
    depth = np.linspace(-1e-4, 1.5 * law.max_depth, 300)  # out of contact, in, and past the tabulated depth
    r_eq = np.where(rng.random((4, 4, 36)) < 0.1, np.inf, rng.uniform(0.0, R, (4, 4, 36)))  # repeats and off-pad
    r_eq[0, 0, :5] = r_eq[1, 1, :5]
    dense = _dense_law_pressure(law, depth, r_eq)
    assert np.count_nonzero(dense) > 0.3 * dense.size
    sparse = rigid.law_pressure(law, depth, r_eq)
    assert np.array_equal(sparse, dense)
    weights = rng.random(36)
    assert np.array_equal(sparse @ weights, dense @ weights)  # C order: a BLAS product sums alike
    rows = rng.random(len(depth)) < 0.3
    part = rigid.law_pressure(law, depth, r_eq, rows)
    assert np.array_equal(part[rows], dense[rows]) and not part[~rows].any()
    # summed over a sensel's quadrature points in the call: the rows' sums as the whole table's, the rest 0
    summed = rigid.law_pressure(law, depth, r_eq, rows, weights=weights)
    assert summed.shape == (len(depth), 4, 4)
    assert np.array_equal(summed, part @ weights)


def test_a_rigid_press_equals_one_built_on_whole_tables(monkeypatch, law):
    scene = Scene(objects=(_block(),), fingertip=FingertipSpec(radius=R))
    obj = scene.objects[0]
    profile = press_profile(PressTarget(0.0, 0.0, depth=0.003, speed=0.01), obj.height, radius=R, timestep=0.002)
    fast = rigid.run_rigid_press(scene, obj, profile, law=law)
    real = rigid.law_pressure
    asked = []

    def whole(law_, depth, r_eq, rows=None, weights=None):
        asked.append(rows is not None)
        table = real(law_, depth, r_eq)  # every row of every table, summed over the whole of it
        return table if weights is None else table @ weights

    monkeypatch.setattr(rigid, "law_pressure", whole)
    plain = rigid.run_rigid_press(scene, obj, profile, law=law)
    assert asked == [True, True]  # the force table's band and the sensel table's rows were asked for
    for name in ("force", "indentation", "sensel_pressure", "tip_position"):
        assert np.array_equal(getattr(fast, name), getattr(plain, name)), name


def test_one_integration_of_every_profile_equals_a_call_per_profile(law):
    bounds = sensel_bounds(FingertipSpec(radius=R))
    depth = np.linspace(0.0, law.max_depth, 41)
    basis = law.basis_at(depth)
    for centre in (None, np.array([6e-4, -3e-4]), np.random.default_rng(1).uniform(-1e-3, 1e-3, (41, 2))):
        per_profile = np.zeros((41, 4, 4))
        for k in range(basis.radii.shape[1]):
            depth_k, young_k = basis.radii[:, k] ** 2 / R, basis.coeffs[:, k] * np.pi * R / 2
            per_profile += analytic.hertz_sensel_pressure(depth_k, young_k, R, bounds, centre)
        assert np.array_equal(analytic.law_sensel_pressure(law, depth, bounds, centre),
                              np.maximum(per_profile, 0.0))


def test_the_pad_cache_is_keyed_by_fingertip_and_gives_the_uncached_image(law):
    obj = _block()
    target = PressTarget(0.0, 0.0, depth=0.003, speed=0.01)
    pads: dict = {}
    images = []
    for tip in (FingertipSpec(radius=R), FingertipSpec(radius=R), FingertipSpec(radius=R, pitch=0.0024)):
        scene = Scene(objects=(obj,), fingertip=tip)
        profile = press_profile(target, obj.height, radius=R, timestep=0.002)
        kept = analytic.run_analytic_press(scene, obj, profile, law=law, pads=pads)
        fresh = analytic.run_analytic_press(scene, obj, profile, law=law)
        assert np.array_equal(kept.sensel_pressure, fresh.sensel_pressure)
        images.append((len(pads), kept.sensel_pressure))
    # the same pad hits its entry; another pitch misses it and images differently
    assert [n for n, _ in images] == [1, 1, 2]
    assert not np.array_equal(images[0][1], images[2][1])


def test_the_source_keeps_one_law_per_stack_and_misses_on_a_changed_material():
    from palpate.sim.source import SimSource

    target = PressTarget(0.0, 0.0, depth=0.003, speed=0.01)
    source = SimSource(Scene(objects=(_block(),), fingertip=FingertipSpec(radius=R)), fidelity="analytic")
    source.press(target)
    source.press(target)
    (key,) = source._laws
    law = source._laws[key]
    other = SimSource(Scene(objects=(_block(young=3e5),), fingertip=FingertipSpec(radius=R)), fidelity="analytic")
    other._laws = source._laws  # one cache, a stiffer block: its own entry, its own law
    other.press(target)
    assert len(source._laws) == 2 and source._laws[key] is law
    (new,) = set(source._laws) - {key}
    np.testing.assert_allclose(source._laws[new].force[1:] / law.force[1:], 1.5, rtol=1e-9)


def test_the_source_keeps_one_blas_controller_across_presses():
    from palpate.sim.source import SimSource

    pytest.importorskip("threadpoolctl")
    source = SimSource(Scene(objects=(_block(),), fingertip=FingertipSpec(radius=R)), fidelity="analytic")
    source.press(PressTarget(0.0, 0.0, depth=0.003, speed=0.01))
    first = source._blas
    source.press(PressTarget(0.001, 0.0, depth=0.002, speed=0.01))
    assert first is not None and source._blas is first



def test_force_depth_tables_are_kept_by_law_and_footprint_and_answer_as_a_fresh_table(law):
    from dataclasses import replace

    from palpate.sim.footprint import rigid_depth_for_force

    tip = FingertipSpec(radius=R)
    block = _block()
    tables: dict = {}
    for centre, force in (((0.0, 0.0), 0.5), ((0.01, -0.02), 0.8), ((0.0, 0.0), 0.3)):
        kept = rigid_depth_for_force(block, np.array(centre), tip, law, force, tables=tables)
        assert kept == rigid_depth_for_force(block, np.array(centre), tip, law, force)
    assert len(tables) == 1  # three points of one flat top: one footprint, one table
    (d, f), = tables.values()
    assert not (d.flags.writeable or f.flags.writeable)
    # the same law's arrays in another object (another press point's law) hit; any change of them misses
    twin = replace(law, force=law.force.copy(), coeffs=law.coeffs.copy())
    rigid_depth_for_force(block, np.zeros(2), tip, twin, 0.5, tables=tables)
    assert len(tables) == 1
    softer = replace(law, force=0.9 * law.force, coeffs=0.9 * law.coeffs)
    deeper = rigid_depth_for_force(block, np.zeros(2), tip, softer, 0.5, tables=tables)
    assert len(tables) == 2 and deeper > rigid_depth_for_force(block, np.zeros(2), tip, law, 0.5)
    # a footprint over the block's edge is another table, and the force there needs a deeper press
    edge = np.array([0.05 - 0.002, 0.0])
    at_edge = rigid_depth_for_force(block, edge, tip, law, 0.5, tables=tables)
    assert len(tables) == 3 and at_edge == rigid_depth_for_force(block, edge, tip, law, 0.5)
    assert at_edge > rigid_depth_for_force(block, np.zeros(2), tip, law, 0.5)


def test_a_kept_press_model_moved_to_the_next_start_presses_as_a_fresh_compile(law):
    import mujoco

    scene = Scene(objects=(_block(),), fingertip=FingertipSpec(radius=R))
    obj = scene.objects[0]
    models: dict = {}
    for x, depth in ((0.0, 0.003), (0.004, 0.0025), (0.0, 0.003)):
        profile = press_profile(PressTarget(x, 0.0, depth=depth, speed=0.01), obj.height, radius=R, timestep=0.002)
        kept = rigid.run_rigid_press(scene, obj, profile, law=law, models=models)
        fresh = rigid.run_rigid_press(scene, obj, profile, law=law)
        for name in ("force", "indentation", "sensel_pressure", "tip_position", "t"):
            assert np.array_equal(getattr(kept, name), getattr(fresh, name)), name
    assert len(models) == 1
    (model, data, _), = models.values()
    # a warning of one press does not carry into the next (it would fail the press): the data are reset
    data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number = 3
    rigid.run_rigid_press(scene, obj, profile, law=law, models=models)
    # another timestep is another model
    rigid.run_rigid_press(scene, obj, profile, timestep=0.001, law=law, models=models)
    assert len(models) == 2


def test_the_rigid_rung_steps_the_finger_alone_as_it_would_in_the_whole_scene(monkeypatch, law):
    post = ObjectSpec("post", "cylinder", (0.01, 0.02), (0.08, 0.0), Material("m", 1e5, 0.3))
    scene = Scene(objects=(_block(), post), fingertip=FingertipSpec(radius=R))
    obj = scene.objects[0]
    profile = press_profile(PressTarget(0.002, 0.001, depth=0.003, speed=0.01), obj.height, radius=R, timestep=0.002)
    models: dict = {}
    alone = rigid.run_rigid_press(scene, obj, profile, law=law, models=models)
    (model, _, _), = models.values()
    assert (model.nbody, model.ngeom, model.nsite) == (2, 1, 0)
    build = rigid.build_press_model
    monkeypatch.setattr(rigid, "build_press_model", lambda *a, finger_only, **k: build(*a, **k))  # the whole scene
    models = {}
    whole = rigid.run_rigid_press(scene, obj, profile, law=law, models=models)
    (model, _, _), = models.values()
    assert model.nbody == 4 and model.nsite == 17
    for name in ("force", "indentation", "sensel_pressure", "tip_position", "t"):
        assert np.array_equal(getattr(alone, name), getattr(whole, name)), name


def test_column_energies_are_shared_by_stacks_alike_up_to_one_modulus_factor(monkeypatch):
    from palpate.sim.contact import stack as st
    from palpate.sim.contact.axisymmetric import column_energy

    solved = []

    def spy(*args, **kwargs):
        solved.append(args[0].bulk.young)
        return column_energy(*args, **kwargs)

    monkeypatch.setattr(st, "column_energy", spy)
    cache: dict = {}
    energies = {}
    for young, poisson in ((1.5e5, 0.3), (4.2e5, 0.3), (1.5e5, 0.45)):
        lookup = st.object_lookup(_block(young, poisson), 0.0, 0.0, 0.03)
        energies[young, poisson] = st._column_energy(lookup, 0.03, [], R, 0.004, "bonded", cache)
    # the stiffer block of the same Poisson ratio is the first one scaled: no FE of its own; another ratio is solved
    assert solved == [1.5e5, 1.5e5]
    shared = energies[4.2e5, 0.3]
    fresh = column_energy(st.column_stack(st.object_lookup(_block(4.2e5, 0.3), 0.0, 0.0, 0.03), 0.03, []), R, 0.004)
    # linear elasticity: the same shares, forces and pressures in proportion (to the rounding of two solves)
    np.testing.assert_allclose(shared.element_energy, fresh.element_energy, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(shared.force, fresh.force, rtol=1e-9)
    np.testing.assert_allclose(shared.pressure, fresh.pressure, rtol=1e-9, atol=1e-9 * fresh.pressure.max())
    assert not np.allclose(energies[1.5e5, 0.45].element_energy, shared.element_energy, rtol=1e-3)


def test_one_maker_shares_its_law_cache_among_the_sources_it_makes():
    import tomllib

    from test_run import SMALL

    from palpate.core.session.sources import scenario_source_maker
    from palpate.core.world.scenario_file import parse_scenario

    scenario = parse_scenario(tomllib.loads(SMALL), "small.toml")
    objects = (scenario.objects[0].spec,)
    make, other = scenario_source_maker(scenario), scenario_source_maker(scenario)
    first, second = make(objects, 1, "robot"), make(objects, 2, "robot")
    assert first._laws is second._laws
    assert other(objects, 1, "robot")._laws is not first._laws


@pytest.mark.physics
def test_a_run_sharing_laws_among_its_sources_gives_the_maps_of_one_that_does_not(monkeypatch, tmp_path):
    """The stated tolerance of the shared cache: a column's FE energy shares reused for a stack alike up to one
    modulus factor differ from a fresh solve's in the last bits; maps agree to 1e-12, summary numbers to 1e-9."""
    import json
    import tomllib

    from test_run import SMALL

    from palpate.core.session.run import run_scenario
    from palpate.core.world.scenario_file import parse_scenario
    from palpate.sim import source as source_mod

    scenario = parse_scenario(tomllib.loads(SMALL.replace("attainable_accuracy = true", "figures = false")),
                              "small.toml")
    shared = run_scenario(scenario, tmp_path / "shared")
    init = source_mod.SimSource.__init__

    def alone(self, *args, laws=None, **kwargs):
        init(self, *args, **kwargs)

    monkeypatch.setattr(source_mod.SimSource, "__init__", alone)
    apart = run_scenario(scenario, tmp_path / "apart")
    for name in ("slab.npz", "slab_postprocessed.npz"):
        a, b = np.load(tmp_path / "shared" / "maps" / name), np.load(tmp_path / "apart" / "maps" / name)
        for key in a.files:
            np.testing.assert_allclose(a[key], b[key], rtol=0, atol=1e-12)
    a, b = json.loads(json.dumps(shared["objects"])), json.loads(json.dumps(apart["objects"]))
    assert [r["cell"] for r in a[0]["per_press"]] == [r["cell"] for r in b[0]["per_press"]]
    for ra, rb in zip(a[0]["per_press"], b[0]["per_press"], strict=True):
        np.testing.assert_allclose(ra["posterior"], rb["posterior"], rtol=1e-9, atol=1e-15)


def test_auto_decides_a_force_press_on_the_law_where_it_lands_and_solves_no_other(monkeypatch):
    """A force target's depth (what auto places in its validity table) comes from the law at the point the press's
    own draws put it, the law the press then feels: beside a wall, where every point has a law of its own, one
    surface solve a press (and no axisymmetric one), not one at the target and another a fraction of a millimetre
    away."""
    from palpate.core.world.scene import Inclusion
    from palpate.sim import source as source_mod
    from palpate.sim.bem import law as law_mod
    from palpate.sim.contact import stack as st

    wall = ObjectSpec("slab", "box", (0.1, 0.1, 0.03), (0.0, 0.0), Material("foam", 3e4, 0.3),
                      inclusions=(Inclusion(Material("rubber", 1.5e5, 0.45), "box", (0.03, 0.0, 0.015),
                                            (0.06, 0.1, 0.03)),))
    solved: list = []
    averaged: list = []
    real, real_average = law_mod.surface_law, st.axisymmetric_law

    def spy(*args, **kwargs):
        law = real(*args, **kwargs)
        solved.append(law is not None)
        return law

    def spy_average(*args, **kwargs):
        averaged.append(args)
        return real_average(*args, **kwargs)

    monkeypatch.setattr(law_mod, "surface_law", spy)
    monkeypatch.setattr(st, "axisymmetric_law", spy_average)
    src = source_mod.SimSource(Scene((wall,)), fidelity="auto", seed=3, variability="human")
    targets = [PressTarget(-0.002 + 0.0015 * k, 0.0, force=2.0, speed=0.01) for k in range(3)]
    for t in targets:
        src.press(t)
    assert solved == [True] * 3 and not averaged
