"""Fingertip reversals (core/alignment/events.reversals) on a tracker's noisy path: one per turn, alternating."""

from __future__ import annotations

import numpy as np
import pytest

from palpate.core.alignment.events import reversals
from palpate.hardware.polhemus.emulator import press_motion


@pytest.mark.parametrize("seed", range(12))
def test_a_noisy_slow_turn_is_one_reversal_and_reversals_alternate(seed):
    """A raised-cosine press (5 mm every 2 s, 240 Hz) with 0.1 mm of noise per axis, as the Liberty emulator gives:
    the slow bottom and top of each press are one reversal each, near the true turn, and they alternate in
    direction (noise used to break a slow turn into two reversals the same way, 0.3 s apart, which made two presses
    pair with the c_P peaks at two clock offsets)."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 6.0, 1.0 / 240.0)
    motion = press_motion(depth=0.005, period=2.0)
    path = np.array([motion(ti, 1)[0] for ti in t]) + rng.normal(0.0, 1e-4, (len(t), 3))
    found = reversals(t, path)
    np.testing.assert_allclose([r.t for r in found], [1.0, 2.0, 3.0, 4.0, 5.0], atol=0.05)
    down = [r.direction[2] < 0 for r in found]  # moving down before the turn: the bottom of a press
    assert down == [True, False, True, False, True]


def test_a_real_double_dip_keeps_its_three_reversals():
    """Down 5 mm, up 2 mm, down 2 mm, up: two bottoms and the top between them are real turns, not noise."""
    t = np.arange(0.0, 4.0, 1.0 / 240.0)
    z = np.interp(t, [0.0, 1.0, 1.5, 2.0, 3.0, 4.0], [0.05, 0.045, 0.047, 0.045, 0.05, 0.05])
    found = reversals(t, np.column_stack([np.zeros_like(t), np.zeros_like(t), z]))
    assert [r.direction[2] < 0 for r in found] == [True, False, True]
    np.testing.assert_allclose([r.t for r in found], [1.0, 1.5, 2.0], atol=0.1)
