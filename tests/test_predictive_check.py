"""The predictive realism check: its discriminant against scikit-learn's, its energy distances against the direct
formula, its errors, and its size and power on a synthetic simulator whose truth is known."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import binom

from palpate.core.errors import ValidationError
from palpate.core.perception.param_stats import PressTable, energy_distance
from palpate.core.perception.predictive_check import (
    MIN_SESSIONS,
    lda_loo_accuracy,
    predictive_check,
    session_energy,
)

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))
from realism_predictive import REAL, TRUTHS, draw_sessions, draw_table, fitted_gaussians, trial  # noqa: E402

from palpate.core.perception.param_stats import table_from_csv  # noqa: E402


def _sklearn_loo(x0, x1, shrinkage):
    from sklearn.discriminant_analysis import LinearDiscriminantAnalysis

    x = np.vstack([x0, x1])
    y = np.r_[np.zeros(len(x0)), np.ones(len(x1))]
    hits = 0
    for i in range(len(x)):
        keep = np.arange(len(x)) != i
        lda = LinearDiscriminantAnalysis(solver="lsqr", shrinkage=shrinkage, priors=[0.5, 0.5])
        hits += int(lda.fit(x[keep], y[keep]).predict(x[i:i + 1])[0] == y[i])
    return hits / len(x)


@pytest.mark.parametrize("seed, shift, shrinkage", [(0, 0.0, 0.1), (1, 0.8, 0.1), (2, 2.0, 0.1), (3, 0.5, 0.0),
                                                    (4, 1.0, 0.7), (5, 0.3, 0.1)])
def test_closed_form_leave_one_out_equals_scikit_learn_refitting_each_time(seed, shift, shrinkage):
    rng = np.random.default_rng(seed)
    cov = np.array([[2.0, 0.5, 0, 0], [0.5, 1.0, 0.2, 0], [0, 0.2, 0.5, 0.1], [0, 0, 0.1, 3.0]])
    x0 = rng.multivariate_normal(np.zeros(4), cov, size=10)
    x1 = rng.multivariate_normal(np.full(4, shift), cov, size=12)
    assert lda_loo_accuracy(x0, x1, shrinkage) == pytest.approx(_sklearn_loo(x0, x1, shrinkage), abs=1e-12)


def test_discriminant_tells_apart_separated_classes_and_not_one_distribution():
    rng = np.random.default_rng(7)
    same = [lda_loo_accuracy(rng.normal(size=(10, 4)), rng.normal(size=(10, 4))) for _ in range(200)]
    assert np.mean(same) < 0.6
    assert lda_loo_accuracy(rng.normal(size=(10, 4)), rng.normal(size=(10, 4)) + 5.0) == 1.0


def test_leave_one_session_out_energies_equal_the_direct_formula():
    rng = np.random.default_rng(3)
    sessions = [rng.normal(size=(n, 3)) * (1 + k % 3) for k, n in enumerate([10, 9, 10, 7, 10])]
    real = rng.normal(size=(10, 3)) + 0.5
    stat, null = session_energy(real, sessions)
    ones = np.ones(3)
    assert stat == pytest.approx(energy_distance(real, np.vstack(sessions), ones), rel=1e-10)
    for s in range(len(sessions)):
        others = np.vstack([x for k, x in enumerate(sessions) if k != s])
        assert null[s] == pytest.approx(energy_distance(sessions[s], others, ones), rel=1e-10)


def _gauss_table(rng, materials=("A", "B"), presses=10, scale=1.0):
    rows = []
    for i, _ in enumerate(materials):
        x = rng.normal(size=(presses, 6)) * scale + np.array([50.0 * (i + 1), 5, 100, 3.0 * (i + 1), 4, 100])
        rows.append(x)
    return PressTable(tuple(materials), tuple(rows))


def test_errors_name_the_limit():
    rng = np.random.default_rng(0)
    real = _gauss_table(rng)
    with pytest.raises(ValidationError, match=f"at least {MIN_SESSIONS} are needed"):
        predictive_check(real, [_gauss_table(rng) for _ in range(MIN_SESSIONS - 1)], ("A", "B"))
    short = PressTable(("A", "B"), (real.rows[0][:2], real.rows[1]))
    with pytest.raises(ValidationError, match="2 presses of 'A'; at least 4"):
        predictive_check(short, [_gauss_table(rng) for _ in range(MIN_SESSIONS)], ("A", "B"))
    with pytest.raises(ValidationError, match="leave-one-out posteriors of shape"):
        predictive_check(real, [_gauss_table(rng) for _ in range(MIN_SESSIONS)], ("A", "B"),
                         session_loo=np.ones((MIN_SESSIONS, 3)))
    with pytest.raises(ValidationError, match="two \\(n, d\\) arrays"):
        lda_loo_accuracy(np.zeros((2, 4)), np.zeros((5, 4)))


def test_check_reports_every_material_band_and_verdict_in_its_dict():
    rng = np.random.default_rng(1)
    sessions = [_gauss_table(rng) for _ in range(MIN_SESSIONS)]
    check = predictive_check(_gauss_table(rng, scale=3.0), sessions, ("A", "B"),
                             session_loo=np.full((MIN_SESSIONS, 2), 0.9), real_loo=np.array([0.9, 0.9]))
    doc = check.to_dict()
    assert set(doc["materials"]) == {"A", "B"}
    assert set(doc["materials"]["A"]["bands"]) == {"cv n1", "cv a1", "spread", "n2<0", "loo"}
    # the first material's posterior votes, the second's does not; a table three times as spread fails
    assert doc["materials"]["A"]["bands"]["loo"]["decisive"] and not doc["materials"]["B"]["bands"]["loo"]["decisive"]
    assert not check.passed and not doc["passed"]
    assert doc["band_misses"] == check.band_misses >= 2


# Size and power. The benchmark (benchmarks/realism_predictive.py) measures them on 100 trials per truth with
# fresh sessions each; here, to stay fast, 20 trials per truth draw S = 100 sessions from 4 pools of 105 (5 trials
# per pool; the truths share the pools, as they share one simulator). Every trial's real table and sessions are
# still draws of the simulator, so a trial is judged as with fresh sessions; trials of one pool are correlated,
# which widens the count's spread somewhat beyond the binomial's.
TRIALS, POOLS, POOL_SIZE, SESSIONS = 20, 4, 105, 100
#: Judged right at least this many of TRIALS times. The benchmark measured 95, 100, 97 and 100 of 100; at the lower
#: rates of RATE a binomial count of TRIALS falls below these with probability < 2%
#: (test_thresholds_leave_a_binomial_margin).
AT_LEAST = {"simulator": 15, "2x spread": 19, "0.6x spread": 17, "shifted a1, a2": 19}
RATE = {"simulator": 0.9, "2x spread": 0.99, "0.6x spread": 0.95, "shifted a1, a2": 0.99}


def test_thresholds_leave_a_binomial_margin():
    for truth, k in AT_LEAST.items():
        assert binom.cdf(k - 1, TRIALS, RATE[truth]) < 0.02, truth


@pytest.fixture(scope="module")
def pools():
    g = fitted_gaussians(table_from_csv(REAL))
    return g, [draw_sessions(g, POOL_SIZE, np.random.default_rng([11, p])) for p in range(POOLS)]


@pytest.mark.parametrize("truth", list(TRUTHS))
def test_size_and_power_on_a_synthetic_simulator(pools, truth):
    g, pool = pools
    rng = np.random.default_rng([5, list(TRUTHS).index(truth)])
    right = sum(trial(g, truth, SESSIONS, rng, pool[t * POOLS // TRIALS]).passed == (truth == "simulator")
                for t in range(TRIALS))
    assert right >= AT_LEAST[truth]


def test_moving_a_table_of_the_simulator_in_n1_fails_both_tests_of_every_material():
    # the same real presses, moved 3 of the simulator's standard deviations in n1
    g = fitted_gaussians(table_from_csv(REAL))
    rng = np.random.default_rng(21)
    tables, loo = draw_sessions(g, MIN_SESSIONS, rng)
    real = draw_table(g, rng)
    check = predictive_check(real, tables, g.materials, session_loo=loo)
    moved = PressTable(real.materials, tuple(r + np.array([3 * np.sqrt(c[0, 0]), 0, 0, 0, 0, 0])
                                             for r, c in zip(real.rows, g.cov, strict=True)))
    bad = predictive_check(moved, tables, g.materials, session_loo=loo)
    assert not bad.passed and not any(m.c2st_passed or m.energy_passed for m in bad.materials)
    for before, after in zip(check.materials, bad.materials, strict=True):
        assert after.c2st > before.c2st and after.energy > before.energy
