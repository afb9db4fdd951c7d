"""The searches of ``palpate calibrate realism``: where a fit goes after its start and Latin-hypercube design.

All work in box positions u in [0, 1]^d (:class:`~palpate.sim.realism.calibrate.FreeParameter`) on a candidate
evaluation that simulates the tuning seeds with common random numbers, so the objective is a deterministic but
rough function of u: a press whose fit changes moves a CV or a negative share by a step, and a parameter can have
no effect at all over part of its box (a foam's plateau strain above the strains the presses reach). Each
candidate costs the same, so the budget counts candidates, whichever search asks for them.

- ``nelder-mead``: the simplex from the best design point (derivative-free, but it walks: with five or more
  parameters it stops far above the objective's floor long before the budget is spent).
- ``trust-region``: Gauss-Newton on the residual vector ((sim - real) / tolerance per moment) with a model
  *fitted*, not differenced: in a box of half-width rho around the centre, the residuals of at least 2d + 1
  candidates (new ones from a seeded Latin hypercube in that box, plus every earlier one inside it) are regressed
  on u, which averages the objective's steps out of the slope and sees a parameter's effect from rho away. The
  step minimises the fitted model within the box (bounded linear least squares); a trial that lowers the objective
  is the new centre (rho doubles when the step reached the box's side), otherwise rho halves; below
  :data:`RHO_MIN` it starts again from :data:`RHO_START` around the best candidate, with d more candidates in
  each model than the last time. Candidates that fail (NaN residuals) stay out of the models; where too many
  fail to fit one, rho doubles, up to the whole box.
- ``multi-start``: the trust region from several design points instead of the best one alone. The trust region
  only descends, and the design's best point can lie in a basin whose floor is far above the truth's (recovery
  fits of five parameters from 20 design points end there about one time in four). So the :data:`MULTI_STARTS`
  best design points at least :data:`MULTI_SEPARATION` box widths apart (infinity norm; greedy, best first) each
  get an equal share of the first :data:`MULTI_FIRST_STAGE` of the remaining budget, and the rest continues the
  region holding the best candidate, with its models' candidates, half-width and random stream. A share is about
  one model and a trial or two: enough to see which start descends lower, not to converge. It cannot find a basin
  no good design point lies in (a truth whose neighbours in the design fail, as presses the drive cannot follow).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from palpate.core.errors import ValidationError

#: The searches :func:`run_search` knows.
SEARCHES = ("nelder-mead", "trust-region", "multi-start")
#: The trust region's first half-width, in box widths (the Nelder-Mead simplex spans the same), its largest and the
#: smallest before a restart: below ~0.02 box widths the objective's steps are all a model would see.
RHO_START, RHO_MAX, RHO_MIN = 0.15, 0.5, 0.02
#: Objective of a candidate whose presses could not be simulated or fitted (residuals NaN): a wall, not a number to
#: descend; the trust region leaves such candidates out of its models.
FAILED = 1e6
#: The multi-start's starts, their least distance apart (box widths, infinity norm) and the share of the remaining
#: budget its first stage (all starts together) takes: with 80 candidates after the design, three starts of about
#: one model (2d + 1 candidates) and a trial each, fewer where the share cannot hold that many.
MULTI_STARTS, MULTI_SEPARATION, MULTI_FIRST_STAGE = 3, 0.3, 0.5


def objective_of(residuals: np.ndarray) -> float:
    """The objective of a residual vector: its sum of squares, :data:`FAILED` when any residual is not finite."""
    r = np.asarray(residuals, dtype=float)
    return float(np.sum(r ** 2)) if np.all(np.isfinite(r)) else FAILED


class BudgetSpent(Exception):
    """Raised by a candidate evaluation once the budget is spent: ends whichever search asked."""


def run_search(search: str, residuals: Callable[[np.ndarray], np.ndarray], start: np.ndarray, remaining: int,
               seed: int = 0, candidates: Sequence[tuple[np.ndarray, np.ndarray]] = ()) -> None:
    """Spend up to ``remaining`` candidates improving on ``start`` (box positions) with ``search``.

    ``residuals(u)``: the residual vector of the candidate at u (:func:`objective_of` is the objective; NaN: the
    candidate failed); it records every candidate itself and raises :class:`BudgetSpent` when the budget is gone,
    which ends the search quietly. The caller takes the best candidate from its own record. ``seed``: the trust
    region's sampling (deterministic). ``candidates``: (u, residuals) of the candidates already evaluated (the
    design), where the multi-start picks its starts (without them it starts from ``start`` alone).
    """
    if search not in SEARCHES:
        raise ValidationError(f"unknown search {search!r}; known: {', '.join(SEARCHES)}")
    if remaining <= 0:
        return
    try:
        if search == "nelder-mead":
            _nelder_mead(residuals, np.asarray(start, float), remaining)
        elif search == "trust-region":
            _trust_region(residuals, _Region.at(np.asarray(start, float), seed))
        else:
            _multi_start(residuals, np.asarray(start, float), remaining, seed, candidates)
    except BudgetSpent:
        pass


def _nelder_mead(residuals, start: np.ndarray, remaining: int) -> None:
    from scipy.optimize import minimize

    d = len(start)
    # the first simplex spans 0.15 of each box, towards the box's middle
    simplex = np.vstack([start] + [np.clip(start + 0.15 * np.eye(d)[i] * (1 if start[i] < 0.85 else -1), 0.0, 1.0)
                                   for i in range(d)])
    minimize(lambda u: objective_of(residuals(u)), start, method="Nelder-Mead", bounds=[(0.0, 1.0)] * d,
             options={"maxfev": remaining, "initial_simplex": simplex, "xatol": 1e-3, "fatol": 1e-3})


@dataclass
class _Region:
    """A trust region's state, kept outside its loop so that a stage cut short can be continued: the centre and its
    residuals (None: not yet evaluated), the half-width rho (box widths), the candidates that did not fail and
    how many candidates each model takes."""

    centre: np.ndarray
    r_centre: np.ndarray | None
    rho: float
    rng: np.random.Generator
    points_per_model: int
    seen: list[tuple[np.ndarray, np.ndarray]] = field(default_factory=list)

    @classmethod
    def at(cls, start: np.ndarray, seed, r_start: np.ndarray | None = None) -> _Region:
        return cls(np.clip(start, 0.0, 1.0), r_start, RHO_START, np.random.default_rng(seed), 2 * len(start) + 1)

    def best(self) -> float:
        return min((objective_of(r) for _, r in self.seen), default=FAILED)


def _trust_region(residuals, region: _Region) -> None:
    from scipy.optimize import lsq_linear
    from scipy.stats import qmc

    d = len(region.centre)
    seen, rng = region.seen, region.rng
    calls = 0

    def evaluate(u: np.ndarray) -> np.ndarray:
        nonlocal calls
        calls += 1
        r = np.asarray(residuals(u), dtype=float)
        if np.all(np.isfinite(r)):  # a failed candidate tells nothing about the residuals' slope
            seen.append((np.clip(u, 0.0, 1.0), r))
        return r

    def inside(lo: np.ndarray, hi: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
        return [(u, r) for u, r in seen if np.all(u >= lo - 1e-12) and np.all(u <= hi + 1e-12)]

    if region.r_centre is None:
        region.r_centre = evaluate(region.centre)
    elif np.all(np.isfinite(region.r_centre)) and not any(np.array_equal(u, region.centre) for u, _ in seen):
        seen.append((region.centre, region.r_centre))  # a design point's residuals, known without a candidate
    idle = 0
    while idle < 100:  # otherwise it ends when the budget is spent (BudgetSpent)
        before = calls
        centre, rho = region.centre, region.rho
        lo, hi = np.maximum(centre - rho, 0.0), np.minimum(centre + rho, 1.0)
        need = region.points_per_model - len(inside(lo, hi))
        if need > 0:
            for u in lo + qmc.LatinHypercube(d=d, seed=rng).random(need) * (hi - lo):
                evaluate(u)
        near = inside(lo, hi)
        better = False
        if len(near) > d:  # enough to fit the model (candidates that failed are not in it)
            u = np.array([p for p, _ in near]) - centre
            coef, *_ = np.linalg.lstsq(np.column_stack([np.ones(len(u)), u]), np.array([q for _, q in near]),
                                       rcond=None)
            b, jac = coef[0], coef[1:].T  # the smoothed residuals at the centre and their slope, per box width
            step = lsq_linear(jac, -b, bounds=(lo - centre, hi - centre)).x
            if np.max(np.abs(step)) > 1e-9:
                r_trial = evaluate(centre + step)
                better = objective_of(r_trial) < objective_of(region.r_centre)
        if better:
            region.rho = min(2.0 * rho, RHO_MAX) if np.any(np.abs(step) >= 0.99 * rho) else rho
            region.centre, region.r_centre = np.clip(centre + step, 0.0, 1.0), r_trial
        elif len(near) <= d:  # too many failed around here to fit a model: look wider, up to the whole box
            region.rho = min(2.0 * rho, 1.0)
            if not seen:
                region.points_per_model += 1  # a new draw each time, so the budget is spent, not the loop
        else:
            region.rho = 0.5 * rho
            if region.rho < RHO_MIN:
                if seen:
                    region.centre, region.r_centre = min(seen, key=lambda s: objective_of(s[1]))
                region.rho, region.points_per_model = RHO_START, region.points_per_model + d
        idle = idle + 1 if calls == before else 0


class _StageSpent(Exception):
    """Raised by a stage's own counter once its share of the budget is spent: ends that stage only."""


