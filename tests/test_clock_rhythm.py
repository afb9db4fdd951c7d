"""The clock map on presses at a person's rhythm (2-3 s apart, a little irregular): an offset one press-period away
pairs most presses too, and the fine alignment tells the right one from it."""

from __future__ import annotations

import pytest
from clock_streams import OFFSET, human_streams

from palpate.core.alignment.clock import estimate_clock_map
from palpate.core.errors import ValidationError


def test_presses_at_a_persons_rhythm_are_aligned_and_not_refused():
    # seeds 100-111: three of them have a rival offset a period away pairing 18-20 of the 24 presses
    errors = []
    for seed in range(100, 112):
        frames, poses, _ = human_streams(seed)
        cmap = estimate_clock_map(frames, poses)
        assert cmap.presses >= 22, seed
        errors.append(cmap.to_taxel(10.0) - 10.0 - OFFSET)
    assert max(abs(e) for e in errors) < 0.002


@pytest.mark.parametrize("seed", [100, 101, 109])
def test_poses_of_other_presses_are_refused(seed):
    frames, _, _ = human_streams(seed)
    _, poses, _ = human_streams(seed + 1000)
    with pytest.raises(ValidationError, match="clock estimate"):
        estimate_clock_map(frames, poses)
