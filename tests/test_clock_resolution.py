"""The clock offset's printed uncertainty carries the timestamps' resolution: a Liberty stamps whole milliseconds, and
no number of presses averages a truncated stamp's half-tick lag away."""

from __future__ import annotations

import numpy as np
import pytest
from clock_streams import OFFSET, streams

from palpate.core.alignment.clock import estimate_clock_map, stamp_resolution
from palpate.core.perception.streams import PoseSample


def test_the_stamps_tick_is_found_and_a_computed_period_has_none():
    rng = np.random.default_rng(0)
    t = 3.0 + np.arange(0.0, 10.0, 1 / 240) + rng.uniform(0, 1 / 240)
    assert stamp_resolution(np.floor(t * 1000) / 1000) == pytest.approx(1e-3)
    assert stamp_resolution(np.round(t * 1e4) / 1e4) == pytest.approx(1e-4)
    jittered = t + rng.normal(0.0, 2e-5, len(t))  # host-stamped floats: only the counting quantum
    assert stamp_resolution(jittered) == pytest.approx(1e-6)
    assert stamp_resolution(5.0 + 0.02 * np.arange(500)) == 0.0  # start + k period: no tick finer than the period
    assert stamp_resolution([1.0]) == 0.0


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_a_millisecond_stamp_truncation_lies_within_the_printed_uncertainty(seed):
    frames, poses = streams(seed, 0.0, presses=6)
    # the device truncates to its 1 ms tick: each pose stamped up to 1 ms early, 0.5 ms on average
    ticked = [PoseSample(float(np.floor(p.t * 1000.0) / 1000.0), p.position, p.quaternion) for p in poses]
    cmap = estimate_clock_map(frames, ticked, max_offset=0.5)  # presses every 2 s
    error = cmap.to_taxel(5.0) - 5.0 - OFFSET
    assert 0.2e-3 < error < 1.0e-3  # the truncation's lag, which the fine step cannot see
    assert abs(error) <= 2.0 * cmap.offset_std
    assert cmap.resolution == pytest.approx(0.5e-3, rel=0.01)
    assert "timestamp resolution" in cmap.text()
    # float stamps: the uncertainty stays the scatter's
    assert estimate_clock_map(frames, poses, max_offset=0.5).resolution < 1e-6