def _limited(residuals, share: int):
    """``residuals`` that raises :class:`_StageSpent` after ``share`` candidates."""
    calls = 0

    def limited(u: np.ndarray) -> np.ndarray:
        nonlocal calls
        if calls >= share:
            raise _StageSpent
        calls += 1
        return residuals(u)

    return limited


def starts_apart(candidates, starts: int, separation: float) -> list[tuple[np.ndarray, np.ndarray]]:
    """Up to ``starts`` of ``candidates`` ((u, residuals) pairs), best first, each at least ``separation`` box
    widths (infinity norm) from every one taken before it; failed candidates are never taken."""
    ranked = sorted(((objective_of(r), i) for i, (_, r) in enumerate(candidates)))
    chosen: list[tuple[np.ndarray, np.ndarray]] = []
    for j, i in ranked:
        u = np.clip(np.asarray(candidates[i][0], float), 0.0, 1.0)
        if j >= FAILED or len(chosen) == starts:
            break
        if all(np.max(np.abs(u - c)) >= separation for c, _ in chosen):
            chosen.append((u, np.asarray(candidates[i][1], float)))
    return chosen


def _multi_start(residuals, start: np.ndarray, remaining: int, seed: int, candidates) -> None:
    d = len(start)
    pool = [(np.asarray(u, float), np.asarray(r, float)) for u, r in candidates]
    if not pool:
        pool = [(np.clip(start, 0.0, 1.0), np.asarray(residuals(start), float))]
        remaining -= 1
    # a start needs a model (2d + 1 candidates) and a trial in its share to learn anything about its basin
    stage = int(MULTI_FIRST_STAGE * remaining)
    starts = starts_apart(pool, min(MULTI_STARTS, stage // (2 * d + 2)), MULTI_SEPARATION)
    if len(starts) <= 1:
        best = starts[0] if starts else min(pool, key=lambda c: objective_of(c[1]))
        _trust_region(residuals, _Region.at(best[0], seed, best[1]))
        return
    regions = [_Region.at(u, (seed, k), r) for k, (u, r) in enumerate(starts)]
    share = stage // len(regions)
    for region in regions:
        try:
            _trust_region(_limited(residuals, share), region)
        except _StageSpent:
            pass
    # the race is decided by measurement: the region holding the best candidate goes on from that candidate,
    # keeping its models' candidates, its half-width and its random stream
    winner = min(regions, key=lambda g: g.best())
    if winner.seen:
        winner.centre, winner.r_centre = min(winner.seen, key=lambda s: objective_of(s[1]))
    _trust_region(residuals, winner)
