"""Hysteresis levels on c_P and the contacts they find.

The levels come from the stream's own noise where not given: the baseline is the 5th percentile of c_P, the
noise the robust spread of second differences. A contact starts when c_P rises above the on level and ends when it
falls to the off level or below, so noise around either level neither splits one press nor merges two.
"""

from __future__ import annotations

import math
from bisect import bisect_right
from dataclasses import dataclass

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.perception.smallstats import median_sorted, percentile_sorted

# Consistent scale factor of the median absolute deviation for a Gaussian.
_MAD_TO_SIGMA = 1.4826
_SQRT6 = math.sqrt(6)


@dataclass(frozen=True)
class Thresholds:
    """Hysteresis levels on c_P and the noise statistics they came from."""

    on: float
    off: float
    baseline: float
    noise: float


def estimate_thresholds(
    c_P: np.ndarray, on_threshold: float | None = None, off_threshold: float | None = None
) -> Thresholds:
    """Hysteresis levels from the data's own noise where not given.

    The baseline is the 5th percentile of c_P (contact-free samples are the low ones); the noise is the robust
    standard deviation of second differences (MAD / sqrt 6), which the smooth ramps of a press barely affect.
    Defaults are on = baseline + max(6 noise, f) and off = baseline + max(3 noise, f / 4), where f is a
    thousandth of the stream's range above baseline, so a perfectly clean stream still needs a real rise.

    Raises:
        ValidationError: non-finite thresholds or off >= on.
    """
    c = np.asarray(c_P, dtype=float)
    if len(c) == 0:
        raise ValidationError("cannot estimate thresholds from an empty contact series")
    cs = np.sort(c)  # NaN sorts last
    if not (math.isfinite(cs[0]) and math.isfinite(cs[-1])):
        raise ValidationError("cannot estimate thresholds: c_P holds NaN or inf")
    baseline = percentile_sorted(cs, 5)
    # Second differences cancel the steady ramps of pressing and releasing, which would inflate a spread of
    # first differences in a stream that is mostly contact; for white noise their variance is 6 sigma^2.
    noise = 0.0
    if len(c) > 2:
        d1 = c[1:] - c[:-1]
        d2 = np.sort(d1[1:] - d1[:-1])
        mad = np.abs(d2 - median_sorted(d2))
        mad.sort()
        noise = _MAD_TO_SIGMA * median_sorted(mad) / _SQRT6
    # A floor for perfectly clean data (noise 0): contact must still rise by a thousandth of the stream's range.
    floor = 1e-3 * (float(cs[-1]) - baseline) or 1.0
    on = baseline + max(6 * noise, floor) if on_threshold is None else float(on_threshold)
    if off_threshold is None:
        off = baseline + max(3 * noise, 0.25 * floor)
        if on_threshold is not None:
            off = min(off, 0.5 * (baseline + on))
    else:
        off = float(off_threshold)
    if not (np.isfinite(on) and np.isfinite(off)):
        raise ValidationError(f"on_threshold and off_threshold must be finite, got {on!r} and {off!r}")
    if off >= on:
        raise ValidationError(
            f"off_threshold ({off:g}) must be below on_threshold ({on:g}) for hysteresis (units of c_P)"
        )
    return Thresholds(on=on, off=off, baseline=baseline, noise=noise)


def contact_intervals(c_P: np.ndarray, on: float, off: float) -> list[tuple[int, int | None]]:
    """Contacts found by hysteresis, as (onset, release) sample indices.

    onset is the first sample above ``off`` of the run that crosses ``on`` (-1 when the stream starts inside the
    contact); release is the first sample at or below ``off`` after it (None if the stream ends first).
    """
    c = np.asarray(c_P, dtype=float)
    # Walk the crossings only: a contact starts at the first sample above on after a release and is released at
    # the first sample at or below off after that (off < on, so no sample is both).
    ons = np.flatnonzero(c > on).tolist()
    offs = np.flatnonzero(c <= off).tolist()
    out: list[tuple[int, int | None]] = []
    k = 0
    while k < len(ons):
        start = ons[k]
        j = bisect_right(offs, start)
        onset = offs[j - 1] + 1 if j else -1
        if j == len(offs):
            out.append((onset, None))
            break
        out.append((onset, offs[j]))
        k = bisect_right(ons, offs[j])
    return out
