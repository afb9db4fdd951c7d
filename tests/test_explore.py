"""Exploration policies, the expected-gain computation against a brute force on the map's own code, and the
closed loop's stop rules on tiny analytic scenes."""

from __future__ import annotations

import numpy as np
import pytest

from palpate.core.errors import ValidationError
from palpate.core.mapping.grids import Grid2D, VoxelGrid
from palpate.core.perception.memory import HapticMemory
from palpate.core.planning.info_gain import InfoGain, disagreement, expected_gain, uncovered
from palpate.core.planning.outcomes import outcome_posteriors, outcome_table
from palpate.core.planning.policies import MaxEntropy, Predefined, RandomCells, Raster
from palpate.core.planning.registry import make_policy, stop_reason
from palpate.core.world.scenario_file import parse_scenario

CERTAIN = {0: np.array([0.999, 0.0005, 0.0005]), 1: np.array([0.0005, 0.999, 0.0005]),
           2: np.array([0.0005, 0.0005, 0.999])}
VAGUE = np.array([0.5, 0.3, 0.2])


@pytest.fixture(scope="module")
def memory() -> HapticMemory:
    """Three well separated materials (parameters [n1, n2, a1, a2]), 10 presses each, seeded."""
    rng = np.random.default_rng(5)
    mus = np.array([[100.0, 1.0, 20.0, 0.5], [300.0, 2.0, 40.0, 1.0], [900.0, 3.0, 60.0, 1.5]])
    x = np.vstack([mu * (1 + 0.05 * rng.standard_normal((10, 4))) for mu in mus])
    return HapticMemory(["m0", "m1", "m2"]).fit(x, ["m0"] * 10 + ["m1"] * 10 + ["m2"] * 10)


def _grid(shape=(6, 5)) -> Grid2D:
    return Grid2D(["m0", "m1", "m2"], shape, cell_size=0.01)


def _certain_except(free: set[tuple[int, int]], shape=(6, 5)) -> Grid2D:
    """A grid whose every cell is explored and certain (material 0) except the ``free`` ones."""
    g = _grid(shape)
    for ix in range(shape[0]):
        for iy in range(shape[1]):
            if (ix, iy) not in free:
                g.update_cell(ix, iy, CERTAIN[0])
    return g


ALL_POLICIES = ["raster", "random", "max_entropy", "info_gain"]


@pytest.mark.parametrize("name", ALL_POLICIES)
def test_policy_chooses_in_bounds_and_never_a_certain_cell_while_uncertain_ones_remain(name, memory):
    free = {(0, 4), (3, 2), (5, 0)}
    g = _certain_except(free)
    # One free cell is explored but still vague: it counts as "better" than the certain ones too.
    g.update_cell(3, 2, VAGUE)
    policy = make_policy(name, seed=1, memory=memory)
    chosen = []
    for _ in range(len(free)):
        t = policy.next_target(g, g.postprocessed(), chosen[-1] if chosen else None)
        assert t is not None
        assert 0 <= t.ix < 6 and 0 <= t.iy < 5
        assert (t.ix, t.iy) in free and (t.ix, t.iy) not in chosen
        chosen.append((t.ix, t.iy))
        g.update_cell(t.ix, t.iy, CERTAIN[1])
    assert set(chosen) == free
    # Every cell is now explored and certain: nothing is worth a press.
    assert policy.next_target(g, g.postprocessed(), chosen[-1]) is None


def test_predefined_follows_its_list_and_rejects_a_cell_outside_the_grid():
    g = _grid((4, 3))
    p = Predefined([(0, 0), (3, 2)], repeats=2)
    assert [(t.ix, t.iy) for t in (p.next_target(g) for _ in range(4))] == [(0, 0), (3, 2), (0, 0), (3, 2)]
    assert p.next_target(g) is None
    with pytest.raises(ValidationError, match=r"5,1 .*outside the 4x3 grid"):
        Predefined([(4, 0)]).next_target(g)


def test_raster_visits_every_cell_once_in_boustrophedon_order():
    g = _grid((3, 2))
    r = Raster()
    order = [(t.ix, t.iy) for t in iter(lambda: r.next_target(g), None)]
    assert order == [(0, 0), (1, 0), (2, 0), (2, 1), (1, 1), (0, 1)]


