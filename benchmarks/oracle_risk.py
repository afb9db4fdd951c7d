"""An oracle reference for the exploration benchmarks: info_gain told where its map is wrong.

The clairvoyant references (benchmarks/clairvoyant.py, clairvoyant_bound.py) know every press's *reading*; this one
knows the *truth* instead, but only uses it to say where the post-processed map is wrong now: info_gain's value of
every unpressed cell whose most probable material is not the true one (or is undecided) rises by
``oracle_weight`` (cells). Everything else, the lattice, the belief, the expected gain, the one-press-at-a-time
choice, is info_gain's. So it tells apart two reasons for a long tail: if this planner has the tail too, the greedy
choice is what misses it; if it does not, a greedy planner would do with a better estimate of where the map is wrong
(the risk the planner's belief misjudges), and that estimate is what to improve.

Run through benchmarks/exploration_families.py (``--policies ...,oracle_risk``, offline only; ``--info-gain``
settings apply to it too).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from family_runs import Run, offline_run
from scene_families import FamilyScene

from palpate.core.mapping.accuracy import decided_labels
from palpate.core.planning.info_gain import InfoGain


def wrong_unpressed(grid, post, truth: np.ndarray) -> np.ndarray:
    """(ny, nx) 1.0 on each unpressed cell with a true material (truth >= 0) whose post-processed most probable
    material is not it or is undecided (as the benchmark's accuracy counts it), else 0.0."""
    label, decided = decided_labels(np.asarray(post.probabilities))
    wrong = (truth >= 0) & ~((label == truth) & decided)
    return (wrong & ~np.asarray(grid.explored, dtype=bool)).astype(float)


@dataclass
class OracleRisk(InfoGain):
    """info_gain plus ``oracle_weight`` on every cell :func:`wrong_unpressed` marks (module docstring).

    Args (beyond :class:`~palpate.core.planning.info_gain.InfoGain`'s):
        truth: (ny, nx) true material index per cell (-1: not counted).
        oracle_weight: value added per wrong unpressed cell, cells (1: a wrong cell is worth one cell set right).
    """

    truth: np.ndarray | None = None
    oracle_weight: float = 1.0

    def _value(self, grid, post):
        value, cells, allowed = super()._value(grid, post)
        # a new array: info_gain keeps ``value`` between choices and refreshes it only where the map changed
        return value + self.oracle_weight * wrong_unpressed(grid, post, self.truth), cells, allowed


def with_oracle(policy: InfoGain, truth: np.ndarray) -> OracleRisk:
    """An :class:`OracleRisk` with every setting of ``policy`` (an info_gain policy) and the scene's truth."""
    kept = {f.name: getattr(policy, f.name) for f in dataclasses.fields(InfoGain) if f.init}
    return OracleRisk(**kept, truth=np.asarray(truth))


def oracle_risk_run(fs: FamilyScene, *, stop_at: float | None = None, settings: dict | None = None) -> Run:
    """The oracle-risk planner on one scene, presses answered offline as info_gain's (benchmarks/family_runs.py)."""
    return offline_run(fs, "info_gain", stop_at=stop_at, settings=settings, policy_for=with_oracle)
