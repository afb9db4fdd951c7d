"""Order statistics and the straight-line fit on the short arrays of one press, giving numpy's floats exactly.

``np.percentile``, ``np.median`` and ``np.polyfit`` cost tens of microseconds per call in argument handling alone,
more than the arithmetic on a press's few dozen samples. These give the same floats (the same interpolation and
the same least-squares solve) from a sorted array or with one LAPACK call, so segmentation costs what its
arithmetic costs and the maps do not change by a bit.
"""

from __future__ import annotations

import math

import numpy as np

_EPS = float(np.finfo(float).eps)


def percentile_sorted(xs: np.ndarray, q: float) -> float:
    """``np.percentile(x, q)`` (its default 'linear' method) of ``xs = np.sort(x)``, finite and non-empty.

    The interpolation is numpy's: from the lower neighbour when the fraction is below one half, from the upper one
    otherwise.
    """
    n = len(xs)
    vi = (n - 1) * (q / 100)
    lo = math.floor(vi)
    hi = min(lo + 1, n - 1)
    g = vi - lo
    a, b = float(xs[lo]), float(xs[hi])
    diff = b - a
    return b - diff * (1 - g) if g >= 0.5 else a + diff * g


def median_sorted(xs: np.ndarray) -> float:
    """``np.median`` of ``xs`` (sorted, finite, non-empty): the middle value, or the mean of the middle two."""
    n = len(xs)
    h = n // 2
    return float(xs[h]) if n % 2 else (float(xs[h - 1]) + float(xs[h])) / 2.0


def line_fit(x: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """(slope, intercept) of the least-squares line through (x, y): ``np.polyfit(x, y, 1)``'s arithmetic (columns
    scaled to unit norm, one LAPACK least-squares solve with polyfit's rcond), without its overhead.

    Args:
        x, y: 1-D float arrays of the same length >= 2, x not constant.
    """
    lhs = np.empty((len(x), 2))
    np.add(x, 0.0, out=lhs[:, 0])  # polyfit adds 0.0 too, which turns -0.0 into 0.0
    lhs[:, 1] = 1.0
    scale = np.sqrt((lhs * lhs).sum(axis=0))
    lhs /= scale
    coef = np.linalg.lstsq(lhs, y + 0.0, len(x) * _EPS)[0] / scale
    return float(coef[0]), float(coef[1])