def test_random_is_seeded_and_prefers_unexplored_cells():
    g = _grid((4, 4))
    g.update_cell(0, 0, VAGUE)  # explored but uncertain: unexplored cells come first
    a = [RandomCells(3).next_target(g) for _ in range(2)]
    assert a[0] == a[1] and (a[0].ix, a[0].iy) != (0, 0)


def test_max_entropy_plans_on_the_post_processed_map():
    # Columns 0 and 2 of a 3x1 strip are certain; the middle cell is extrapolated from both (certain, so
    # not chosen first) while a lone cell far away is not: on a 5x1 strip the far end must win.
    g = _grid((5, 1))
    g.update_cell(0, 0, CERTAIN[0])
    g.update_cell(2, 0, CERTAIN[0])
    t = MaxEntropy().next_target(g)
    assert (t.ix, t.iy) == (4, 0)
    assert t.score == pytest.approx(np.log10(3))


def test_info_gain_prefers_an_uncertain_cell_to_a_certain_one(memory):
    g = _certain_except({(4, 1)})
    g.update_cell(4, 1, VAGUE)
    pol = InfoGain(memory)
    gains = pol.gains(g)
    assert gains[1, 4] > 0.1 and gains[1, 4] > 10 * np.delete(gains.ravel(), 1 * 6 + 4).max()
    t = pol.next_target(g)
    assert (t.ix, t.iy) == (4, 1)


def test_info_gain_prefers_a_boundary_between_materials_to_the_middle_of_a_known_region(memory):
    # 9x5: columns 0-3 are material 0, 5-8 material 1, column 4 (the boundary) and cell (1, 2) (inside the
    # known material-0 region) are not pressed.
    g = _grid((9, 5))
    for ix in range(9):
        for iy in range(5):
            if ix == 4 or (ix, iy) == (1, 2):
                continue
            g.update_cell(ix, iy, CERTAIN[0] if ix < 4 else CERTAIN[1])
    pol = InfoGain(memory)
    gains = pol.gains(g)
    assert gains[2, 4] > gains[2, 1] + 0.1
    t = pol.next_target(g)
    assert t.ix == 4


def test_expected_gain_matches_a_brute_force_on_the_maps_own_update_and_post_processing(memory, rng):
    updates = [(int(rng.integers(5)), int(rng.integers(4)), rng.dirichlet([0.4, 0.4, 0.4])) for _ in range(7)]

    def build(extra=()):
        grid = _grid((5, 4))
        for ix, iy, p in [*updates, *extra]:
            grid.update_cell(ix, iy, p)
        return grid

    g = build()
    post = g.postprocessed()
    table = outcome_table(outcome_posteriors(memory, 4, seed=2))
    fast = expected_gain(g, post, table)
    outcomes, lik = table
    h0 = post.entropy()
    explored = np.asarray(g.explored)
    for iy in range(4):
        for ix in range(5):
            belief = np.asarray(post.probabilities)[iy, ix] @ lik  # P(outcome)
            total = 0.0
            for u, q in enumerate(outcomes):
                h1 = build([(ix, iy, q)]).postprocessed().entropy()
                change = h0 - h1
                nb = np.zeros_like(explored)
                nb[max(0, iy - 1):iy + 2, max(0, ix - 1):ix + 2] = True
                nb &= ~explored
                nb[iy, ix] = False
                # Nothing beyond the pressed cell and its unexplored neighbours may change.
                others = np.ones_like(explored)
                others[iy, ix] = False
                others &= ~nb
                assert np.allclose(change[others], 0.0, atol=1e-12)
                total += belief[u] * (change[iy, ix] + np.maximum(change[nb], 0.0).sum())
            assert fast[iy, ix] == pytest.approx(total, abs=1e-9), (ix, iy)


def test_outcome_table_merges_near_identical_posteriors_and_keeps_probabilities(memory):
    q = outcome_posteriors(memory, 8, seed=0)
    outcomes, lik = outcome_table(q)
    assert outcomes.shape[0] < q.shape[0] * q.shape[1]
    np.testing.assert_allclose(outcomes.sum(axis=1), 1.0)
    np.testing.assert_allclose(lik.sum(axis=1), 1.0)
    # The expectation of the posterior per material is kept to the merge resolution.
    np.testing.assert_allclose(lik @ outcomes, q.mean(axis=1), atol=0.02)
    with pytest.raises(ValidationError, match="shape"):
        outcome_table(q[:, :, :2])


