"""Press segmentation: hysteresis, first-contact height, press phase, and every rejection with its reason."""

from __future__ import annotations

import numpy as np
import pytest
from synthetic_streams import PressSpec, make_recording, series_from_arrays

from palpate.core.errors import ValidationError
from palpate.core.perception.pipeline import PipelineConfig, contact_series_from_recording
from palpate.core.perception.segment import segment_presses
from palpate.core.perception.streaming import PressSegmenter

SURFACE = 0.03

SPECS = [
    PressSpec(0.3, 0.004, hold=0.3, x=0.00, y=0.00),
    PressSpec(1.9, 0.003, x=0.02, y=0.00),
    # A short pause between these two: contact ends for 0.25 s only.
    PressSpec(2.95, 0.002, approach=0.001, x=0.02, y=0.02),
    PressSpec(3.6, 0.0035, approach=0.001, x=0.00, y=0.02),
    PressSpec(4.55, 0.004, x=0.01, y=0.01),  # partial: the stream ends while pressing
]
T_END = 5.0


def _true_contacts(specs):
    """(t_contact, t_deepest, t_release) of each press from its spec."""
    out = []
    for p in specs:
        t_c = p.t_start + p.approach / p.speed
        t_b = t_c + p.depth / p.speed
        out.append((t_c, t_b, t_b + p.hold + p.depth / p.speed))
    return out


def _noisy_series(rng, **kw):
    rec = make_recording(SPECS, rng=rng, t_end=T_END, surface_z=SURFACE, sensel_noise=0.6, pose_noise=2e-5, **kw)
    return rec, contact_series_from_recording(rec.recording, PipelineConfig())


def test_finds_exactly_the_presses_in_a_noisy_stream_with_pauses_and_a_partial_end(rng):
    _, series = _noisy_series(rng)
    seg = segment_presses(series)
    truth = _true_contacts(SPECS)
    assert len(seg.presses) == 4
    assert len(seg.rejected) == 1
    assert seg.rejected[0].reason.startswith("partial: stream ends before release")
    assert seg.rejected[0].t_onset == pytest.approx(truth[4][0], abs=0.1)
    assert [p.index for p in seg.presses] == [0, 1, 2, 3] and seg.rejected[0].index == 4
    for press, spec, (t_c, t_b, t_r) in zip(seg.presses, SPECS, truth, strict=False):
        assert press.t_onset == pytest.approx(t_c, abs=0.05)
        # With pose noise the deepest sample may be anywhere in a hold.
        assert t_b - 0.05 <= press.t_peak <= t_b + spec.hold + 0.05
        assert press.t_release == pytest.approx(t_r, abs=0.05)
        assert press.location == pytest.approx((spec.x, spec.y), abs=1e-4)
        # 30 Hz poses linearly interpolated cut the corner at the deepest point by up to ~0.17 mm.
        assert press.depth == pytest.approx(spec.depth, abs=3e-4)
        assert press.h0 == pytest.approx(SURFACE, abs=2e-4)
    assert seg.noise > 0 and seg.off_threshold < seg.on_threshold


def test_press_phase_runs_from_onset_to_the_deepest_point(rng):
    _, series = _noisy_series(rng)
    for press in segment_presses(series).presses:
        assert press.t[-1] == press.t_peak
        assert press.c_D[-1] == pytest.approx(press.depth) and press.c_D.max() == pytest.approx(press.depth)
        assert np.all(press.c_D >= 0)
        assert press.t[0] >= press.t_onset and press.t_peak < press.t_release
        assert len(press.t) == len(press.c_P) == len(press.c_A) == len(press.c_D) == press.n_samples


def test_first_contact_height_is_exact_on_clean_data(rng):
    rec = make_recording(SPECS[:2], rng=rng, t_end=2.9, surface_z=SURFACE)
    seg = segment_presses(contact_series_from_recording(rec.recording))
    assert len(seg.presses) == 2 and not seg.rejected
    for press, spec in zip(seg.presses, SPECS, strict=False):
        # Frames are 0.2 mm apart in height; the 3/2-law extrapolation locates contact far better than that.
        assert press.h0 == pytest.approx(SURFACE, abs=1e-5)
        assert press.depth == pytest.approx(spec.depth, abs=1e-5)


def test_hysteresis_keeps_a_noisy_hold_as_one_press(rng):
    t = np.arange(0.0, 3.0, 0.02)
    # Press 1.5 mm deep, back off to 0.6 mm and hold there, then release.
    height = np.interp(t, [0, 0.3, 0.65, 0.9, 1.9, 2.1, 3.0],
                       [0.032, 0.032, 0.0285, 0.0294, 0.0294, 0.032, 0.032])
    c_p = 40.0 * np.clip((0.03 - height) * 1e3, 0, None) ** 1.5 + rng.normal(0.0, 2.0, len(t))
    on, off = 40.0 * 0.6**1.5, 6.0  # the hold level sits right at the on threshold
    hold = (t > 0.95) & (t < 1.85)
    crossings = np.count_nonzero(np.diff((c_p[hold] > on).astype(int)) == 1)
    assert crossings >= 5  # a single threshold would split this press many times
    seg = segment_presses(series_from_arrays(t, c_p, height), on_threshold=on, off_threshold=off)
    assert len(seg.presses) == 1 and not seg.rejected
    assert seg.presses[0].t_peak == pytest.approx(0.65, abs=0.02)
    # Contact ends during the lift from 1.9 s, before the tip leaves the surface at 2.1 - 0.2 * 0.6 / 2.6 s.
    assert 1.9 < seg.presses[0].t_release <= 2.1 - 0.2 * 0.6 / 2.6


