"""Streaming segmentation: contact samples in one at a time (or in chunks), presses out as they are released,
at a cost per sample that does not grow with the stream.

The presses are those :func:`~palpate.core.perception.segment.segment_presses` finds on the whole stream with the
same thresholds, to the bit: the same hysteresis, decided sample by sample, and the same press building
(:func:`~palpate.core.perception.segment.build_press`) on the contact's samples. What a press needs from the samples
before it (its approach, back to the previous release) is kept as a summary instead of the samples: the highest
valid height, and the approach's running "last sample at or above" heights (a stack of suffix maxima, short on any
real approach), so nothing is buffered between presses.
"""

from __future__ import annotations

from bisect import bisect_right

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.perception.features import ContactSeries
from palpate.core.perception.segment import (
    ENDS_IN_CONTACT,
    STARTS_IN_CONTACT,
    Crossing,
    Press,
    PressLimits,
    RejectedPress,
    build_press,
    check_limits,
    check_series,
)
from palpate.core.perception.thresholds import Thresholds, estimate_thresholds


class _Approach:
    """The samples since the previous release, summarised for :func:`build_press` (see the module docstring)."""

    def __init__(self) -> None:
        self.h_valid_max: float | None = None
        self.neg_h: list[float] = []  # -height of each stack entry, increasing (heights strictly decreasing)
        self.entries: list[list[float]] = []  # [t, h, t_next, h_next] of each suffix maximum

    def push(self, t: float, h: float, valid: bool) -> None:
        if valid:
            self.h_valid_max = h if self.h_valid_max is None else max(self.h_valid_max, h)
        entries = self.entries
        if entries:
            entries[-1][2], entries[-1][3] = t, h  # the newest entry is the sample just before this one
        while entries and entries[-1][1] <= h:  # a later sample as high hides it for every query
            entries.pop()
            self.neg_h.pop()
        entries.append([t, h, t, h])
        self.neg_h.append(-h)

    def close(self, t_next: float, h_next: float) -> None:
        """The contact starts: the sample after the approach's last one."""
        self.entries[-1][2], self.entries[-1][3] = t_next, h_next

    def highest_valid(self, floor: float) -> float:
        return floor if self.h_valid_max is None else max(self.h_valid_max, floor)

    def last_at_or_above(self, height: float) -> Crossing | None:
        k = bisect_right(self.neg_h, -height)  # entries[:k] are the ones at or above height
        if not k:
            return None
        t, h, t_next, h_next = self.entries[k - 1]
        return Crossing(t, h, t_next, h_next)


class StreamSegmenter:
    """Contact samples in, presses out as they are released; fixed hysteresis levels.

    Args:
        thresholds: the levels (e.g. ``segment_presses(calibration_series).thresholds``).
        min_duration, min_depth, min_samples: as :func:`~palpate.core.perception.segment.segment_presses`.
        calibrated: c_P is in N (copied into the presses).

    Rejected contacts accumulate in :attr:`rejected`.
    """

    def __init__(self, thresholds: Thresholds, *, min_duration: float = 0.1, min_depth: float = 0.0005,
                 min_samples: int = 5, calibrated: bool = False):
        check_limits(min_duration, min_depth, min_samples)
        self.thresholds = thresholds
        self.limits = PressLimits(min_duration, min_depth, int(min_samples))
        self.calibrated = calibrated
        self.rejected: list[RejectedPress] = []
        self._on, self._off = thresholds.on, thresholds.off
        self._index = 0
        self._t_first: float | None = None
        self._t_last: float | None = None
        self._approach = _Approach()
        self._last_free: tuple | None = None  # the newest sample at or below the off level
        self._pending: list[tuple] = []  # samples above off since then, not (yet) in a contact
        self._contact: list[tuple] | None = None  # from the sample before the onset on, while in contact
        self._partial = False  # the stream started inside the contact

    def push(self, t: float, c_p: float, c_a: float, h: float, x: float, y: float, valid: bool) -> Press | None:
        """One sample (time s after the previous one, c_P, c_A m^2, height m, x, y m, pose usable); returns the
        press it releases, if any (a rejected contact goes to :attr:`rejected`)."""
        sample = (t, c_p, c_a, h, x, y, valid)
        if self._t_first is None:
            self._t_first = t
        self._t_last = t
        if self._contact is not None:
            self._contact.append(sample)
            return self._release(sample) if c_p <= self._off else None
        if c_p > self._on:  # a contact starts; its onset is the first sample above off
            if self._last_free is None:
                self._partial, self._contact = True, []
            else:
                first = (self._pending or [sample])[0]
                self._approach.close(first[0], first[3])
                self._contact = [self._last_free, *self._pending, sample]
            self._pending = []
        elif c_p <= self._off:
            for s in self._pending:
                self._approach.push(s[0], s[3], s[6])
            self._pending = []
            self._approach.push(t, h, valid)
            self._last_free = sample
        else:
            self._pending.append(sample)
        return None

    def _release(self, sample: tuple) -> Press | None:
        contact, approach = self._contact, self._approach
        self._contact, self._approach, self._last_free = None, _Approach(), sample
        self._approach.push(sample[0], sample[3], sample[6])  # the next approach starts at this release
        index = self._index
        self._index += 1
        if self._partial:
            self._partial = False
            self.rejected.append(RejectedPress(self._t_first, sample[0], STARTS_IN_CONTACT, index))
            return None
        t, c_p, c_a, h, x, y, valid = (np.array(col) for col in zip(*contact, strict=True))
        out = build_press(t, c_p, c_a, h, np.column_stack([x, y]), valid, approach, self.thresholds, self.limits,
                          index, self.calibrated)
        if isinstance(out, RejectedPress):
            self.rejected.append(out)
            return None
        return out

    def finish(self) -> None:
        """End of stream: a contact still open is rejected as partial."""
        if self._contact is not None:
            t0 = self._t_first if self._partial else self._contact[1][0]
            self.rejected.append(RejectedPress(t0, self._t_last, STARTS_IN_CONTACT if self._partial
                                               else ENDS_IN_CONTACT, self._index))
            self._index += 1
            self._contact, self._partial = None, False