def test_travel_cost_picks_the_nearer_of_two_equally_good_cells(memory):
    g = _certain_except({(0, 0), (5, 4)})
    near = make_policy("info_gain", memory=memory, travel_cost_per_mm=0.01).next_target(g, last=(4, 4))
    assert (near.ix, near.iy) == (5, 4)
    near = make_policy("max_entropy", travel_cost_per_mm=0.01).next_target(g, last=(1, 0))
    assert (near.ix, near.iy) == (0, 0)


@pytest.mark.parametrize("name", ["max_entropy", "info_gain"])
def test_voxel_policies_choose_the_uncertain_column_and_press_to_its_deepest_uncertain_voxel(name, memory):
    v = VoxelGrid(["m0", "m1", "m2"], (3, 2, 4), cell_size=0.0025)
    for ix in range(3):
        for iy in range(2):
            # Column (2, 1) was pressed only 5 mm deep: its two lower voxels are still unknown.
            v.update_press(0.0025 * (ix + 0.5), 0.0025 * (iy + 0.5), 0.005 if (ix, iy) == (2, 1) else 0.01,
                           CERTAIN[0])
    t = make_policy(name, memory=memory, max_depth=0.01).next_target(v)
    assert (t.ix, t.iy, t.depth) == (2, 1, pytest.approx(0.01))
    # A press limited to 6 mm reaches 3 voxels; the target depth never exceeds the limit.
    t = make_policy(name, memory=memory, max_depth=0.006).next_target(v)
    assert (t.ix, t.iy, t.depth) == (2, 1, pytest.approx(0.006))
    # Pressed to the bottom, the column is certain and nothing is left.
    v.update_press(0.00625, 0.00375, 0.01, CERTAIN[0])
    assert make_policy(name, memory=memory, max_depth=0.01).next_target(v) is None


def test_make_policy_rejects_unknown_names_and_missing_inputs():
    with pytest.raises(ValidationError, match="known: predefined, raster, random, max_entropy, info_gain"):
        make_policy("spiral")
    with pytest.raises(ValidationError, match="memory"):
        make_policy("info_gain")
    with pytest.raises(ValidationError, match="travel_cost_per_mm"):
        make_policy("max_entropy", travel_cost_per_mm=-1.0)


def test_entropy_stop_rules():
    g = _certain_except({(2, 2)})
    post = g.postprocessed()
    h = post.entropy()
    assert stop_reason(post, mean_entropy=float(h.mean()) + 1e-9) == "mean_entropy"
    assert stop_reason(post, mean_entropy=float(h.mean()) - 1e-6) is None
    assert stop_reason(post, max_entropy=float(h.max()) + 1e-9) == "max_entropy"
    assert stop_reason(post, max_entropy=float(h.max()) - 1e-6) is None
    assert stop_reason(post) is None


# ---------------------------------------------------------------------------------------------------------------
# scenario keys and the closed loop


BASE = {
    "scenario": {"name": "tiny", "seed": 4, "fidelity": "analytic"},
    "materials": [{"name": "soft", "young_kpa": 20.0}, {"name": "hard", "young_kpa": 450.0, "poisson": 0.4}],
    "training": {"presses_per_material": 5, "depth_mm": 4.0, "max_force_n": 10.0},
    "exploration": {"policy": "info_gain", "budget": 12, "depth_mm": 4.0, "max_force_n": 10.0,
                    "variability": "robot"},
    "objects": [{"name": "slab", "size_mm": [40.0, 30.0, 40.0], "position_mm": [20.0, 15.0], "material": "soft",
                 "inclusions": [{"material": "hard", "shape": "column", "center_mm": [35.0, 15.0],
                                 "size_mm": [10.0, 30.0]}]}],
    "outputs": {"figures": False, "haptic_material": False},
}


def _scenario(**exploration):
    import copy

    raw = copy.deepcopy(BASE)
    raw["exploration"].update(exploration)
    return parse_scenario(raw, "tiny.toml")


