"""The order statistics and line fit of one press give numpy's floats bit for bit (maps must not change by a bit)."""

from __future__ import annotations

import numpy as np
import pytest

from palpate.core.perception.smallstats import line_fit, median_sorted, percentile_sorted


def _samples(rng: np.random.Generator, n: int) -> np.ndarray:
    kind = rng.integers(4)
    if kind == 0:  # integer-valued, many ties (raw counts)
        return rng.integers(0, 6, n).astype(float)
    if kind == 1:  # wide range of magnitudes and signs
        return rng.normal(size=n) * 10.0 ** rng.uniform(-8, 8, n)
    if kind == 2:  # a press: flat baseline then a ramp
        return np.concatenate([np.zeros(n // 2), np.linspace(0, 400, n - n // 2) ** 1.5])
    return rng.uniform(-1, 1, n)


@pytest.mark.parametrize("seed", range(5))
def test_percentile_and_median_equal_numpy_bit_for_bit(seed):
    rng = np.random.default_rng(seed)
    for n in list(range(1, 12)) + [40, 41, 120, 1001]:
        x = _samples(rng, n)
        xs = np.sort(x)
        for q in (0, 5, 25, 50, 95, 100, 33.3):
            assert percentile_sorted(xs, q) == np.percentile(x, q), (n, q)
        assert median_sorted(xs) == np.median(x), n


@pytest.mark.parametrize("seed", range(5))
def test_line_fit_equals_polyfit_bit_for_bit(seed):
    rng = np.random.default_rng(100 + seed)
    for n in (2, 3, 4, 7, 20, 60):
        x = 0.03 - np.sort(rng.uniform(0, 0.004, n))  # heights of a finger moving down, m
        y = np.clip(rng.normal(size=n) + np.linspace(0, 30, n), 0, None)
        slope, intercept = np.polyfit(x, y, 1)
        assert line_fit(x, y) == (slope, intercept)
        x[0] = -0.0  # polyfit turns -0.0 into 0.0; so must the copy
        assert line_fit(x, y) == tuple(np.polyfit(x, y, 1))
