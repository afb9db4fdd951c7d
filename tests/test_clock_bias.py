"""The clock map's offset (core/alignment/clock.estimate_clock_map) is unbiased under the tracker's position noise:
over a batch of synthetic sessions with a known offset (tests/clock_streams.py: the emulated fingertip and pad,
sampled without the serial emulators), the mean error stays within a few standard errors of zero (the standard
error taken from the batch's own scatter), with and without noise, at the Liberty's 240 Hz and at 30 Hz.

The session recorder's test once suggested noise pushes the offset positive (+0.7 to +2.2 ms over noise seeds 0-4,
-0.3 ms without noise); on more seeds that was the scatter of two-press estimates (docs/real_rig.md)."""

from __future__ import annotations

import numpy as np
import pytest
from clock_streams import OFFSET, streams

from palpate.core.alignment.clock import estimate_clock_map

SEEDS = range(300, 324)  # not among the benchmark's seeds


def _errors(sigma: float, pose_rate: float) -> np.ndarray:
    out = []
    for seed in SEEDS:
        frames, poses = streams(seed, sigma, presses=4, pose_rate=pose_rate)
        out.append(estimate_clock_map(frames, poses, max_offset=0.5).offset - OFFSET)
    return np.array(out)


@pytest.mark.parametrize("pose_rate", [240.0, 30.0])
@pytest.mark.parametrize("sigma", [0.1e-3, 0.2e-3])
def test_pose_noise_does_not_bias_the_offset(sigma, pose_rate):
    err = _errors(sigma, pose_rate)
    sd = np.std(err, ddof=1)
    # 3.5 standard errors: a batch this size stays inside by chance in all but ~1 of 2000 batches; the seeds are
    # fixed, so the outcome is too
    assert abs(err.mean()) < 3.5 * sd / np.sqrt(len(err)), (err.mean(), sd)
    # noise only scatters the estimates: none is a wild one (a press paired or aligned wrongly)
    assert np.max(np.abs(err - err.mean())) < 5 * sd
    if pose_rate == 240.0 and sigma == 0.1e-3:  # the session recorder's emulator: its test bounds 5 ms
        assert np.max(np.abs(err)) < 0.005


def test_without_noise_the_offset_is_found_to_a_fraction_of_a_millisecond():
    err = _errors(0.0, 240.0)
    assert abs(err.mean()) < 3.5 * np.std(err, ddof=1) / np.sqrt(len(err)) + 1e-4
    assert np.max(np.abs(err)) < 0.001