@pytest.mark.parametrize("key, value, policy, match", [
    ("stop_min_gain", 0.1, "raster", "stop_min_gain: only the info_gain policy"),
    ("travel_cost_per_mm", 0.01, "random", "travel_cost_per_mm: only max_entropy, info_gain and boundary"),
    ("map", "voxel", "boundary", "exploration.policy: the boundary policy plans on a fine 2-D map"),
    ("stop_max_entropy", -0.1, "raster", "stop_max_entropy: must be >= 0.0"),
    ("policy", "spiral", "raster", "exploration.policy: must be one of .*max_entropy, info_gain"),
    ("extrapolation_passes", 0, "raster", 'exploration.extrapolation_passes: must be >= 1 \\(or "all"\\)'),
    ("extrapolation_passes", "many", "raster", 'extrapolation_passes: expected an integer >= 1 or "all"'),
    ("extrapolation_passes", 2.0, "raster", "extrapolation_passes: expected"),
    ("objective", "entropy", "max_entropy", "exploration.objective: only the info_gain policy"),
    ("objective", "speed", "info_gain", "exploration.objective: must be one of accuracy, entropy"),
    ("feature_size_mm", 0.0, "info_gain", "exploration.feature_size_mm: must be > 0.0"),
    ("feature_size_mm", 40.0, "random", "feature_size_mm: only the info_gain policy"),
])
def test_scenario_rejects_bad_exploration_keys_naming_them(key, value, policy, match):
    with pytest.raises(ValidationError, match=match):
        _scenario(**{"policy": policy, key: value})


def test_info_gain_settings_reach_the_policy(trained):
    sc = _scenario(objective="entropy", feature_size_mm=45.0)
    assert (sc.exploration.objective, sc.exploration.feature_size) == ("entropy", pytest.approx(0.045))
    pol = make_policy("info_gain", memory=trained, objective=sc.exploration.objective,
                      feature_size=sc.exploration.feature_size)
    assert (pol.objective, pol.correlation_mm, pol.coverage_weight) == ("entropy", pytest.approx(45.0), 0.3)
    assert _scenario().exploration.objective == "accuracy"
    with pytest.raises(ValidationError, match="objective must be one of accuracy, entropy"):
        InfoGain(trained, objective="speed")


@pytest.fixture(scope="module")
def trained():
    from palpate.core.session.progress import Progress
    from palpate.core.session.sources import scenario_source_maker
    from palpate.core.session.training import train_memory

    sc = _scenario()
    make = scenario_source_maker(sc)
    return train_memory(sc, make, [11, 12], Progress(enabled=False)).memory


def _explore(memory, make_source=None, **exploration):
    from palpate.core.session.explore import explore_object
    from palpate.core.session.progress import Progress
    from palpate.core.session.report import object_summary
    from palpate.core.session.sources import scenario_source_maker

    sc = _scenario(**exploration)
    result = explore_object(sc, sc.objects[0], memory, make_source or scenario_source_maker(sc), 21,
                            Progress(enabled=False))
    return object_summary(result)


def test_loop_stops_at_the_press_budget(trained):
    s = _explore(trained, policy="raster", budget=3)
    assert (s["presses"], s["stop_reason"]) == (3, "budget")
    row = s["per_press"][-1]
    assert 0.0 <= row["accuracy_all_cells_postprocessed"] <= 1.0
    assert row["mean_entropy_postprocessed"] <= row["mean_entropy"]


def test_loop_stops_once_the_mean_entropy_is_low_enough(trained):
    s = _explore(trained, stop_mean_entropy=0.15)
    h = [r["mean_entropy_postprocessed"] for r in s["per_press"]]
    assert s["stop_reason"] == "mean_entropy" and s["presses"] < 12
    assert h[-1] <= 0.15 and all(v > 0.15 for v in h[:-1])


def test_loop_stops_once_the_max_entropy_is_low_enough(trained):
    s = _explore(trained, stop_max_entropy=0.2)
    assert s["stop_reason"] == "max_entropy" and s["presses"] < 12


