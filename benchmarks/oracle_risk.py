"""Oracle references for the exploration benchmarks: info_gain told where its map is wrong.

The clairvoyant references (benchmarks/clairvoyant.py, clairvoyant_bound.py) replace info_gain's choice; these keep
it and only add what the planner cannot know: every unpressed cell whose post-processed most probable material
differs from a reference map (or is undecided) is worth ``oracle_weight`` (cells) more. Everything else, the
lattice, the belief, the expected gain, the one-press-at-a-time choice, is info_gain's. Two reference maps:

* ``truth``: where the map is wrong (knows the truth);
* ``readings``: where a press would read something else than the map says (each cell's felt material, what an
  offline press there reads; knows no more than the clairvoyant planner).

So they tell apart two reasons for a long tail: if these planners have the tail too, the greedy choice is what
misses it; if not, a greedy planner would do with a better estimate of where the map is wrong, and that estimate (the
risk the planner's belief misjudges) is what to improve. ``hit`` and ``false_alarm`` make the oracle noisy, to say
how sharp such an estimate must be: a fixed share of cells (drawn once per scene) is never marked, another always.

Run through benchmarks/exploration_families.py (``--policies ...,oracle_truth,oracle_readings``, offline only;
``--info-gain`` settings apply to them too; ``--oracle-noise HIT,FALSE_ALARM``).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from family_runs import Run, felt_cells_cached, offline_run
from scene_families import FamilyScene

from palpate.core.errors import ValidationError
from palpate.core.mapping.accuracy import decided_labels
from palpate.core.planning.info_gain import InfoGain

#: What an oracle compares the map with (module docstring).
KNOWS = ("truth", "readings")


def wrong_unpressed(grid, post, reference: np.ndarray) -> np.ndarray:
    """(ny, nx) 1.0 on each unpressed cell with a reference material (>= 0) whose post-processed most probable
    material is not it or is undecided (as the benchmark's accuracy counts it), else 0.0."""
    label, decided = decided_labels(np.asarray(post.probabilities))
    wrong = (reference >= 0) & ~((label == reference) & decided)
    return (wrong & ~np.asarray(grid.explored, dtype=bool)).astype(float)


@dataclass
class OracleRisk(InfoGain):
    """info_gain plus ``oracle_weight`` on every cell :func:`wrong_unpressed` marks (module docstring).

    Args (beyond :class:`~palpate.core.planning.info_gain.InfoGain`'s):
        reference: (ny, nx) the material index per cell the map is compared with (-1: not counted).
        oracle_weight: value added per marked cell, cells (1: a wrong cell is worth one cell set right).
        hit: share of the wrong cells marked, [0, 1].
        false_alarm: share of the other unpressed cells marked, [0, hit].
        draws: (ny, nx) one uniform [0, 1) number per cell, fixed for the run: a wrong cell is marked when its draw
            is below ``hit``, another when below ``false_alarm`` (None: exact, only with hit 1 and false_alarm 0).
    """

    reference: np.ndarray | None = None
    oracle_weight: float = 1.0
    hit: float = 1.0
    false_alarm: float = 0.0
    draws: np.ndarray | None = None

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.reference is None:
            raise ValidationError("the oracle needs a reference map")
        if not (np.isfinite(self.oracle_weight) and self.oracle_weight >= 0):
            raise ValidationError(f"oracle_weight must be a finite number >= 0, got {self.oracle_weight!r}")
        if not (0 <= self.false_alarm <= self.hit <= 1):
            raise ValidationError(f"need 0 <= false_alarm <= hit <= 1, got {self.false_alarm!r}, {self.hit!r}")
        if self.draws is None and (self.hit, self.false_alarm) != (1.0, 0.0):
            raise ValidationError("a noisy oracle needs its draws")

    def marked(self, grid, post) -> np.ndarray:
        """(ny, nx) 1.0 on the cells the oracle adds value to."""
        wrong = wrong_unpressed(grid, post, self.reference)
        if self.draws is None:
            return wrong
        free = ~np.asarray(grid.explored, dtype=bool)
        return np.where(wrong > 0, self.draws < self.hit, free & (self.draws < self.false_alarm)).astype(float)

    def value_terms(self, grid, post):
        value, cells, allowed = super().value_terms(grid, post)
        # a new array: info_gain keeps ``value`` between choices and refreshes it only where the map changed
        return value + self.oracle_weight * self.marked(grid, post), cells, allowed


def with_oracle(policy: InfoGain, reference: np.ndarray, *, hit: float = 1.0, false_alarm: float = 0.0,
                seed: int = 0) -> OracleRisk:
    """An :class:`OracleRisk` with every setting of ``policy`` (an info_gain policy), comparing with ``reference``;
    a noisy one (``hit`` < 1 or ``false_alarm`` > 0) draws its per-cell numbers with ``seed``."""
    kept = {f.name: getattr(policy, f.name) for f in dataclasses.fields(InfoGain) if f.init}
    reference = np.asarray(reference)
    exact = (hit, false_alarm) == (1.0, 0.0)
    draws = None if exact else np.random.default_rng(seed).random(reference.shape)
    return OracleRisk(**kept, reference=reference, hit=hit, false_alarm=false_alarm, draws=draws)


def oracle_run(fs: FamilyScene, knows: str, *, stop_at: float | None = None, settings: dict | None = None,
               hit: float = 1.0, false_alarm: float = 0.0) -> Run:
    """The oracle planner that ``knows`` the truth or the readings (:data:`KNOWS`) on one scene, presses answered
    offline as info_gain's (benchmarks/family_runs.py)."""
    if knows not in KNOWS:
        raise ValidationError(f"an oracle knows one of {', '.join(KNOWS)}, got {knows!r}")
    felt = felt_cells_cached(fs) if knows == "readings" else None

    def build(policy, truth):
        return with_oracle(policy, truth if felt is None else felt, hit=hit, false_alarm=false_alarm,
                           seed=fs.seed + 5000)

    return offline_run(fs, "info_gain", stop_at=stop_at, settings=settings, felt=felt, policy_for=build)