def test_short_pause_does_not_merge_two_presses():
    t = np.arange(0.0, 2.0, 0.01)
    height = np.interp(t, [0, 0.2, 0.6, 0.9, 0.95, 1.3, 1.6, 2.0],
                       [0.031, 0.031, 0.027, 0.0305, 0.0305, 0.027, 0.031, 0.031])
    c_p = 50.0 * np.clip((0.03 - height) * 1e3, 0, None) ** 1.5
    seg = segment_presses(series_from_arrays(t, c_p, height))
    assert len(seg.presses) == 2
    assert seg.presses[0].t_release < seg.presses[1].t_onset


def _single_press(t_end=2.0, depth=0.003, valid=None):
    """One press at 10 mm/s from 2 mm above the surface at z = 0.03 m, starting at 0.4 s."""
    t = np.arange(0.0, t_end, 0.02)
    travel = (0.002 + depth) / 0.01
    height = np.interp(t, [0, 0.4, 0.4 + travel, 0.4 + 2 * travel, 10.0], [0.032, 0.032, 0.03 - depth, 0.032, 0.032])
    c_p = 50.0 * np.clip((0.03 - height) * 1e3, 0, None) ** 1.5
    return series_from_arrays(t, c_p, height, valid=valid)


@pytest.mark.parametrize(
    ("kwargs", "series_kw", "reason"),
    [
        ({"min_duration": 1.0}, {}, "too short"),
        ({"min_depth": 0.005}, {}, "too shallow"),
        ({"min_samples": 40}, {}, "too few samples"),
        ({}, {"t_end": 0.8}, "partial: stream ends before release"),
    ],
)
def test_each_rejection_has_its_reason(kwargs, series_kw, reason):
    seg = segment_presses(_single_press(**series_kw), **kwargs)
    assert seg.presses == []
    assert len(seg.rejected) == 1 and seg.rejected[0].reason.startswith(reason)


def test_invalid_pose_during_contact_rejects_the_press():
    n = len(np.arange(0.0, 2.0, 0.02))
    valid = np.ones(n, bool)
    valid[32] = False  # inside the contact of the single press
    seg = segment_presses(_single_press(valid=valid))
    assert seg.presses == [] and seg.rejected[0].reason.startswith("invalid pose: 1 of")
    valid = np.ones(n, bool)
    valid[-5:] = False  # after release: harmless
    assert len(segment_presses(_single_press(valid=valid)).presses) == 1


def test_stream_starting_in_contact_is_partial():
    s = _single_press()
    seg = segment_presses(s.slice(40, len(s)))
    assert seg.presses == [] and seg.rejected[0].reason.startswith("partial: stream starts in contact")


def test_streaming_segmenter_matches_batch(rng):
    _, series = _noisy_series(rng)
    batch = segment_presses(series)
    seg = PressSegmenter(thresholds=batch.thresholds)
    got = []
    edges = np.unique(np.concatenate([[0], rng.integers(1, len(series), 25), [len(series)]]))
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        got += seg.feed(series.slice(a, b))
    got += seg.finish()
    assert [p.index for p in got] == [p.index for p in batch.presses]
    for p, q in zip(got, batch.presses, strict=True):
        assert p.t_onset == pytest.approx(q.t_onset) and p.depth == pytest.approx(q.depth)
        np.testing.assert_allclose(p.c_D, q.c_D)
    assert [(r.index, r.reason) for r in seg.rejected] == [(r.index, r.reason) for r in batch.rejected]


def test_streaming_segmenter_estimates_thresholds_after_warmup():
    s = _single_press()
    seg = PressSegmenter(warmup=15)
    assert seg.feed(s.slice(0, 10)) == [] and seg.thresholds is None
    presses = seg.feed(s.slice(10, len(s))) + seg.finish()
    assert len(presses) == 1 and seg.thresholds is not None
    with pytest.raises(ValidationError, match="chunk starts"):
        seg2 = PressSegmenter(on_threshold=5.0, off_threshold=1.0)
        seg2.feed(s.slice(0, 20))
        seg2.feed(s.slice(10, 30))


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"on_threshold": 5.0, "off_threshold": 5.0}, "below on_threshold"),
        ({"on_threshold": float("nan")}, "finite"),
        ({"min_samples": 2}, "min_samples"),
        ({"min_depth": -1.0}, "min_depth"),
        ({"min_duration": float("inf")}, "min_duration"),
    ],
)
def test_bad_parameters_raise(kwargs, match):
    with pytest.raises(ValidationError, match=match):
        segment_presses(_single_press(), **kwargs)


def test_non_finite_series_is_rejected():
    s = _single_press()
    s.c_P[10] = np.nan
    with pytest.raises(ValidationError, match="c_P"):
        segment_presses(s)