def test_loop_stops_when_no_cell_is_worth_a_press(trained):
    s = _explore(trained, stop_min_gain=0.5)
    assert s["stop_reason"] == "min_gain"
    assert 0 < s["presses"] < 12
    assert all(r["score"] >= 0.5 for r in s["per_press"])
    assert _explore(trained, stop_min_gain=100.0)["presses"] == 0


def test_loop_stops_when_the_policy_has_nothing_left(trained):
    s = _explore(trained, policy="raster", budget=20)  # 4 x 3 cells
    assert (s["presses"], s["stop_reason"]) == (12, "policy_exhausted")


def test_loop_drives_any_object_with_press_and_rejects_one_without(trained):
    from palpate.core.session.sources import scenario_source_maker

    pressed = []

    class Finger:
        def __init__(self, inner):
            self.inner = inner

        def press(self, target):
            pressed.append((target.x, target.y, target.depth))
            return self.inner.press(target)

    sc = _scenario()
    inner = scenario_source_maker(sc)
    s = _explore(trained, make_source=lambda *a: Finger(inner(*a)), policy="info_gain", budget=4)
    assert s["presses"] == 4 and len(pressed) == 4
    assert [list(r["target_m"]) for r in s["per_press"]] == [[x, y] for x, y, _ in pressed]
    with pytest.raises(ValidationError, match="has no press"):
        _explore(trained, make_source=lambda *a: object(), budget=1)


def test_scenario_extrapolation_passes_default_all_and_voxel_refusal():
    assert _scenario().exploration.extrapolation_passes == 1
    assert _scenario(extrapolation_passes="all").exploration.extrapolation_passes is None
    assert _scenario(extrapolation_passes=3).exploration.extrapolation_passes == 3
    with pytest.raises(ValidationError, match="extrapolation_passes: iterated eq. 6.15 .* map is 'voxel'"):
        _scenario(extrapolation_passes=2, map="voxel")


def test_loop_reports_and_returns_the_iterated_post_processing(trained):
    from palpate.core.session.explore import explore_object
    from palpate.core.session.progress import Progress
    from palpate.core.session.report import object_summary
    from palpate.core.session.sources import scenario_source_maker

    sc = _scenario(policy="raster", budget=2, extrapolation_passes="all")
    result = explore_object(sc, sc.objects[0], trained, scenario_source_maker(sc), 21, Progress(enabled=False))
    summary, grid, post = object_summary(result), result.grid, result.post
    cal = sc.exploration.calibration
    certainty = cal.extrapolation_certainty
    assert certainty < 1  # the calibrated default: an extrapolated cell is less certain than its sources
    assert np.array_equal(post.probabilities, grid.postprocessed(
        passes=None, certainty=certainty, wall_reliability=cal.wall_reliability).probabilities)
    # Two presses in one corner fill the whole 4x3 map: no cell is left at the uniform prior.
    assert not np.isclose(post.probabilities, 0.5).all(axis=-1).any()
    assert summary["per_press"][-1]["mean_entropy_postprocessed"] == pytest.approx(float(post.mean_entropy()))


def test_disagreement_is_high_between_two_materials_and_zero_inside_one():
    g = _grid((7, 3))
    g.update_cell(1, 1, CERTAIN[0])
    g.update_cell(5, 1, CERTAIN[2])
    g.update_cell(0, 0, CERTAIN[0])
    d = disagreement(g)  # (ny, nx)
    assert d[1, 3] == pytest.approx(0.5, abs=0.15)  # two apart from each: a coin toss, one soft corner aside
    assert d[0, 1] == 0.0 and d[1, 0] == 0.0  # only material 0 in reach
    assert d[1, 1] == 0.0 and d[1, 5] == 0.0  # explored
    assert np.all(np.isfinite(d)) and d.min() >= 0.0 and d.max() < 1.0


def test_info_gain_starts_with_a_spread_lattice_then_goes_to_the_boundary(memory):
    q = outcome_posteriors(memory)
    g = _grid((9, 9))
    policy = InfoGain(memory)
    first, last = [], None
    for _ in range(9):
        t = policy.next_target(g, None, last)
        first.append((t.ix, t.iy))
        # Left third material 0, the rest material 2: the boundary lies between columns 1 and 4.
        g.update_cell(t.ix, t.iy, q[0, 0] if t.ix < 3 else q[2, 0])
        last = (t.ix, t.iy)
    assert sorted(first) == [(x, y) for x in (1, 4, 7) for y in (1, 4, 7)]
    t = InfoGain(memory, objective="entropy").next_target(g, None, last)
    assert t.ix in (2, 3)
    flat = InfoGain(memory, spread_stride=1, boundary_weight=0.0)
    assert flat.next_target(_grid((9, 9))) is not None


