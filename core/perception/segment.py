"""Cut a contact series into presses, keeping only each press phase (first contact to deepest point).

Contact is detected on c_P with hysteresis: it starts when c_P rises above ``on_threshold`` and ends when it falls
to ``off_threshold`` or below, so noise around either level neither splits one press in two nor merges two
presses separated by a pause. The onset is then moved back to the first sample above ``off_threshold``, and the
height at first contact h0 is found between the last sample without contact and the first one with it by
extrapolating the 3/2-power law: (c_P - baseline)^(2/3) is linear in height near the onset (eq. 6.6), so its root
is the contact height. Indentation c_D = h0 - height (eq. 6.4), clipped at 0 because it is non-negative by
definition and pose noise near the onset would otherwise make it slightly negative.

Every detected contact ends up either as a :class:`Press` or as a :class:`RejectedPress` with a reason (partial,
too short, too shallow, too few samples, invalid pose): nothing is dropped silently.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.perception.features import ContactSeries
from palpate.core.perception.smallstats import line_fit
from palpate.core.perception.thresholds import Thresholds, contact_intervals, estimate_thresholds

# Fewest samples for the line that locates the first contact (two define it, more average the noise).
_ONSET_FIT_MIN = 4


@dataclass(frozen=True)
class Press:
    """The press phase of one press-and-release: samples from first contact to the deepest point.

    Attributes:
        index: position of this contact among all contacts detected in the stream (accepted or rejected).
        t_onset: time of first contact, s (interpolated between frames).
        t_peak: time of the deepest point, s (the first of the deepest pose and the c_P maximum).
        t_release: time contact ended, s (first frame at or below the off threshold).
        h0: height at first contact along -press_axis, m.
        location: mean fingertip (x, y) over the press phase, m.
        depth: largest indentation c_D, m.
        t: times of the press-phase samples, s.
        c_P: contact intensity (counts, or N if calibrated).
        c_A: contact area, m^2.
        c_D: indentation relative to h0, m, >= 0.
        xy: fingertip (x, y), m, shape (k, 2).
        calibrated: True when c_P is in N.
    """

    index: int
    t_onset: float
    t_peak: float
    t_release: float
    h0: float
    location: tuple[float, float]
    depth: float
    t: np.ndarray
    c_P: np.ndarray
    c_A: np.ndarray
    c_D: np.ndarray
    xy: np.ndarray
    calibrated: bool = False

    @property
    def n_samples(self) -> int:
        """Number of press-phase samples."""
        return len(self.t)


@dataclass(frozen=True)
class RejectedPress:
    """A detected contact that did not become a press, and why.

    Attributes:
        t_onset: first sample of the contact, s.
        t_end: last sample looked at (release, or end of stream), s.
        reason: what disqualified it, with the measured value and the limit.
        index: position among all contacts detected in the stream.
    """

    t_onset: float
    t_end: float
    reason: str
    index: int = -1


@dataclass
class Segmentation:
    """Result of :func:`segment_presses`.

    Attributes:
        presses: accepted presses in time order.
        rejected: every other detected contact, with its reason.
        on_threshold, off_threshold: the hysteresis levels used (units of c_P).
        baseline: c_P level without contact.
        noise: estimated standard deviation of c_P noise.
    """

    presses: list[Press] = field(default_factory=list)
    rejected: list[RejectedPress] = field(default_factory=list)
    on_threshold: float = float("nan")
    off_threshold: float = float("nan")
    baseline: float = 0.0
    noise: float = 0.0

    @property
    def thresholds(self) -> Thresholds:
        """The levels used, to reuse on another stream (e.g. by :class:`PressSegmenter`)."""
        return Thresholds(self.on_threshold, self.off_threshold, self.baseline, self.noise)


def check_series(series: ContactSeries) -> None:
    """ValidationError unless every array of the series is finite and its times increase strictly."""
    names = ("t", "c_P", "c_A", "height", "xy")
    arrays = [np.asarray(getattr(series, name), dtype=float) for name in names]
    # NaN and inf survive a sum, so one sum per array checks it; the culprit is looked for only on failure (or on
    # an overflow of finite values, which then passes).
    if not math.isfinite(sum(float(a.sum()) for a in arrays)):
        for name, arr in zip(names, arrays, strict=True):
            if not np.all(np.isfinite(arr)):
                raise ValidationError(f"ContactSeries.{name} holds NaN or inf; expected finite values")
    t = arrays[0]
    if len(t) > 1 and not (t[1:] > t[:-1]).all():
        raise ValidationError("ContactSeries.t must increase strictly")


def check_limits(min_duration: float, min_depth: float, min_samples: int) -> None:
    if not (np.isfinite(min_duration) and min_duration >= 0):
        raise ValidationError(f"min_duration must be >= 0 s, got {min_duration!r}")
    if not (np.isfinite(min_depth) and min_depth >= 0):
        raise ValidationError(f"min_depth must be >= 0 m, got {min_depth!r}")
    if int(min_samples) != min_samples or min_samples < 3:
        raise ValidationError(f"min_samples must be an integer >= 3 (a fit needs 3 samples), got {min_samples!r}")


def segment_presses(
    series: ContactSeries,
    *,
    on_threshold: float | None = None,
    off_threshold: float | None = None,
    min_duration: float = 0.1,
    min_depth: float = 0.0005,
    min_samples: int = 5,
    series_checked: bool = False,
) -> Segmentation:
    """Find the presses in a contact series.

    Args:
        series: contact features (see :func:`palpate.core.perception.features.contact_features`).
        on_threshold: c_P level that starts a contact; derived from the data's noise when None.
        off_threshold: c_P level at or below which a contact ends; derived from the noise when None.
        min_duration: shortest contact (onset to release) accepted, s.
        min_depth: shallowest press accepted (largest c_D), m.
        min_samples: fewest press-phase samples accepted (>= 3, what a fit needs).
        series_checked: True when the series is known to be finite with strictly increasing times, as
            :func:`~palpate.core.perception.features.contact_features` makes it from a synchronised stream; it is
            then not checked again.

    Returns:
        A :class:`Segmentation`: accepted presses and rejected contacts with reasons ("partial: stream ends before
        release", "partial: stream starts in contact", "too short", "too shallow", "too few samples",
        "invalid pose").

    Raises:
        ValidationError: non-finite series, bad thresholds or limits.
    """
    if not series_checked:
        check_series(series)
    check_limits(min_duration, min_depth, min_samples)
    th = estimate_thresholds(series.c_P, on_threshold, off_threshold)
    presses, rejected, _ = segment_series(
        series, th, min_duration=min_duration, min_depth=min_depth, min_samples=int(min_samples),
        final=True, first_index=0,
    )
    return Segmentation(presses, rejected, th.on, th.off, th.baseline, th.noise)


def segment_series(
    series: ContactSeries,
    th: Thresholds,
    *,
    min_duration: float,
    min_depth: float,
    min_samples: int,
    final: bool,
    first_index: int,
) -> tuple[list[Press], list[RejectedPress], int]:
    """Presses and rejections of a series; also the index from which the next chunk of a stream should resume.

    With ``final`` False a contact still open at the end is not reported. The resume index is the release of the
    last finished contact (0 if none), so the approach to the next contact, which bounds its first-contact
    height, is kept.
    """
    t = series.t
    n = len(t)
    limits = PressLimits(min_duration, min_depth, min_samples)
    presses: list[Press] = []
    rejected: list[RejectedPress] = []
    index = first_index
    i_top = 0  # start of the approach to the next contact: the previous release
    for onset, release in contact_intervals(series.c_P, th.on, th.off):
        if release is None and not final:
            break
        i0 = max(onset, 0)
        end = n - 1 if release is None else release
        if onset < 0:
            outcome = RejectedPress(float(t[0]), float(t[end]), STARTS_IN_CONTACT, index)
        elif release is None:
            outcome = RejectedPress(float(t[i0]), float(t[end]), ENDS_IN_CONTACT, index)
        else:
            w = slice(i0 - 1, release + 1)
            outcome = build_press(series.t[w], series.c_P[w], series.c_A[w], series.height[w], series.xy[w],
                                  series.valid[w], _ApproachSlice(series, i_top, i0), th, limits, index,
                                  series.calibrated)
        (presses if isinstance(outcome, Press) else rejected).append(outcome)
        index += 1
        i_top = end
    return presses, rejected, i_top


STARTS_IN_CONTACT = "partial: stream starts in contact, first contact not observed"
ENDS_IN_CONTACT = "partial: stream ends before release"


@dataclass(frozen=True)
class PressLimits:
    """What a contact must reach to become a press: duration s, depth m, press-phase samples."""

    min_duration: float
    min_depth: float
    min_samples: int


@dataclass(frozen=True)
class Crossing:
    """The last approach sample at or above a height, and the sample after it (times s, heights m)."""

    t: float
    h: float
    t_next: float
    h_next: float


class _ApproachSlice:
    """The approach to a contact in a whole series: samples i_top (the previous release) to i0 - 1."""

    def __init__(self, series: ContactSeries, i_top: int, i0: int):
        self.t, self.h, self.valid, self.sl = series.t, series.height, series.valid, slice(i_top, i0)

    def highest_valid(self, floor: float) -> float:
        """Highest height of a valid approach sample, and ``floor`` (m)."""
        return float(np.max(self.h[self.sl][self.valid[self.sl]], initial=floor))

    def last_at_or_above(self, height: float) -> Crossing | None:
        """The last approach sample at or above ``height`` (None if there is none)."""
        above = np.flatnonzero(self.h[self.sl] >= height)
        if not len(above):
            return None
        j = self.sl.start + int(above[-1])
        return Crossing(float(self.t[j]), float(self.h[j]), float(self.t[j + 1]), float(self.h[j + 1]))


def build_press(t, c_p, c_a, h, xy, valid, approach, th: Thresholds, limits: PressLimits, index: int,
                calibrated: bool) -> Press | RejectedPress:
    """The press of one released contact, or why it is rejected.

    Args:
        t, c_p, c_a, h, xy, valid: the contact's samples (time s, intensity, area m^2, height m, (x, y) m, pose
            usable), from the last sample before the onset to the release, both included.
        approach: the samples before the contact back to the previous release (``highest_valid`` and
            ``last_at_or_above``, as :class:`_ApproachSlice` answers them for a whole series).
        th, limits: the hysteresis levels and what a press must reach.
        index: the contact's position in the stream; calibrated: c_P in N.
    """
    t_start, t_end = float(t[1]), float(t[-1])
    if not valid.all():
        bad = int(np.count_nonzero(~valid))
        return RejectedPress(t_start, t_end,
                             f"invalid pose: {bad} of {len(valid)} samples in a pose gap or outside the pose span",
                             index)
    duration = t_end - t_start
    if duration < limits.min_duration:
        return RejectedPress(t_start, t_end, f"too short: {duration:.3f} s < min_duration "
                             f"{limits.min_duration:g} s", index)
    # The deepest point by the pose and the intensity maximum coincide on good data; when a clock-offset error
    # or a slow pose rate separates them, the samples in between contradict each other (one stream says
    # pressing, the other releasing), so the press phase stops at the first of the two.
    peak = 1 + min(int(h[1:-1].argmin()), int(c_p[1:-1].argmax()))
    sl = slice(1, peak + 1)
    h0, t_onset = _first_contact(t, c_p[sl] - th.baseline, h, approach, th.on - th.baseline)
    indent = h0 - h[sl]
    depth = float(indent.max())
    if depth < limits.min_depth:
        return RejectedPress(t_start, t_end, f"too shallow: depth {depth * 1e3:.3f} mm < min_depth "
                             f"{limits.min_depth * 1e3:g} mm", index)
    k = peak
    if k < limits.min_samples:
        return RejectedPress(t_start, t_end, f"too few samples: {k} press-phase samples < min_samples "
                             f"{limits.min_samples}", index)
    xy = np.asarray(xy[sl], dtype=float)
    return Press(
        index=index,
        t_onset=t_onset,
        t_peak=float(t[peak]),
        t_release=t_end,
        h0=h0,
        location=(float(xy[:, 0].sum()) / k, float(xy[:, 1].sum()) / k),  # np.mean's arithmetic
        depth=depth,
        t=np.asarray(t[sl], dtype=float),
        c_P=np.asarray(c_p[sl], dtype=float),
        c_A=np.asarray(c_a[sl], dtype=float),
        c_D=np.maximum(indent, 0.0, out=indent),
        xy=xy,
        calibrated=calibrated,
    )


def _first_contact(t: np.ndarray, ex: np.ndarray, h: np.ndarray, approach, detect: float) -> tuple[float, float]:
    """Height (m) and time (s) of first contact; ``t``, ``h`` from the last sample before the onset on, ``ex`` c_P
    above the baseline over the press phase (onset to peak).

    Under eq. 6.6, (c_P - baseline)^(2/3) is linear in height with its root at h0. The line is fitted to the early
    press phase, from the on level (reliably above noise) to half the peak, where sensels hidden by noise
    thresholds matter least and the finger still moves steadily; it falls back to the first samples after the
    onset. h0 is clamped between the first contact sample and the highest point of the approach (samples i_top to
    i0), and defaults to the middle of the last free / first contact bracket if no line can be fitted.
    """
    h_free, h_lo = float(h[0]), float(h[1])
    h_hi = approach.highest_valid(h_free)
    if h_hi <= h_lo:  # not moving into the object at the onset: the last free height is the best we know
        return h_free, float(t[0])
    window = np.flatnonzero((ex >= detect) & (ex <= 0.5 * ex.max()))
    if len(window) < _ONSET_FIT_MIN:
        window = np.arange(min(_ONSET_FIT_MIN, len(ex)))
    x = h[1:1 + len(ex)][window]
    h0 = 0.5 * (h_free + h_lo) if h_free > h_lo else h_lo
    if len(window) >= 2 and x.max() > x.min():
        slope, intercept = line_fit(x, np.maximum(ex[window], 0.0) ** (2.0 / 3.0))
        if slope < 0:
            h0 = min(max(-intercept / slope, h_lo), h_hi)
    # Time of first contact: where the approach last crossed h0 going down.
    c = approach.last_at_or_above(h0)
    if c is None:
        c = Crossing(float(t[0]), h_free, float(t[1]), h_lo)
    frac = 0.0 if c.h == c.h_next else min(max((c.h - h0) / (c.h - c.h_next), 0.0), 1.0)
    return h0, float(c.t + frac * (c.t_next - c.t))
