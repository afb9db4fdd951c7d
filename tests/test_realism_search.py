"""The calibration's searches on problems with a known answer, and a fit that survives a failed report session."""

from pathlib import Path

import numpy as np
import pytest

import palpate.sim.realism.calibrate as calibration
from palpate.core.errors import PalpateError, PressShortfall, ValidationError
from palpate.core.perception.param_stats import PressTable
from palpate.core.world.scenario_file import load_scenario
from palpate.sim.realism.calibrate import SeedRun, calibrate
from palpate.sim.realism.parameters import free_parameters
from palpate.sim.realism.profile import LAB
from palpate.sim.realism.search import BudgetSpent, run_search

SCENARIO = Path(__file__).resolve().parent.parent / "scenarios" / "thesis_ch6.toml"


def _rough_problem(d: int, seed: int, budget: int, failing: float = 0.0):
    """Residuals linear in u with a known zero, plus steps (a press's fit changing) and a dead band (a parameter
    without effect over part of its box); candidates with u[1] + u[2] below ``failing`` fail (NaN, as a press the
    drive cannot follow); records every candidate and spends ``budget`` at most."""
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(3 * d + 3, d)) * 10.0
    truth = rng.uniform(0.15, 0.85, d)
    seen: list[tuple[float, np.ndarray]] = []

    def residuals(u: np.ndarray) -> np.ndarray:
        if len(seen) >= budget:
            raise BudgetSpent
        assert np.all(u >= 0.0) and np.all(u <= 1.0), u
        x = u - truth
        x[0] = max(x[0], 0.0) if truth[0] < 0.5 else min(x[0], 0.0)  # no slope on one side of the truth
        r = a @ x + 2.0 * np.floor(3.0 * np.sin(40.0 * u.sum()))
        if u[1] + u[2] < failing:
            r = np.full_like(r, np.nan)
        seen.append((float(r @ r) if np.all(np.isfinite(r)) else np.inf, u.copy()))
        return r

    start = np.clip(truth + np.where(truth < 0.5, 0.3, -0.3), 0.0, 1.0)
    return residuals, start, truth, seen


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_the_trust_region_finds_the_zero_of_a_rough_problem_where_nelder_mead_stalls(seed):
    budget = 80
    errors = {}
    for search in ("trust-region", "nelder-mead"):
        residuals, start, truth, seen = _rough_problem(5, seed, budget)
        run_search(search, residuals, start, budget)
        best = min(seen, key=lambda s: s[0])
        errors[search] = float(np.sqrt(np.mean((best[1] - truth) ** 2)))
        assert len(seen) <= budget
    assert errors["trust-region"] < 0.1
    assert errors["trust-region"] < errors["nelder-mead"]


@pytest.mark.parametrize("seed, margin, start_fails, tol", [(4, 0.02, False, 0.05), (3, 0.1, True, 0.1)])
def test_the_trust_region_finds_an_answer_beside_candidates_that_fail(seed, margin, start_fails, tol):
    # the answer lies ``margin`` from a region where every candidate fails (NaN residuals), or the start is in it
    truth = _rough_problem(5, seed, 80)[2]
    residuals, start, truth, seen = _rough_problem(5, seed, 80, failing=truth[1] + truth[2] - margin)
    assert (start[1] + start[2] < truth[1] + truth[2] - margin) == start_fails
    run_search("trust-region", residuals, start, 80)
    assert sum(np.isinf(j) for j, _ in seen) >= 5  # it did meet them
    best = min(seen, key=lambda s: s[0])
    assert np.sqrt(np.mean((best[1] - truth) ** 2)) < tol  # from 0.3 box widths off


def test_the_trust_region_spends_its_budget_and_repeats_itself():
    paths = []
    for _ in range(2):
        residuals, start, _, seen = _rough_problem(4, 7, 40)
        run_search("trust-region", residuals, start, 40, seed=3)
        paths.append(np.array([u for _, u in seen]))
    assert len(paths[0]) == 40
    np.testing.assert_array_equal(paths[0], paths[1])
    with pytest.raises(ValidationError, match="unknown search 'simplex'"):
        run_search("simplex", lambda u: u, np.zeros(2), 5)


def test_a_fit_keeps_going_when_a_report_session_fails(monkeypatch):
    scenario = load_scenario(SCENARIO)
    refs = tuple(scenario.references)
    rng = np.random.default_rng(0)
    real = PressTable(refs, tuple(np.column_stack([rng.uniform(50, 100, 10) * (i + 1), rng.normal(0, 5, 10),
                                                   np.ones(10), rng.uniform(2, 4, 10), rng.normal(0, 5, 10),
                                                   np.ones(10)]) for i in range(len(refs))))
    calls = []

    def fake_session(sc, profile, seed, fidelity):
        calls.append(seed)
        if seed == 202:
            raise PressShortfall("the drive could not follow the hard foam")
        noise = np.random.default_rng(seed).normal(1.0, 0.01, (10, 6))
        return SeedRun(seed, PressTable(refs, tuple(r * noise for r in real.rows)), np.ones(len(refs)))

    monkeypatch.setattr(calibration, "simulate_seed", fake_session)
    free = free_parameters(["press.tilt_deg"])
    result = calibrate(real, scenario, LAB, free, tune_seeds=[101], report_seeds=[201, 202, 203], budget=3,
                       search="trust-region")
    assert [r.seed for r in result.report_runs] == [201, 203]
    assert result.profile.provenance["report_seeds"] == [201, 203]
    assert "PressShortfall" in result.profile.provenance["report_seeds_failed"]["202"]
    assert result.evaluations == 3
    monkeypatch.setattr(calibration, "simulate_seed",
                        lambda sc, p, s, f: fake_session(sc, p, 202 if s >= 200 else s, f))
    with pytest.raises(PalpateError, match="every report seed"):
        calibrate(real, scenario, LAB, free, tune_seeds=[101], report_seeds=[202], budget=2)


def test_tolerances_replace_a_statistics_weight_and_bad_ones_are_refused(tmp_path):
    from palpate.core.cli import main
    from palpate.sim.realism.moments import MOMENTS, SCALES, objective, with_tolerances

    tight = with_tolerances(SCALES, {"log_mean_a1": 0.1})
    real = np.zeros((2, len(MOMENTS)))
    off = real.copy()
    off[:, MOMENTS.index("log_mean_a1")] = 0.3
    assert objective(off, real, SCALES) == pytest.approx(2.0)
    assert objective(off, real, tight) == pytest.approx(18.0)  # three times the default's weight, squared
    assert np.isinf(with_tolerances(SCALES, {"loo_self": np.inf})[MOMENTS.index("loo_self")])
    for bad, match in (({"mean_a1": 0.1}, "unknown statistic 'mean_a1'"), ({"log_cv_n1": 0.0}, "must be > 0"),
                       ({m: np.inf for m in MOMENTS}, "nothing to fit")):
        with pytest.raises(ValidationError, match=match):
            with_tolerances(SCALES, bad)
    table = Path(__file__).resolve().parent.parent / "models" / "realism" / "seed000_tables_6_3_to_6_5.csv"
    out = tmp_path / "p.toml"
    for arg in ("log_mean_a1", "log_mean_a1=x", "mean_a1=0.1"):
        assert main(["calibrate", "realism", str(table), "--scenario", str(SCENARIO), "--out", str(out),
                     "--tolerance", arg, "--quick"]) == 2
    assert not out.exists()