def test_uncovered_marks_cells_with_no_pressed_cell_among_themselves_and_their_4_neighbours():
    g = _grid((5, 4))
    g.update_cell(1, 1, CERTAIN[0])
    u = uncovered(g)  # (ny, nx)
    assert u[1, 1] == 0 and u[0, 1] == 0 and u[1, 0] == 0 and u[2, 1] == 0 and u[1, 2] == 0
    assert u[0, 0] == 1 and u[2, 2] == 1 and u[3, 4] == 1
    assert u.sum() == 20 - 5


def test_the_shipped_info_gain_scenario_maps_the_block_with_fewer_presses_than_cells(repo_dir, tmp_path):
    """scenarios/explore_info_gain.toml end to end: lattice, then presses by expected accuracy, stopped by the
    min-gain rule before the budget, the post-processed map mostly right (the lump is 2 x 2 cells and hides
    between lattice points until a hole is checked)."""
    from palpate.core.session.run import run_scenario
    from palpate.core.world.scenario_file import load_scenario

    sc = load_scenario(repo_dir / "scenarios" / "explore_info_gain.toml")
    summary = run_scenario(sc, tmp_path)
    (obj,) = summary["objects"]
    ny, nx = obj["grid"]["shape"]  # the map's array shape: rows, columns
    # stopped by the rule, before the budget, with well under one press per cell (the contact law feels the lump
    # from the neighbouring cells too, so its surroundings take more presses than the old surface-only law's half)
    assert obj["stop_reason"] == "min_gain" and obj["presses"] < min(sc.exploration.budget, 0.6 * nx * ny)
    # the map against what this physics allows (every column pressed once; 0.95 here): a press feels its
    # neighbours, so a point-wise ground truth is not all attainable
    ceiling = obj["attainable_accuracy"]["ceiling"]
    assert ceiling >= 0.9
    assert obj["accuracy"]["all_cells_after_postprocessing"] >= 0.9 * ceiling
    # the same accuracy split by whether a wall lies within a press's contact radius: the parts add up, the lump
    # makes both kinds, and the cells clear of walls are the easier ones
    walls = obj["accuracy"]["by_walls_after_postprocessing"]
    clear, near = walls["clear"], walls["near"]
    assert clear["cells"] + near["cells"] == nx * ny and clear["cells"] > 0 and near["cells"] > 0
    assert (clear["accuracy"] * clear["cells"] + near["accuracy"] * near["cells"]) / (nx * ny) == pytest.approx(
        obj["accuracy"]["all_cells_after_postprocessing"])
    assert clear["accuracy"] >= near["accuracy"]
    # the lattice comes first: every third cell, centred (1-based cells in the summary)
    lattice = {(x + 1, y + 1) for x in range((nx - 1) % 3 // 2, nx, 3) for y in range((ny - 1) % 3 // 2, ny, 3)}
    assert {tuple(r["cell"]) for r in obj["per_press"][:len(lattice)]} == lattice
    # a hard cell was found: the lump is not averaged away
    named = {sc.references[int(np.argmax(r["posterior"]))] for r in obj["per_press"] if r["posterior"]}
    assert "Material_3" in named


def test_attainable_accuracy_reuses_a_full_raster_and_presses_every_column_otherwise(trained):
    from palpate.core.session.ceiling import attainable_accuracy, ceiling_summary
    from palpate.core.session.explore import explore_object
    from palpate.core.session.progress import Progress
    from palpate.core.session.sources import scenario_source_maker

    def run(**exploration):
        sc = _scenario(**exploration)
        make = scenario_source_maker(sc)
        return sc, make, explore_object(sc, sc.objects[0], trained, make, 21, Progress(enabled=False))

    sc, make, full = run(policy="raster", budget=12)  # 4 x 3 cells: the run is its own ceiling
    c = attainable_accuracy(sc, sc.objects[0], trained, make, 5, Progress(enabled=False), full)
    assert (c.reused_run, c.presses, c.accuracy) == (True, 12, full.steps[-1].accuracy_postprocessed)
    sc, make, short = run(policy="info_gain", budget=3)
    c = attainable_accuracy(sc, sc.objects[0], trained, make, 5, Progress(enabled=False), short)
    assert not c.reused_run and c.presses == 12 and 0.5 <= c.accuracy <= 1.0
    s = ceiling_summary(short, c)
    acc = [st.accuracy_postprocessed for st in short.steps]
    assert s["ceiling"] == c.accuracy and s["ceiling_presses"] == 12
    assert s["presses_to_level"] == next((k + 1 for k, a in enumerate(acc) if a >= 0.95), None)


def test_map_postprocessing_round_trips_and_names_bad_metadata():
    from palpate.core.session.explore import MapPostprocessing

    for settings in (MapPostprocessing(), MapPostprocessing(None, True), MapPostprocessing(3, False)):
        assert MapPostprocessing.from_dict(settings.to_dict(), "rec.mcap") == settings
    assert MapPostprocessing.from_dict({}, "rec.mcap") == MapPostprocessing(1, False)  # an older recording
    with pytest.raises(ValidationError, match="rec.mcap: extrapolation_passes must be an integer >= 1"):
        MapPostprocessing.from_dict({"extrapolation_passes": 0}, "rec.mcap")
    with pytest.raises(ValidationError, match="rec.mcap: voxel_lateral must be true or false"):
        MapPostprocessing.from_dict({"voxel_lateral": "yes"}, "rec.mcap")
    with pytest.raises(ValidationError, match="rec.mcap: unknown key"):
        MapPostprocessing.from_dict({"passes": 2}, "rec.mcap")


def test_policies_plan_on_the_map_without_wall_tempering():
    from palpate.core.mapping.calibration import DEFAULT_CALIBRATION, SEED_CALIBRATION
    from palpate.core.mapping.grids import Grid2D
    from palpate.core.session.explore import MapPostprocessing

    g = Grid2D(["a", "b"], (3, 1))
    g.update_cell(0, 0, [0.95, 0.05])
    g.update_cell(1, 0, [0.05, 0.95])  # a wall between two pressed cells
    settings = MapPostprocessing()
    post = settings.apply(g, DEFAULT_CALIBRATION)
    plan = settings.planned_on(g, DEFAULT_CALIBRATION, post)
    assert DEFAULT_CALIBRATION.wall_reliability < 1
    # the reported map is less sure beside the wall; the planned-on one is the map without the tempering
    assert post.probabilities[0, 0].max() < plan.probabilities[0, 0].max()
    unwalled = g.postprocessed(certainty=DEFAULT_CALIBRATION.extrapolation_certainty)
    assert np.array_equal(plan.probabilities, unwalled.probabilities)
    seed_post = settings.apply(g, SEED_CALIBRATION)
    assert settings.planned_on(g, SEED_CALIBRATION, seed_post) is seed_post


def test_the_boundary_policy_presses_points_inside_the_inner_half_of_their_cells(trained):
    from palpate.core.session.boundaries import boundary_reader
    from palpate.core.session.explore import explore_object
    from palpate.core.session.progress import Progress
    from palpate.core.session.sources import scenario_source_maker

    sc = _scenario(policy="boundary", budget=8)
    reader, why = boundary_reader(sc)
    assert reader is not None, why
    res = explore_object(sc, sc.objects[0], trained, scenario_source_maker(sc), 21, Progress(enabled=False),
                         boundary_reader=reader)
    centres = res.geometry.cell_centres()
    off = [np.subtract(s.target, centres[s.cell[1], s.cell[0]]) for s in res.steps]
    assert len(res.steps) == 8 and all(s.boundary is not None for s in res.steps)
    assert all(np.all(np.abs(d) <= res.geometry.cell_size / 4 + 1e-12) for d in off)
    assert sum(np.any(np.abs(d) > 1e-4) for d in off) >= 3  # after the lattice, off the centres
    assert all(np.hypot(*(np.subtract(s.result.location, s.target))) < 2e-3 for s in res.steps)
