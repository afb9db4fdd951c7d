"""Streaming segmentation: contact-series chunks in as they arrive, presses out as they complete (the same presses
:func:`~palpate.core.perception.segment.segment_presses` finds on the whole stream)."""

from __future__ import annotations

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.perception.features import ContactSeries
from palpate.core.perception.segment import (
    Press,
    RejectedPress,
    Thresholds,
    check_limits,
    check_series,
    estimate_thresholds,
    segment_series,
)


class PressSegmenter:
    """Streaming segmentation: feed contact-series chunks as they arrive, get presses as they complete.

    Thresholds are fixed for the whole stream: the given ones, or those estimated from the first ``warmup``
    samples (which should include contact-free time), or a whole :class:`Thresholds` (e.g.
    ``segment_presses(calibration_series).thresholds``). Rejected contacts accumulate in :attr:`rejected`. With
    fixed thresholds the presses equal those of :func:`segment_presses` on the whole stream, as long as the
    contact-free time between two presses stays under ``max_buffer`` samples (beyond that the buffer is cut at
    the last contact-free sample, which can only lower the bound on the next first-contact height).
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
        max_buffer: int = 100_000,
        thresholds: Thresholds | None = None,
    ) -> None:
        check_limits(min_duration, min_depth, min_samples)
        self._given = (on_threshold, off_threshold)
        self._limits = dict(min_duration=min_duration, min_depth=min_depth, min_samples=int(min_samples))
        self._warmup = int(warmup)
        self._max_buffer = int(max_buffer)
        self.thresholds: Thresholds | None = thresholds
        self.rejected: list[RejectedPress] = []
        self._buffer: ContactSeries | None = None
        self._next_index = 0

    def feed(self, chunk: ContactSeries) -> list[Press]:
        """Append a chunk (times after the previous chunk's) and return the presses completed so far."""
        check_series(chunk)
        buf = chunk if self._buffer is None else _concat(self._buffer, chunk)
        self._buffer = buf
        if self.thresholds is None:
            if None in self._given and len(buf) < self._warmup:
                return []
            self.thresholds = estimate_thresholds(buf.c_P, *self._given)
        return self._run(final=False)

    def finish(self) -> list[Press]:
        """End of stream: return the last completed presses; a contact still open is rejected as partial."""
        if self._buffer is None or len(self._buffer) == 0:
            return []
        if self.thresholds is None:
            self.thresholds = estimate_thresholds(self._buffer.c_P, *self._given)
        out = self._run(final=True)
        self._buffer = None
        return out

    def _run(self, final: bool) -> list[Press]:
        buf = self._buffer
        presses, rejected, resume = segment_series(buf, self.thresholds, final=final, first_index=self._next_index,
                                             **self._limits)
        self.rejected.extend(rejected)
        self._next_index += len(presses) + len(rejected)
        if len(buf) - resume > self._max_buffer:
            free = np.flatnonzero(buf.c_P[resume:] <= self.thresholds.off)
            resume += int(free[-1]) if len(free) else 0
        self._buffer = buf.slice(resume, len(buf))
        return presses


def _concat(a: ContactSeries, b: ContactSeries) -> ContactSeries:
    if len(a) and len(b) and b.t[0] <= a.t[-1]:
        raise ValidationError(f"chunk starts at t={b.t[0]} s, not after the previous chunk's end t={a.t[-1]} s")
    return ContactSeries(
        t=np.concatenate([a.t, b.t]),
        c_P=np.concatenate([a.c_P, b.c_P]),
        c_A=np.concatenate([a.c_A, b.c_A]),
        height=np.concatenate([a.height, b.height]),
        xy=np.concatenate([a.xy, b.xy]),
        valid=np.concatenate([a.valid, b.valid]),
        calibrated=a.calibrated,
        z=np.concatenate([a.z, b.z]),
    )