class PressSegmenter:
    """Streaming segmentation of contact-series chunks: feed them as they arrive, get presses as they complete.

    Thresholds are fixed for the whole stream: the given ones, or those estimated from the first ``warmup``
    samples (which should include contact-free time), or a whole :class:`Thresholds` (e.g.
    ``segment_presses(calibration_series).thresholds``). Rejected contacts accumulate in :attr:`rejected`. With
    fixed thresholds the presses equal those of :func:`segment_presses` on the whole stream; each sample costs
    the same however long the stream (see :class:`StreamSegmenter`).
    """

    def __init__(
        self,
        *,
        on_threshold: float | None = None,
        off_threshold: float | None = None,
        min_duration: float = 0.1,
        min_depth: float = 0.0005,
        min_samples: int = 5,
        warmup: int = 50,
        thresholds: Thresholds | None = None,
    ) -> None:
        check_limits(min_duration, min_depth, min_samples)
        self._given = (on_threshold, off_threshold)
        self._limits = dict(min_duration=min_duration, min_depth=min_depth, min_samples=int(min_samples))
        self._warmup = int(warmup)
        self.thresholds: Thresholds | None = thresholds
        self._engine: StreamSegmenter | None = None
        self._held: list[ContactSeries] = []  # chunks before the thresholds are known
        self._t_end: float | None = None
        self._rejected: list[RejectedPress] = []

    @property
    def rejected(self) -> list[RejectedPress]:
        """Every contact rejected so far, with its reason."""
        return self._rejected if self._engine is None else self._engine.rejected

    def feed(self, chunk: ContactSeries) -> list[Press]:
        """Append a chunk (times after the previous chunk's) and return the presses completed by it."""
        check_series(chunk)
        if len(chunk) and self._t_end is not None and chunk.t[0] <= self._t_end:
            raise ValidationError(f"chunk starts at t={chunk.t[0]} s, not after the previous chunk's end "
                                  f"t={self._t_end} s")
        if len(chunk):
            self._t_end = float(chunk.t[-1])
        if self._engine is None:
            self._held.append(chunk)
            if self.thresholds is None:
                held = sum(len(c) for c in self._held)
                if None in self._given and held < self._warmup:
                    return []
                self.thresholds = estimate_thresholds(np.concatenate([c.c_P for c in self._held]), *self._given)
            self._start(chunk.calibrated)
            chunks, self._held = self._held, []
            return [p for c in chunks for p in self._push(c)]
        return self._push(chunk)

    def finish(self) -> list[Press]:
        """End of stream: return the last completed presses; a contact still open is rejected as partial."""
        out: list[Press] = []
        if self._engine is None and self._held:
            if self.thresholds is None:
                self.thresholds = estimate_thresholds(np.concatenate([c.c_P for c in self._held]), *self._given)
            self._start(self._held[0].calibrated)
            chunks, self._held = self._held, []
            out = [p for c in chunks for p in self._push(c)]
        if self._engine is not None:
            self._engine.finish()
        return out

    def _start(self, calibrated: bool) -> None:
        self._engine = StreamSegmenter(self.thresholds, calibrated=calibrated, **self._limits)
        self._engine.rejected = self._rejected

    def _push(self, chunk: ContactSeries) -> list[Press]:
        push = self._engine.push
        rows = zip(chunk.t.tolist(), chunk.c_P.tolist(), chunk.c_A.tolist(), chunk.height.tolist(),
                   chunk.xy[:, 0].tolist(), chunk.xy[:, 1].tolist(), chunk.valid.tolist(), strict=True)
        return [p for p in (push(*row) for row in rows) if p is not None]
