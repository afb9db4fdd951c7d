"""The realism decision statistic (benchmarks/realism_expected.py): the expected targets of a population of presses
pooled over seeds, and its seed-bootstrap standard error, paired between populations."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from palpate.core.errors import ValidationError
from palpate.core.perception.param_stats import PressTable, table_from_csv
from palpate.core.perception.realism_targets import check_targets, loo_self

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "benchmarks"))
from realism_ceiling import read_simulated  # noqa: E402
from realism_expected import (  # noqa: E402
    SeedPresses,
    expected_targets,
    perfect_seeds,
    pooled_held,
    simulated_seeds,
)

REAL = REPO / "models" / "realism" / "seed000_tables_6_3_to_6_5.csv"
HELDOUT = REPO / "benchmarks" / "data" / "thesis_ch6_heldout_presses.csv"
MATERIALS = ["Material_1", "Material_2", "Material_3"]


@pytest.fixture(scope="module")
def real() -> PressTable:
    return table_from_csv(REAL)


def _seed(table: PressTable, real: PressTable) -> SeedPresses:
    """The table as one seed, each row its own press (ids = row index), with the targets it holds."""
    held = check_targets(table, real, loo_self(table, MATERIALS), MATERIALS).held
    return SeedPresses(table.rows, tuple(np.arange(len(r)) for r in table.rows), held)


def test_a_seed_pooled_with_its_own_copy_is_drawn_as_a_boot_out_resample_of_its_presses(real):
    seeds = [_seed(real, real)] * 2  # 20 pooled presses per material, each real press twice with one id
    u = np.random.default_rng(1).random((6, 3, 10))
    held = pooled_held(seeds, real, u, np.random.default_rng(2))
    for k in range(len(u)):
        picks = [(u[k, i] * 20).astype(int) % 10 for i in range(3)]  # the position in the pool, as a real press
        if any(np.bincount(p).max() > 10 - 3 for p in picks):
            continue  # redrawn: fewer than MIN_SAMPLES left by a held-out group
        table = PressTable(real.materials, tuple(real.rows[i][p] for i, p in enumerate(picks)))
        ref = check_targets(table, real, loo_self(table, MATERIALS, picks), MATERIALS).held
        np.testing.assert_array_equal(held[k], ref)


def test_two_identical_populations_differ_by_zero_with_a_standard_error_of_zero(real):
    seeds = perfect_seeds(real, 4, np.random.default_rng(0))
    e = expected_targets([seeds, seeds], real, draws=20, resamples=4, resample_draws=10, rng=np.random.default_rng(3))
    assert e.expected[1] == e.expected[0] and e.se(1, 0) == 0.0
    np.testing.assert_array_equal(e.counts[:, 0], e.counts[:, 1])
    assert e.se(0) >= 0.0 and e.se_per_seed(0) > 0.0
    # each seed's own count: what perfect_seeds checked
    assert e.observed[0] == pytest.approx(np.mean([s.held.sum() for s in seeds]))


def test_a_wider_spread_of_one_materials_n1_lowers_only_that_materials_cv_target(real):
    wide = [r.copy() for r in real.rows]
    n1 = wide[2][:, 0]
    wide[2][:, 0] = n1.mean() + 1.6 * (n1 - n1.mean())  # the hard foam's CV of n1 x1.6
    base, spread = [_seed(real, real)] * 3, [_seed(PressTable(real.materials, tuple(wide)), real)] * 3
    e = expected_targets([base, spread], real, draws=60, resamples=2, resample_draws=5, rng=np.random.default_rng(4))
    assert e.probability[1, 2, 0] < e.probability[0, 2, 0] - 0.2
    # the same uniforms draw the same presses: the other materials' CV and n2 targets are the same draws
    np.testing.assert_array_equal(e.probability[1, :2, :3], e.probability[0, :2, :3])
    np.testing.assert_array_equal(e.probability[1, 2, 1:3], e.probability[0, 2, 1:3])
    assert e.expected[1] < e.expected[0]


def test_all_twelve_are_held_no_more_often_than_the_rarest_single_target(real):
    seeds = perfect_seeds(real, 3, np.random.default_rng(5))
    e = expected_targets([seeds], real, draws=60, resamples=2, resample_draws=5, rng=np.random.default_rng(6))
    assert 0.0 <= e.all_held[0] <= e.probability[0].min()


def test_the_csvs_seeds_keep_what_each_seed_held(real):
    seeds, pops = simulated_seeds(HELDOUT, real)
    sim = read_simulated(HELDOUT, real)
    assert seeds == sim.seeds == (6, 301, 302, 303, 304, 305)
    np.testing.assert_array_equal(sum(p.held.astype(int) for p in pops), sim.held)
    assert sum(int(p.held.sum()) for p in pops) == 52
    # ids distinct across seeds: a seed drawn twice by the bootstrap gives copies that are held out together
    ids = np.concatenate([p.ids[0] for p in pops])
    assert len(np.unique(ids)) == len(ids)


def test_populations_of_different_sizes_or_too_few_draws_are_refused(real):
    a, b = perfect_seeds(real, 3, np.random.default_rng(0)), perfect_seeds(real, 2, np.random.default_rng(1))
    with pytest.raises(ValidationError, match="same number of seeds"):
        expected_targets([a, b], real, 10, 2, 2, np.random.default_rng(0))
    with pytest.raises(ValidationError, match="resamples"):
        expected_targets([a], real, 10, 1, 2, np.random.default_rng(0))


def test_session_levels_pool_only_the_within_seed_spread(real):
    base = perfect_seeds(real, 3, np.random.default_rng(7))
    # each seed's presses of every material scaled by its own session gain: n1, n2 by k, Phi_N by k^2
    scaled = []
    for s, k in zip(base, (0.5, 1.0, 2.0), strict=True):
        f = np.array([k, k, k * k, 1.0, 1.0, 1.0])
        scaled.append(SeedPresses(tuple(r * f for r in s.rows), s.ids, s.held))
    kw = {"draws": 60, "resamples": 2, "resample_draws": 5}
    pooled = expected_targets([base, scaled], real, rng=np.random.default_rng(8), **kw)
    session = expected_targets([base, scaled], real, rng=np.random.default_rng(8), session_levels=True, **kw)
    # pooled, the gains between seeds widen every material's n1; at one seed's level the CVs and signs are the same
    assert np.all(pooled.probability[1, :, 0] < pooled.probability[0, :, 0])
    np.testing.assert_array_equal(session.probability[1, :, :3], session.probability[0, :, :3])
