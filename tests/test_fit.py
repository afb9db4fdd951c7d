"""Interaction-law fits (eq. 6.5, 6.6, 6.16, 6.17): recovery, calibrated errors, degenerate input."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from palpate.core.errors import FitError
from palpate.core.perception.fit import FIT_UNITS, fit_power_law, fit_press
from palpate.core.perception.segment import Press


def _draw(rng, n=30, k1=75.0, k2=12.0, sigma=5.0, x_max=4.0):
    x = np.sort(rng.uniform(0.0, x_max, n))
    return x, k1 * x**1.5 + k2 + sigma * rng.standard_normal(n)


def test_exact_data_gives_exact_parameters_and_zero_residual():
    x = np.linspace(0.0, 4.0, 12)
    y = 75.0 * x**1.5 + 12.0
    fit = fit_power_law(x, y)
    assert fit.k1 == pytest.approx(75.0, rel=1e-12)
    assert fit.k2 == pytest.approx(12.0, rel=1e-10)
    assert fit.phi <= 1e-20 * np.sum(y**2)
    assert fit.n == 12


def test_matches_normal_equations_and_phi_is_eq_6_16(rng):
    x, y = _draw(rng)
    fit = fit_power_law(x, y)
    design = np.column_stack([x**1.5, np.ones_like(x)])
    coef, *_ = np.linalg.lstsq(design, y, rcond=None)
    assert [fit.k1, fit.k2] == pytest.approx(coef, rel=1e-10)
    assert fit.phi == pytest.approx(np.sum((y - (coef[0] * x**1.5 + coef[1])) ** 2), rel=1e-10)
    # Standard errors: sqrt(diag(s^2 (X^T X)^-1)) with s^2 = Phi / (n - 2).
    cov = fit.phi / (len(x) - 2) * np.linalg.inv(design.T @ design)
    assert [fit.se_k1, fit.se_k2] == pytest.approx(np.sqrt(np.diag(cov)), rel=1e-8)
    assert fit.cov_k1k2 == pytest.approx(cov[0, 1], rel=1e-8)


def test_recovers_known_parameters_within_a_few_standard_errors(rng):
    x, y = _draw(rng, n=40)
    fit = fit_power_law(x, y)
    assert abs(fit.k1 - 75.0) < 3 * fit.se_k1
    assert abs(fit.k2 - 12.0) < 3 * fit.se_k2
    assert fit.se_k1 < 2.0  # informative, not just wide


def test_two_sigma_intervals_cover_the_truth_about_95_percent():
    rng = np.random.default_rng(7)
    draws = 600
    cover = np.zeros((draws, 2), dtype=bool)
    for i in range(draws):
        x, y = _draw(rng, n=30, sigma=8.0)
        f = fit_power_law(x, y)
        cover[i] = [abs(f.k1 - 75.0) <= 2 * f.se_k1, abs(f.k2 - 12.0) <= 2 * f.se_k2]
    rate = cover.mean(axis=0)
    # With n - 2 = 28 dof the exact coverage of +-2 se is 94.5 %; 600 draws give a standard error of ~0.9 %.
    assert np.all(rate > 0.92) and np.all(rate < 0.97), rate


def test_stable_in_si_units_where_x_is_tiny():
    # c_D in metres: x^1.5 ~ 1e-4, k1 ~ 2e6; centring and scaling keeps full precision.
    x_mm = np.linspace(0.1, 4.0, 25)
    y = 75.0 * x_mm**1.5 + 12.0
    fit = fit_power_law(x_mm * 1e-3, y)
    assert fit.k1 == pytest.approx(75.0 * 1e-3**-1.5, rel=1e-9)
    assert fit.k2 == pytest.approx(12.0, rel=1e-9)


def test_large_offset_does_not_lose_the_slope():
    x = np.linspace(1000.0, 1000.5, 20)
    y = 3.0 * x**1.5 - 1e5
    fit = fit_power_law(x, y)
    assert fit.k1 == pytest.approx(3.0, rel=1e-6)


@pytest.mark.parametrize(
    ("x", "y", "match"),
    [
        ([0.0, 1.0], [0.0, 1.0], "at least 3"),
        ([1.0, 1.0, 1.0, 1.0], [1.0, 2.0, 3.0, 4.0], "constant"),
        ([0.0, 0.0, 0.0], [1.0, 2.0, 3.0], "constant"),
        ([0.0, 1.0, 2.0], [0.0, 0.0, 0.0], "zero"),
        ([0.0, np.nan, 2.0], [1.0, 2.0, 3.0], "non-finite"),
        ([0.0, 1.0, 2.0], [1.0, np.inf, 3.0], "non-finite"),
        ([0.0, -1.0, 2.0], [1.0, 2.0, 3.0], ">= 0"),
        ([0.0, 1.0, 2.0], [1.0, 2.0], "same length"),
        ([0.0, 1.0, 1e300], [1.0, 2.0, 3.0], "overflow"),
    ],
)
def test_degenerate_input_raises_fit_error(x, y, match):
    with pytest.raises(FitError, match=match):
        fit_power_law(x, y)


finite = st.floats(min_value=-1e12, max_value=1e12, allow_nan=False, allow_infinity=False)
nonneg = st.floats(min_value=0.0, max_value=1e6, allow_nan=False, allow_infinity=False)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(nonneg, finite), min_size=0, max_size=25))
def test_finite_input_gives_finite_output_or_fit_error(pairs):
    x = np.array([p[0] for p in pairs], dtype=float)
    y = np.array([p[1] for p in pairs], dtype=float)
    try:
        fit = fit_power_law(x, y)
    except FitError:
        return
    values = [fit.k1, fit.k2, fit.phi, fit.se_k1, fit.se_k2, fit.cov_k1k2]
    assert all(np.isfinite(v) for v in values)
    assert fit.phi >= 0 and fit.se_k1 >= 0 and fit.se_k2 >= 0


def _press(c_D, c_A, c_P, index=3):
    n = len(c_P)
    return Press(index=index, t_onset=1.0, t_peak=2.0, t_release=3.0, h0=0.03, location=(0.01, 0.02),
                 depth=float(np.max(c_D)), t=np.linspace(1.0, 2.0, n), c_P=np.asarray(c_P, float),
                 c_A=np.asarray(c_A, float), c_D=np.asarray(c_D, float), xy=np.zeros((n, 2)))


def test_fit_press_uses_mm_and_mm2():
    assert FIT_UNITS == {"c_D": "mm", "c_A": "mm^2"}
    d_mm = np.linspace(0.0, 4.0, 15)
    a_mm2 = np.linspace(6.25, 100.0, 15)
    c_p = 75.0 * d_mm**1.5 + 12.0
    # Area law chosen independently so each fit must read its own abscissa in its own unit.
    c_p_area = 2.5 * a_mm2**1.5 - 30.0
    fit_n = fit_press(_press(d_mm * 1e-3, a_mm2 * 1e-6, c_p))
    assert fit_n.n1 == pytest.approx(75.0, rel=1e-9) and fit_n.n2 == pytest.approx(12.0, rel=1e-9)
    fit_a = fit_press(_press(d_mm * 1e-3, a_mm2 * 1e-6, c_p_area))
    assert fit_a.a1 == pytest.approx(2.5, rel=1e-9) and fit_a.a2 == pytest.approx(-30.0, rel=1e-9)
    assert fit_a.params == pytest.approx([fit_a.n1, fit_a.n2, 2.5, -30.0])
    assert fit_a.press_index == 3 and fit_a.location == (0.01, 0.02) and fit_a.n == 15


def test_fit_press_names_the_failing_law():
    d = np.linspace(0.0, 4e-3, 10)
    with pytest.raises(FitError, match="press 3 .*cutaneous.*constant"):
        fit_press(_press(d, np.full(10, 16 * 6.25e-6), 75.0 * (d * 1e3) ** 1.5))
