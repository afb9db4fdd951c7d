"""How sharp is an estimate of where a press would read other than the map says?

With that signal exact, info_gain meets the worst-scene target on every tuning scene, and it needs about 90% of
those cells marked at 10% false alarms (docs/results.md, "What the greedy planner lacks"). This harness runs
info_gain on scenes of benchmarks/scene_families.py (presses answered offline, stopped as the benchmark stops
them), records the planner's state every ``--every``-th choice after the lattice (at most ``--snapshots`` a scene)
and, for every unpressed cell, the oracle's label (:func:`oracle_risk.wrong_unpressed` against the felt map: a
press there would read other than the map's decided label). Each estimate of benchmarks/risk_estimates.py is scored
by its hits at 10% false alarms and its AUC, pooled over cells, per family and over all.

Anything learned must generalise: the logistic stack of the estimates (``--stack``) is fitted leave-one-family-out
(fitted on the other families' cells, scored on the held-out family's); ``--check A B`` fits it on every family of
the first seed range and scores it, and every estimate, once on seeds A-B (never fitted or chosen on).

Run: .venv/bin/python benchmarks/risk_harness.py [--seeds 0 72] [--estimators post,belief,potts,line,wall,subset]
     [--stack] [--check 72 144]
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.optimize import minimize
from scipy.stats import rankdata

sys.path.insert(0, str(Path(__file__).resolve().parent))

from family_runs import ACCURACY, OF_CEILING, felt_cells_cached, offline_run  # noqa: E402
from oracle_risk import wrong_unpressed  # noqa: E402
from risk_estimates import (  # noqa: E402
    MapState,
    belief_risk,
    line_risk,
    post_risk,
    potts_risk,
    subset_risk,
    wall_risk,
)
from scene_families import scene  # noqa: E402

from palpate.core.errors import ValidationError  # noqa: E402
from palpate.core.planning.info_gain import InfoGain, uncovered  # noqa: E402

ESTIMATORS = {"post": post_risk, "belief": belief_risk, "potts": potts_risk, "line": line_risk, "wall": wall_risk,
              "subset": subset_risk}
FALSE_ALARM = 0.1


@dataclass(frozen=True)
class Snapshot:
    """One logged choice: the scene's seed and family, the planner's state, and the oracle's label per cell."""

    seed: int
    family: str
    state: MapState
    wrong: np.ndarray


@dataclass
class _Logging(InfoGain):
    """info_gain that records its state every ``every``-th choice after the lattice (into ``log``)."""

    log: list | None = None
    every: int = 3
    snapshots: int = 12
    _after_lattice: int = dataclasses.field(default=0, init=False, repr=False)

    def next_target(self, grid, post=None, last=None):
        target = super().next_target(grid, post, last)
        if self.lattice_cell(grid, last) is None:
            if self._after_lattice % self.every == 0 and len(self.log) < self.snapshots:
                self.log.append(MapState(np.asarray(grid.probabilities).copy(),
                                         np.asarray(grid.explored, dtype=bool).copy(),
                                         np.asarray(post.probabilities).copy()))
            self._after_lattice += 1
        return target


def scene_snapshots(seed: int, every: int = 3, snapshots: int = 12) -> list[Snapshot]:
    """info_gain's logged states on one scene, run until the benchmark's stop (95% absolute where raster gets
    there, else 95% of the ceiling), each with the oracle's label against the felt map."""
    fs = scene(seed)
    raster = offline_run(fs, "raster")
    stop = ACCURACY if raster.presses_to(ACCURACY) is not None else OF_CEILING * float(raster.accuracy[-1])
    log: list[MapState] = []

    def build(policy, truth):
        kept = {f.name: getattr(policy, f.name) for f in dataclasses.fields(InfoGain) if f.init}
        return _Logging(**kept, log=log, every=every, snapshots=snapshots)

    offline_run(fs, "info_gain", stop_at=stop, policy_for=build)
    felt = felt_cells_cached(fs)
    return [Snapshot(seed, fs.family, s, wrong_unpressed(s, _Post(s.post), felt) > 0) for s in log]


@dataclass(frozen=True)
class _Post:
    """Just the probabilities of a post-processed map (what :func:`wrong_unpressed` reads)."""

    probabilities: np.ndarray


def hits_at(risk: np.ndarray, wrong: np.ndarray, false_alarm: float = FALSE_ALARM) -> float:
    """Share of the ``wrong`` cells whose risk is above the threshold that marks ``false_alarm`` of the others;
    ties at the threshold are shared out as a random tie-break would, so exactly ``false_alarm`` is spent."""
    wrong = np.asarray(wrong, dtype=bool)
    pos, neg = risk[wrong], risk[~wrong]
    if not pos.size or not neg.size:
        raise ValidationError("hits_at needs both wrong and right cells")
    thr = np.quantile(neg, 1.0 - false_alarm)
    above, tie = np.mean(neg > thr), np.mean(neg == thr)
    share = (false_alarm - above) / tie if tie > 0 else 0.0
    return float(np.mean(pos > thr) + share * np.mean(pos == thr))


def auc(risk: np.ndarray, wrong: np.ndarray) -> float:
    """Probability that a wrong cell's risk is above a right cell's (ties count half)."""
    wrong = np.asarray(wrong, dtype=bool)
    pos_n, neg_n = int(wrong.sum()), int((~wrong).sum())
    if not pos_n or not neg_n:
        raise ValidationError("auc needs both wrong and right cells")
    ranks = rankdata(risk)
    return float((ranks[wrong].sum() - pos_n * (pos_n + 1) / 2) / (pos_n * neg_n))


