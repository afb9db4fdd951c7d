"""End to end: raw streams -> sync -> features -> presses -> interaction parameters."""

from __future__ import annotations

import dataclasses
import logging

import numpy as np
import pytest
from synthetic_streams import PressSpec, make_recording

from palpate.core.errors import ValidationError
from palpate.core.perception.pipeline import (
    PipelineConfig,
    fit_presses,
    fit_presses_with_failures,
    presses_from_recording,
)
from palpate.core.perception.segment import Press
from palpate.core.perception.sync import estimate_clock_offset

N1 = 60.0  # counts / mm^1.5
SPECS = [PressSpec(0.3 + 1.4 * i, 0.004, x=0.01 * i, y=0.005) for i in range(4)]
T_END = 0.3 + 1.4 * 4


def test_clean_recording_recovers_n1_and_locations(rng):
    rec = make_recording(SPECS, rng=rng, t_end=T_END, n1=N1, clock_offset=0.08)
    seg = presses_from_recording(rec.recording, PipelineConfig(clock_offset=0.08))
    assert len(seg.presses) == 4 and not seg.rejected
    fits = fit_presses(seg.presses)
    assert [f.press_index for f in fits] == [0, 1, 2, 3]
    for f, spec in zip(fits, SPECS, strict=True):
        assert f.n1 == pytest.approx(N1, rel=0.01)
        assert abs(f.n2) < 2.0  # counts; the law has no offset
        assert f.location == pytest.approx((spec.x, spec.y), abs=1e-9)
        assert f.a1 > 0


def test_noisy_recording_recovers_n1_on_average(rng):
    rec = make_recording(SPECS, rng=rng, t_end=T_END, n1=N1, clock_offset=0.08, pose_noise=2e-5,
                         sensel_noise=0.5, intensity_noise=2.0)
    fits = fit_presses(presses_from_recording(rec.recording, PipelineConfig(clock_offset=0.08)).presses)
    assert len(fits) == 4
    n1 = np.array([f.n1 for f in fits])
    assert np.mean(n1) == pytest.approx(N1, rel=0.05)
    assert np.all(np.abs(n1 - N1) < 0.12 * N1)


def _decelerating_press(rng, clock_offset):
    """2 mm into the surface at 10 mm/s, 2 mm more at 2.5 mm/s, hold, release (surface at z = 0.03 m)."""
    tk = np.array([0, 0.3, 0.5, 0.7, 1.5, 1.8, 2.4, 3.0])
    zk = np.array([0.032, 0.032, 0.030, 0.028, 0.026, 0.026, 0.032, 0.032])
    return make_recording([PressSpec(0.3, 0.004)], rng=rng, t_end=3.0, n1=N1, clock_offset=clock_offset,
                          knots=(tk, zk))


def test_ignoring_the_clock_offset_biases_the_fit_when_speed_changes(rng):
    # At constant speed a time shift is a height shift that the first-contact height absorbs; a change of speed
    # during the press is what makes the offset matter.
    rec = _decelerating_press(rng, 0.15)
    right = fit_presses(presses_from_recording(rec.recording, PipelineConfig(clock_offset=0.15)).presses)
    wrong = fit_presses(presses_from_recording(rec.recording, PipelineConfig(clock_offset=0.05)).presses)
    assert right[0].n1 == pytest.approx(N1, rel=0.01)
    assert abs(wrong[0].n1 - N1) > 0.2 * N1


def test_estimated_clock_offset_makes_the_fit_right(rng):
    rec = _decelerating_press(rng, 0.15)
    offset = estimate_clock_offset(rec.recording.frames, rec.recording.poses)
    assert offset == pytest.approx(0.15, abs=0.01)
    fit = fit_presses(presses_from_recording(rec.recording, PipelineConfig(clock_offset=offset)).presses)[0]
    assert fit.n1 == pytest.approx(N1, rel=0.05)


def test_pose_gap_during_one_press_rejects_only_that_press(rng):
    # The second press touches at 1.9 s and is deepest at 2.3 s; poses are missing in between.
    rec = make_recording(SPECS, rng=rng, t_end=T_END, n1=N1, pose_gap=(2.0, 2.2))
    seg = presses_from_recording(rec.recording)
    assert [p.index for p in seg.presses] == [0, 2, 3]
    assert len(seg.rejected) == 1 and seg.rejected[0].index == 1
    assert seg.rejected[0].reason.startswith("invalid pose")


def test_calibration_scales_the_kinesthetic_parameters(rng):
    rec = make_recording(SPECS[:1], rng=rng, t_end=1.8, n1=N1)
    raw = fit_presses(presses_from_recording(rec.recording).presses)[0]
    cal = fit_presses(presses_from_recording(rec.recording, PipelineConfig(calibration=0.02)).presses)[0]
    assert cal.calibrated and not raw.calibrated
    assert cal.n1 == pytest.approx(0.02 * raw.n1, rel=1e-6)
    assert cal.phi_n == pytest.approx(0.02**2 * raw.phi_n, rel=1e-6)


def test_presses_whose_fit_fails_are_skipped_and_reported(rng, caplog):
    rec = make_recording(SPECS[:2], rng=rng, t_end=3.2, n1=N1)
    presses = presses_from_recording(rec.recording).presses
    # A press whose area never changes cannot give the cutaneous law.
    flat = dataclasses.replace(presses[0], index=7, c_A=np.full(presses[0].n_samples, presses[0].c_A.max()))
    fits, failures = fit_presses_with_failures([flat, presses[1]])
    assert [f.press_index for f in fits] == [1]
    assert len(failures) == 1 and failures[0].press_index == 7 and "cutaneous" in failures[0].reason
    with caplog.at_level(logging.WARNING, logger="palpate.core.perception.pipeline"):
        assert [f.press_index for f in fit_presses([flat, presses[1]])] == [1]
    assert "press 7" in caplog.text


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [({"max_gap": 0.0}, "max_gap"), ({"clock_offset": float("inf")}, "clock_offset"),
     ({"press_axis": (0.0, 0.0, 0.0)}, "press_axis")],
)
def test_bad_config_is_rejected(kwargs, match):
    with pytest.raises(ValidationError, match=match):
        PipelineConfig(**kwargs)


def test_config_is_frozen_and_press_type_is_plain_data():
    with pytest.raises(dataclasses.FrozenInstanceError):
        PipelineConfig().max_gap = 1.0  # type: ignore[misc]
    assert dataclasses.is_dataclass(Press)
