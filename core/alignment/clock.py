"""The clock map between a pose tracker and a tactile pad, estimated from the presses both saw.

Two devices on two computers stamp samples with two clocks: an unknown offset (seconds or days apart) and a drift
(crystals differ by tens of ppm: 50 ppm is 18 ms an hour). :func:`estimate_clock_map` finds the map
``t_taxel = t_pose + offset + rate * (t_taxel - t_ref)`` in two steps:

1. coarse, needing no prior: each contact's c_P peak (taxel clock) against each reversal of the fingertip's motion
   (pose clock, :mod:`~palpate.core.alignment.events`). Every pairing proposes an offset; the one that pairs the
   most presses wins. When another offset, more than the match tolerance away, pairs nearly as many (presses at a
   steady rhythm look the same one period later), the fine step below settles it: at the right offset the
   per-press offsets agree to milliseconds, at one a press-period away each press is laid on its neighbour's motion
   and they scatter with the rhythm's irregularity. The one candidate whose per-press offsets agree (rms within
   ``TIE_RESIDUAL``) wins; when several or none do, the estimate is refused as ambiguous.
2. fine, per paired press: the pose-time shift that makes the press's c_P one function of its indentation on the
   way in and on the way out (a wrong shift moves the loading branch one way and the unloading branch the other);
   indentation along the press's own motion. The shift is the zero of the branches' mean separation, found on a
   1 ms grid and interpolated; presses whose shift disagrees with the others (robustly, by more than
   ``OUTLIER_SIGMAS`` spreads) are left out and counted.

The per-press offsets are then fitted with a line in time: its value at ``t_ref`` (the presses' mean time) is the
offset, its slope the rate difference (drift), both with standard errors from the scatter. The offset's
uncertainty also carries each device's timestamp resolution (:func:`stamp_resolution`: a Liberty stamps whole ms):
averaging presses does not remove it, because every stamp of a device is rounded or truncated the same way. With
fewer than ``MIN_PRESSES_FOR_DRIFT`` presses or a span under ``MIN_SPAN_FOR_DRIFT`` the drift is taken as 0 and said so.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from palpate.core.alignment.events import Contact, contacts, reversals
from palpate.core.errors import ValidationError
from palpate.core.perception.press_axis import motion_axis
from palpate.core.perception.streams import PoseSample, TaxelFrame, frames_to_arrays, poses_to_arrays

#: A c_P peak and a reversal this close (s) after shifting are the same press.
MATCH_TOLERANCE = 0.15
#: Another offset pairing at least this fraction of the best's presses is a rival, settled by the fine step.
AMBIGUOUS_FRACTION = 0.75
#: Rival offsets tried finely besides the best (the ones pairing the most presses).
MAX_RIVALS = 3
#: Per-press fine offsets agreeing within this rms (s) about one clock map single out a candidate offset: a few ms
#: at the right offset under tracker noise; tens of ms at one a press-period away, where each press's c_P is laid
#: on its neighbour's motion and the rhythm's irregularity scatters them.
TIE_RESIDUAL = 0.008
#: Fine search half-width around the coarse offset, s, and its grid step, s.
FINE_HALF_WIDTH = 0.15
FINE_STEP = 0.001
#: The branches' separation is fitted with a line over +-this around its zero crossing, s.
LINE_HALF_WIDTH = 0.01
#: c_P between these fractions of a press's range enters the fine fit (above noise, below saturation).
FINE_BAND = (0.1, 0.9)
OUTLIER_SIGMAS = 4.0
OUTLIER_FLOOR = 0.005  # s: shifts closer than this to the median are never outliers
MIN_PRESSES_FOR_DRIFT = 4
MIN_SPAN_FOR_DRIFT = 30.0  # s
#: Crystal oscillators agree to ~100 ppm; a fitted drift beyond this means the presses were paired wrongly.
MAX_DRIFT = 1e-3
#: Fine offsets scattering more than this (s, rms about the line) do not describe one clock map.
MAX_RESIDUAL = 0.02


@dataclass(frozen=True)
class ClockMap:
    """``t_taxel = t_pose + offset + rate * (t_taxel - t_ref)`` (s).

    Attributes:
        offset: added to a pose time at ``t_ref`` to get the taxel time, s.
        rate: drift, d(offset)/dt (dimensionless; -50e-6 when the pose clock runs 50 ppm fast).
        t_ref: taxel time at which ``offset`` holds, s.
        offset_std, rate_std: standard errors (None when given by the user, or not estimated).
        method: "given", "estimated" or "estimated, no drift" (too few presses or too short a span for a rate).
        presses: presses the estimate rests on (0 when given).
        outliers: paired presses left out of the fit.
        residual: rms of the per-press offsets about the fitted line, s.
        per_press: (taxel time s, offset s) of each press used, for reports.
        resolution: the two streams' timestamp resolutions' share of ``offset_std``, s (half a tick of each,
            in quadrature).
    """

    offset: float
    rate: float = 0.0
    t_ref: float = 0.0
    offset_std: float | None = None
    rate_std: float | None = None
    method: str = "given"
    presses: int = 0
    outliers: int = 0
    residual: float | None = None
    per_press: tuple[tuple[float, float], ...] = field(default_factory=tuple)
    resolution: float = 0.0

    def __post_init__(self) -> None:
        for name in ("offset", "rate", "t_ref"):
            if not np.isfinite(getattr(self, name)):
                raise ValidationError(f"clock map {name} must be finite, got {getattr(self, name)!r}")
        if not abs(self.rate) < 0.5:
            raise ValidationError(f"clock drift {self.rate!r} is not a drift (|rate| must be well below 1)")

    def to_taxel(self, t_pose) -> np.ndarray:
        """Pose times (s) on the taxel clock."""
        t = np.asarray(t_pose, dtype=float)
        return (t + self.offset - self.rate * self.t_ref) / (1.0 - self.rate)

    @property
    def drift_ppm(self) -> float:
        """How much faster the pose clock runs than the taxel clock, ppm (d t_pose / d t_taxel = 1 - rate)."""
        return -self.rate * 1e6

    def text(self) -> str:
        """One line for people (ms and ppm)."""
        if self.method == "given":
            return f"clock offset {self.offset:.4f} s, drift {self.drift_ppm:.1f} ppm (given)"
        ticks = f" incl. {1e3 * self.resolution:.1f} ms of timestamp resolution" if self.resolution else ""
        off = f"clock offset {self.offset:.4f} s +- {1e3 * (self.offset_std or 0):.1f} ms (1 sigma){ticks}"
        drift = (f"drift {self.drift_ppm:.1f} +- {1e6 * (self.rate_std or 0):.1f} ppm" if self.method == "estimated"
                 else "drift not estimated (taken as 0)")
        left = f", {self.outliers} left out" if self.outliers else ""
        return (f"{off} at taxel time {self.t_ref:.2f} s, {drift}; from {self.presses} presses{left}, "
                f"rms {1e3 * (self.residual or 0):.1f} ms")

    def to_dict(self) -> dict:
        """JSON-ready (a recording's metadata)."""
        return {"offset_s": self.offset, "rate": self.rate, "drift_ppm": self.drift_ppm, "t_ref_s": self.t_ref,
                "offset_std_s": self.offset_std, "rate_std": self.rate_std, "method": self.method,
                "presses": self.presses, "outliers": self.outliers, "residual_s": self.residual,
                "stamp_resolution_s": self.resolution}


def estimate_clock_map(frames: list[TaxelFrame], poses: list[PoseSample], *,
                       max_offset: float | None = None) -> ClockMap:
    """Estimate the clock map that puts ``poses`` on the taxel clock of ``frames`` (see the module docstring).

    Args:
        frames: taxel frames (one pad), taxel clock.
        poses: fingertip poses (one station), pose clock.
        max_offset: search offsets only within +-this, s (None: any; give it when presses come at a steady rhythm).

    Raises:
        ValidationError: no contact or no reversal; no offset pairs two presses; ambiguous; per-press offsets that
            do not agree on one map; an implausible drift; streams that do not overlap once mapped.
    """
    t, counts, _ = frames_to_arrays(frames)
    tp, pos, _ = poses_to_arrays(poses)
    return estimate_clock_map_arrays(t, counts.reshape(len(t), -1).sum(axis=1, dtype=np.int64).astype(float), tp,
                                     pos, max_offset=max_offset)


def estimate_clock_map_arrays(t: np.ndarray, c_p: np.ndarray, tp: np.ndarray, pos: np.ndarray, *,
                              max_offset: float | None = None) -> ClockMap:
    """:func:`estimate_clock_map` from arrays: frame times (s, taxel clock) and each frame's c_P (sum of counts),
    pose times (s, pose clock) and positions (n, 3) m; what a streamed import keeps of its frames."""
    if max_offset is not None and not (math.isfinite(max_offset) and max_offset > 0):
        raise ValidationError(f"clock estimate: max_offset must be a finite number of seconds > 0, got {max_offset!r}")
    t, c_p = np.asarray(t, dtype=float), np.asarray(c_p, dtype=float)
    found = contacts(t, c_p)
    if not found:
        raise ValidationError("clock estimate: the taxel stream shows no finished contact (no press to align on)")
    turns = reversals(tp, pos)
    if not turns:
        raise ValidationError("clock estimate: the fingertip never reverses its motion in the pose stream (no "
                              "press to align on)")
    # a stamp is off by up to half a tick (rounded) or half a tick on average (truncated), the same way at every press
    ticks = 0.5 * math.hypot(stamp_resolution(t), stamp_resolution(tp))
    candidates = _coarse(found, turns, max_offset)
    if len(candidates) == 1:
        return _with_resolution(_fine_map(t, c_p, tp, pos, *candidates[0][:2]), ticks)
    # rivals: the fine step settles which offset the presses agree on
    agreeing = []
    for offset, pairs, _ in candidates:
        try:
            cmap = _fine_map(t, c_p, tp, pos, offset, pairs)
        except ValidationError:
            continue
        if cmap.residual is not None and cmap.residual <= TIE_RESIDUAL:
            agreeing.append(cmap)
    if len(agreeing) == 1:
        return _with_resolution(agreeing[0], ticks)
    (best, _, n_best), (other, _, n_other) = candidates[0], candidates[1]
    why = ("the presses' fine offsets agree at both" if agreeing else "the presses' fine offsets agree at neither")
    raise ValidationError(
        f"clock estimate is ambiguous: an offset of {best:.3f} s pairs {n_best} presses and one of {other:.3f} s "
        f"pairs {n_other}, and {why} (presses at a steady rhythm look alike one period apart); give the offset "
        "(--clock-offset) or bound the search (--max-offset)")


def stamp_resolution(times, *, quantum: float = 1e-6) -> float:
    """The tick a stream's timestamps come in, s: the greatest common divisor of the steps between them (counted in
    ``quantum`` s), or 0 when that is the sampling period itself (stamps computed as start + k period have no tick
    finer than their period and no rounding to speak of).

    A Liberty at 240 Hz stamps whole ms: its steps of 4 and 5 ms give 1 ms. Stamps in floating point give
    ``quantum``.
    """
    t = np.asarray(times, dtype=float)
    steps = np.rint(np.diff(t) / quantum).astype(np.int64)
    steps = steps[steps > 0]
    if len(steps) == 0:
        return 0.0
    tick = int(np.gcd.reduce(steps))
    if tick >= int(np.median(steps)):
        return 0.0
    return tick * quantum


def _with_resolution(cmap: ClockMap, ticks: float) -> ClockMap:
    std = math.hypot(cmap.offset_std or 0.0, ticks)
    return replace(cmap, offset_std=std, resolution=ticks)


def _fine_map(t, c_p, tp, pos, coarse: float, pairs: list[Contact]) -> ClockMap:
    """The clock map fitted to the fine offsets of the paired presses around a coarse offset (s)."""
    fine = []
    for contact in pairs:
        shift = _fine_offset(t, c_p, tp, pos, contact, coarse)
        if shift is not None:
            fine.append((contact.t_peak, shift))
    if len(fine) < 2:
        raise ValidationError(f"clock estimate: only {len(fine)} press(es) could be aligned finely (of {len(pairs)} "
                              "paired); give the offset with --clock-offset")
    return _fit_line(np.array(fine), tp, t)


def _coarse(found: list[Contact], turns, max_offset: float | None) -> list[tuple[float, list[Contact], int]]:
    """Candidate offsets (s), each with the contacts it pairs and their number: the best first, then its rivals
    (offsets more than twice the match tolerance away pairing at least ``AMBIGUOUS_FRACTION`` as many)."""
    peaks = np.array([c.t_peak for c in found])
    revs = np.array([r.t for r in turns])
    cand = (peaks[:, None] - revs[None, :]).reshape(-1)
    if max_offset is not None:
        cand = cand[np.abs(cand) <= max_offset]
    if len(cand) == 0:
        raise ValidationError(f"clock estimate: no press reversal lies within +-{max_offset} s of a c_P peak")
    cand = np.unique(np.round(cand / 0.01) * 0.01)  # 10 ms bins: far finer than the match tolerance
    sorted_revs = np.sort(revs)

    def paired(offset: float) -> np.ndarray:
        # a c_P peak is paired when some reversal, shifted by offset, falls within the tolerance of it
        k = np.clip(np.searchsorted(sorted_revs + offset, peaks), 1, len(sorted_revs) - 1) if len(revs) > 1 else \
            np.zeros(len(peaks), dtype=int)
        near = np.minimum(np.abs(sorted_revs[k] + offset - peaks), np.abs(sorted_revs[k - 1] + offset - peaks)) \
            if len(revs) > 1 else np.abs(sorted_revs[0] + offset - peaks)
        return near <= MATCH_TOLERANCE

    score = np.array([paired(o).sum() for o in cand])
    best = int(np.argmax(score))
    n_best = int(score[best])
    if n_best < 2:
        raise ValidationError(f"clock estimate: no clock offset pairs two c_P peaks with reversals of the fingertip "
                              f"({len(peaks)} contacts, {len(revs)} reversals); the streams may not overlap or not "
                              "be of the same presses; give the offset with --clock-offset")
    chosen = [float(cand[best])]
    rivals = (np.abs(cand - chosen[0]) > 2 * MATCH_TOLERANCE) & (score >= max(2, AMBIGUOUS_FRACTION * n_best))
    for k in np.flatnonzero(rivals)[np.argsort(-score[rivals], kind="stable")]:
        if len(chosen) > MAX_RIVALS:
            break
        if all(abs(float(cand[k]) - c) > 2 * MATCH_TOLERANCE for c in chosen):
            chosen.append(float(cand[k]))
    out = []
    for offset in chosen:
        mask = paired(offset)
        out.append((offset, [c for c, m in zip(found, mask, strict=True) if m], int(mask.sum())))
    return out


def _fine_offset(t, c_p, tp, pos, contact: Contact, coarse: float) -> float | None:
    """The pose-time shift (s) that puts the loading and unloading branches of one press on each other, or None.

    For a shift, each loading frame's indentation is compared with the unloading branch's indentation at the same
    c_P (interpolated), and each unloading frame's with the loading branch's; the mean difference falls steadily
    as the shift grows (the loading branch moves up, the unloading branch down), and its zero is the shift where
    c_P is one function of indentation. No contact law is assumed, only that the material gives back what it took.
    """
    lo, hi = contact.onset, contact.release
    base = float(np.min(c_p[max(lo - 1, 0):hi + 1]))
    band = (c_p[lo:hi] - base) / max(contact.c_max - base, 1e-12)
    use = lo + np.flatnonzero((band >= FINE_BAND[0]) & (band <= FINE_BAND[1]))
    rising = use[use <= contact.peak]
    falling = use[use > contact.peak]
    if len(rising) < 3 or len(falling) < 3:
        return None  # both branches are needed
    # the press axis from the motion during the contact, on the coarse clock
    inside = (tp + coarse >= t[lo]) & (tp + coarse <= t[hi])
    if np.count_nonzero(inside) < 4:
        return None
    near_peak = int(np.argmin(np.abs(tp[inside] + coarse - t[contact.peak])))
    axis = motion_axis(pos[inside], near_peak)
    if axis is None:
        return None
    depth = _smoothed(tp, pos @ axis, t[1] - t[0])
    c_up, c_down = c_p[rising], c_p[falling]
    up_order, down_order = np.argsort(c_up, kind="stable"), np.argsort(c_down, kind="stable")

    def gap(shift: float) -> float:
        d_up = np.interp(t[rising] - shift, tp, depth)
        d_down = np.interp(t[falling] - shift, tp, depth)
        across_down = np.interp(c_up, c_down[down_order], d_down[down_order])
        across_up = np.interp(c_down, c_up[up_order], d_up[up_order])
        return 0.5 * (float(np.mean(d_up - across_down)) + float(np.mean(across_up - d_down)))

    span = (t[lo] - coarse - FINE_HALF_WIDTH, t[hi] - coarse + FINE_HALF_WIDTH)
    if span[0] < tp[0] or span[1] > tp[-1]:
        return None  # the poses do not cover the press and the search around it
    grid = coarse + np.arange(-FINE_HALF_WIDTH, FINE_HALF_WIDTH + 0.5 * FINE_STEP, FINE_STEP)
    g = np.array([gap(s) for s in grid])
    cross = np.flatnonzero((g[:-1] > 0) & (g[1:] <= 0))
    if len(cross) == 0:
        return None  # the branches never swap sides: the press does not pin the offset down
    # noise can make the separation wiggle through zero more than once: take the middle crossing and the line
    # through the separations within LINE_HALF_WIDTH of it
    k = int(cross[len(cross) // 2])
    near = np.abs(grid - grid[k]) <= LINE_HALF_WIDTH
    slope, intercept = np.polyfit(grid[near] - grid[k], g[near], 1)
    if not slope < 0:
        return None
    return float(grid[k] - intercept / slope)


def _smoothed(tp: np.ndarray, x: np.ndarray, window: float) -> np.ndarray:
    """``x`` averaged over a centred window of about ``window`` s (tracker noise averaged over a taxel period; a
    straight motion is unchanged)."""
    rate = (len(tp) - 1) / max(tp[-1] - tp[0], 1e-12)
    k = int(round(window * rate)) | 1
    if k < 3:
        return x
    kernel = np.ones(k) / k
    out = np.convolve(x, kernel, mode="same")
    half = k // 2
    out[:half], out[-half:] = x[:half], x[-half:]  # the ends keep the raw samples
    return out


def _fit_line(fine: np.ndarray, tp: np.ndarray, t: np.ndarray) -> ClockMap:
    times, shifts = fine[:, 0], fine[:, 1]
    med = float(np.median(shifts))
    spread = 1.4826 * float(np.median(np.abs(shifts - med)))
    # drift moves the offsets along the session; the outlier test is on the residual about a first line
    keep = np.ones(len(shifts), dtype=bool)
    for _ in range(2):
        a, b = _line(times[keep], shifts[keep])
        r = shifts - (a + b * (times - times[keep].mean()))
        spread = 1.4826 * float(np.median(np.abs(r[keep])))
        keep = np.abs(r) <= max(OUTLIER_SIGMAS * spread, OUTLIER_FLOOR)
        if keep.sum() < 2:
            keep = np.abs(shifts - med) <= max(OUTLIER_SIGMAS * spread, OUTLIER_FLOOR)
            break
    times_k, shifts_k = times[keep], shifts[keep]
    n = len(times_k)
    t_ref = float(times_k.mean())
    span = float(np.ptp(times_k))
    with_drift = n >= MIN_PRESSES_FOR_DRIFT and span >= MIN_SPAN_FOR_DRIFT
    if with_drift:
        offset, rate = _line(times_k, shifts_k)
        resid = shifts_k - (offset + rate * (times_k - t_ref))
        sigma = float(np.sqrt(np.sum(resid**2) / (n - 2)))
        offset_std = sigma / np.sqrt(n)
        rate_std = sigma / float(np.sqrt(np.sum((times_k - t_ref) ** 2)))
    else:
        offset, rate = float(shifts_k.mean()), 0.0
        resid = shifts_k - offset
        sigma = float(np.sqrt(np.sum(resid**2) / max(n - 1, 1)))
        offset_std, rate_std = sigma / np.sqrt(n), None
    rms = float(np.sqrt(np.mean(resid**2)))
    if rms > MAX_RESIDUAL:
        raise ValidationError(f"clock estimate: the {n} aligned presses disagree (rms {rms * 1e3:.0f} ms about one "
                              "clock map); the streams may not be of the same presses; give the offset")
    if abs(rate) > MAX_DRIFT:
        raise ValidationError(f"clock estimate: a drift of {-rate * 1e6:.0f} ppm between the clocks is not a clock "
                              "drift (crystals agree to ~100 ppm); the presses were paired wrongly; give the offset")
    cmap = ClockMap(offset=float(offset), rate=float(rate), t_ref=t_ref, offset_std=float(offset_std),
                    rate_std=None if rate_std is None else float(rate_std),
                    method="estimated" if with_drift else "estimated, no drift", presses=n,
                    outliers=int(np.count_nonzero(~keep)), residual=rms,
                    per_press=tuple((float(a), float(b)) for a, b in zip(times_k, shifts_k, strict=True)))
    check_overlap(cmap, tp, t)
    return cmap


def _line(x: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """(value at mean x, slope) of the least-squares line; slope 0 for one point or no spread in x."""
    xm = x.mean()
    sxx = float(np.sum((x - xm) ** 2))
    slope = float(np.sum((x - xm) * (y - y.mean())) / sxx) if sxx > 0 else 0.0
    return float(y.mean()), slope


def check_overlap(cmap: ClockMap, tp: np.ndarray, t: np.ndarray, *, min_fraction: float = 0.1) -> None:
    """ValidationError unless the mapped pose span covers at least ``min_fraction`` of the taxel span."""
    mapped = cmap.to_taxel(np.array([tp[0], tp[-1]]))
    lo, hi = max(mapped[0], t[0]), min(mapped[1], t[-1])
    span = max(t[-1] - t[0], 1e-9)
    if hi - lo < min_fraction * span:
        raise ValidationError(
            f"the pose stream ({mapped[0]:.2f} to {mapped[1]:.2f} s on the taxel clock) and the taxel stream "
            f"({t[0]:.2f} to {t[-1]:.2f} s) do not overlap enough ({max(hi - lo, 0):.2f} s in common); check the "
            "files, the clock offset and --start-time")