#: The stack's inputs beyond the estimates: uncovered (no press in the 4-neighbourhood) and the share of the
#: scene's materials no press has read yet (a material the memory knows must be somewhere).
EXTRA = ("uncovered", "unread")


def stack_inputs(s: MapState, names: tuple[str, ...]) -> np.ndarray:
    """(unpressed cells, len(names) + len(EXTRA)) inputs of the logistic stack."""
    m = s.post.shape[-1]
    unread = 1.0 - np.unique(s.readings[s.explored]).size / m
    cols = [ESTIMATORS[n](s) for n in names] + [uncovered(s), np.full(s.explored.shape, unread)]
    return np.stack(cols, -1)[~s.explored]


def fit_logistic(x: np.ndarray, y: np.ndarray, l2: float = 1e-3) -> np.ndarray:
    """Weights (constant first) of an L2-penalised logistic regression of ``y`` on ``x``."""
    a = np.column_stack([np.ones(len(x)), x])
    yf = y.astype(float)

    def loss(w):
        z = a @ w
        grad = a.T @ (1.0 / (1.0 + np.exp(-z)) - yf) / len(yf) + l2 * w
        return float(np.mean(np.logaddexp(0.0, z) - yf * z) + 0.5 * l2 * w @ w), grad

    return minimize(loss, np.zeros(a.shape[1]), jac=True, method="L-BFGS-B").x


def logit(x: np.ndarray, w: np.ndarray) -> np.ndarray:
    return w[0] + x @ w[1:]


def leave_one_family_out(x: np.ndarray, y: np.ndarray, family: np.ndarray) -> np.ndarray:
    """Out-of-family scores: each family's cells scored by a stack fitted on the other families' cells."""
    out = np.empty(len(y))
    for f in np.unique(family):
        held = family == f
        out[held] = logit(x[held], fit_logistic(x[~held], y[~held]))
    return out


def score_line(name: str, risk: np.ndarray, wrong: np.ndarray, family: np.ndarray) -> str:
    """'name all hits/AUC, family hits/AUC ...' (hits at :data:`FALSE_ALARM`)."""
    parts = [f"{name:<10} all {hits_at(risk, wrong):.2f}/{auc(risk, wrong):.2f}"]
    for f in np.unique(family):
        sel = family == f
        parts.append(f"{f} {hits_at(risk[sel], wrong[sel]):.2f}/{auc(risk[sel], wrong[sel]):.2f}")
    return " | ".join(parts)


def _cells(snaps: list[Snapshot]) -> tuple[np.ndarray, np.ndarray]:
    wrong = np.concatenate([s.wrong[~s.state.explored] for s in snaps])
    family = np.concatenate([np.full(int((~s.state.explored).sum()), s.family) for s in snaps])
    return wrong, family


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, nargs=2, default=(0, 72), metavar=("FROM", "TO"))
    ap.add_argument("--estimators", default=",".join(ESTIMATORS))
    ap.add_argument("--stack", action="store_true", help="logistic stack of the estimates, leave-one-family-out")
    ap.add_argument("--check", type=int, nargs=2, metavar=("FROM", "TO"),
                    help="fit the stack on --seeds, score it once on these seeds")
    ap.add_argument("--every", type=int, default=3)
    ap.add_argument("--snapshots", type=int, default=12)
    args = ap.parse_args(argv)
    names = tuple(n for n in args.estimators.split(",") if n)
    unknown = [n for n in names if n not in ESTIMATORS]
    if unknown:
        ap.error(f"unknown estimators {unknown}; known: {', '.join(ESTIMATORS)}")
    t0 = time.time()
    snaps = [s for seed in range(*args.seeds) for s in scene_snapshots(seed, args.every, args.snapshots)]
    wrong, family = _cells(snaps)
    print(f"seeds {args.seeds[0]}-{args.seeds[1] - 1}: {len(snaps)} states, {wrong.size} unpressed cells, "
          f"{wrong.mean():.1%} would read other than the map says ({time.time() - t0:.0f} s); hits at "
          f"{FALSE_ALARM:.0%} false alarms / AUC")
    for n in names:
        risk = np.concatenate([ESTIMATORS[n](s.state)[~s.state.explored] for s in snaps])
        print(score_line(n, risk, wrong, family), flush=True)
    if args.stack or args.check:
        x = np.concatenate([stack_inputs(s.state, names) for s in snaps])
        print(score_line("stack LOFO", leave_one_family_out(x, wrong, family), wrong, family))
        if args.check:
            w = fit_logistic(x, wrong)
            held = [s for seed in range(*args.check) for s in scene_snapshots(seed, args.every, args.snapshots)]
            hw, hf = _cells(held)
            hx = np.concatenate([stack_inputs(s.state, names) for s in held])
            print(f"checked once on seeds {args.check[0]}-{args.check[1] - 1} (fitted on {args.seeds[0]}-"
                  f"{args.seeds[1] - 1}):")
            for n in names:
                print(score_line(n, np.concatenate([ESTIMATORS[n](s.state)[~s.state.explored] for s in held]),
                                 hw, hf), flush=True)
            print(score_line("stack", logit(hx, w), hw, hf))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
