"""The signal path from raw streams to interaction parameters: sync -> features -> segmentation -> fits.

:func:`presses_from_recording` turns one :class:`~palpate.core.perception.streams.PressRecording` into presses (and the
contacts it rejected, with reasons); :func:`fit_presses` fits the interaction laws to each press, skipping and
reporting those that cannot be fitted. Every knob lives in one frozen :class:`PipelineConfig`.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.perception.features import Calibration, ContactSeries, contact_features, press_axis_unit
from palpate.core.perception.fit import FitFailure, PressFit, fit_presses_reporting
from palpate.core.perception.press_axis import heights_along_motion
from palpate.core.perception.segment import Press, Segmentation, estimate_thresholds, segment_presses
from palpate.core.perception.streams import PressRecording
from palpate.core.perception.sync import SyncedStream, synchronise

log = logging.getLogger(__name__)


#: What a press fit uses: both interaction laws, or the kinesthetic one alone (c_P from a force).
FEATURES = ("both", "kinesthetic")


@dataclass(frozen=True)
class PipelineConfig:
    """Knobs of the signal path (SI units).

    Attributes:
        clock_offset: added to pose timestamps to bring them onto the taxel clock, s.
        max_gap: longest pose dropout interpolated across, s.
        noise_threshold: a sensel is active when its count exceeds this.
        calibration: None (c_P in counts), N per count, or a callable counts -> N per sensel.
        press_axis: pressing direction in the world frame.
        press_axis_from_motion: measure each press's height and indentation along the direction the fingertip
            moved during that contact instead of ``press_axis`` (a tracker whose frame is tilted, a person's press;
            see :mod:`palpate.core.perception.press_axis`).
        features: "both" (kinesthetic and cutaneous laws) or "kinesthetic" (c_P from a force: no contact area).
        on_threshold, off_threshold: hysteresis levels on c_P (None: from the data's noise).
        min_duration: shortest accepted contact, s.
        min_depth: shallowest accepted press, m.
        min_samples: fewest accepted press-phase samples.
    """

    clock_offset: float = 0.0
    max_gap: float = 0.1
    noise_threshold: int = 0
    calibration: Calibration = None
    press_axis: tuple[float, float, float] = (0.0, 0.0, -1.0)
    press_axis_from_motion: bool = False
    features: str = "both"
    on_threshold: float | None = None
    off_threshold: float | None = None
    min_duration: float = 0.1
    min_depth: float = 0.0005
    min_samples: int = 5

    def __post_init__(self) -> None:
        if self.features not in FEATURES:
            raise ValidationError(f"PipelineConfig.features must be one of {FEATURES}, got {self.features!r}")
        if not np.isfinite(self.clock_offset):
            raise ValidationError(f"PipelineConfig.clock_offset must be finite (s), got {self.clock_offset!r}")
        if not (np.isfinite(self.max_gap) and self.max_gap > 0):
            raise ValidationError(f"PipelineConfig.max_gap must be > 0 s, got {self.max_gap!r}")
        press_axis_unit(self.press_axis)
        object.__setattr__(self, "press_axis", tuple(float(v) for v in self.press_axis))


DEFAULT_CONFIG = PipelineConfig()


def contact_series_from_recording(rec: PressRecording, config: PipelineConfig = DEFAULT_CONFIG) -> ContactSeries:
    """Synchronise a recording's streams and compute its contact features."""
    return _synced_series(rec, config)[1]


def _synced_series(rec: PressRecording, config: PipelineConfig) -> tuple[SyncedStream, ContactSeries]:
    stream = synchronise(rec.frames, rec.poses, clock_offset=config.clock_offset, max_gap=config.max_gap)
    if stream.gaps:
        log.info("pose stream has %d gap(s) longer than %g s; %d taxel frames marked invalid",
                 len(stream.gaps), config.max_gap, stream.n_invalid)
    series = contact_features(stream, noise_threshold=config.noise_threshold, calibration=config.calibration,
                              press_axis=config.press_axis)
    if config.press_axis_from_motion:
        th = estimate_thresholds(series.c_P, config.on_threshold, config.off_threshold)
        series = heights_along_motion(series, stream.position, th)
    return stream, series


def presses_from_recording(rec: PressRecording, config: PipelineConfig = DEFAULT_CONFIG) -> Segmentation:
    """Sync -> features -> segmentation of one recording.

    Returns:
        The :class:`Segmentation`: accepted presses (press phase only) and rejected contacts with reasons.

    Raises:
        ValidationError: malformed streams or configuration (the message names what is wrong).
    """
    return synced_presses(rec, config)[1]


def synced_presses(rec: PressRecording, config: PipelineConfig = DEFAULT_CONFIG) -> tuple[SyncedStream, Segmentation]:
    """:func:`presses_from_recording` and the synchronised stream it was found in (its stacked taxel counts)."""
    stream, series = _synced_series(rec, config)
    return stream, segment_presses(
        series,
        on_threshold=config.on_threshold,
        off_threshold=config.off_threshold,
        min_duration=config.min_duration,
        min_depth=config.min_depth,
        min_samples=config.min_samples,
        series_checked=True,  # made just now from validated streams
    )


def fit_presses(presses: list[Press]) -> list[PressFit]:
    """Fit the interaction laws of every press; presses whose fit fails are skipped and logged as warnings.

    Use :func:`fit_presses_with_failures` to get the failures as data.
    """
    fits, failures = fit_presses_with_failures(presses)
    for f in failures:
        log.warning("skipped %s", f.reason)
    return fits


def fit_presses_with_failures(presses: list[Press]) -> tuple[list[PressFit], list[FitFailure]]:
    """Fit every press; return (fits, failures) where each failure names the press and the reason."""
    return fit_presses_reporting(presses)
