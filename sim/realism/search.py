"""The searches of ``palpate calibrate realism``: where a fit goes after its start and Latin-hypercube design.

Both work in box positions u in [0, 1]^d (:class:`~palpate.sim.realism.parameters.FreeParameter`) on a candidate
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
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from palpate.core.errors import ValidationError

#: The searches :func:`run_search` knows.
SEARCHES = ("nelder-mead", "trust-region")
#: The trust region's first half-width, in box widths (the Nelder-Mead simplex spans the same), its largest and the
#: smallest before a restart: below ~0.02 box widths the objective's steps are all a model would see.
RHO_START, RHO_MAX, RHO_MIN = 0.15, 0.5, 0.02
#: Objective of a candidate whose presses could not be simulated or fitted (residuals NaN): a wall, not a number to
#: descend; the trust region leaves such candidates out of its models.
FAILED = 1e6


def objective_of(residuals: np.ndarray) -> float:
    """The objective of a residual vector: its sum of squares, :data:`FAILED` when any residual is not finite."""
    r = np.asarray(residuals, dtype=float)
    return float(np.sum(r ** 2)) if np.all(np.isfinite(r)) else FAILED


class BudgetSpent(Exception):
    """Raised by a candidate evaluation once the budget is spent: ends whichever search asked."""


def run_search(search: str, residuals: Callable[[np.ndarray], np.ndarray], start: np.ndarray, remaining: int,
               seed: int = 0) -> None:
    """Spend up to ``remaining`` candidates improving on ``start`` (box positions) with ``search``.

    ``residuals(u)``: the residual vector of the candidate at u (:func:`objective_of` is the objective; NaN: the
    candidate failed); it records every candidate itself and raises :class:`BudgetSpent` when the budget is gone,
    which ends the search quietly. The caller takes the best candidate from its own record. ``seed``: the trust
    region's sampling (deterministic).
    """
    if search not in SEARCHES:
        raise ValidationError(f"unknown search {search!r}; known: {', '.join(SEARCHES)}")
    if remaining <= 0:
        return
    try:
        if search == "nelder-mead":
            _nelder_mead(residuals, np.asarray(start, float), remaining)
        else:
            _trust_region(residuals, np.asarray(start, float), seed)
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


def _trust_region(residuals, start: np.ndarray, seed: int) -> None:
    from scipy.optimize import lsq_linear
    from scipy.stats import qmc

    d = len(start)
    rng = np.random.default_rng(seed)
    seen: list[tuple[np.ndarray, np.ndarray]] = []  # the candidates that did not fail
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

    centre, rho = np.clip(start, 0.0, 1.0), RHO_START
    r_centre = evaluate(centre)
    points_per_model, idle = 2 * d + 1, 0
    while idle < 100:  # otherwise it ends when the budget is spent (BudgetSpent)
        before = calls
        lo, hi = np.maximum(centre - rho, 0.0), np.minimum(centre + rho, 1.0)
        need = points_per_model - len(inside(lo, hi))
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
                better = objective_of(r_trial) < objective_of(r_centre)
        if better:
            rho = min(2.0 * rho, RHO_MAX) if np.any(np.abs(step) >= 0.99 * rho) else rho
            centre, r_centre = np.clip(centre + step, 0.0, 1.0), r_trial
        elif len(near) <= d:  # too many failed around here to fit a model: look wider, up to the whole box
            rho = min(2.0 * rho, 1.0)
            if not seen:
                points_per_model += 1  # a new draw each time, so the budget is spent, not the loop
        else:
            rho *= 0.5
            if rho < RHO_MIN:
                if seen:
                    centre, r_centre = min(seen, key=lambda s: objective_of(s[1]))
                rho, points_per_model = RHO_START, points_per_model + d
        idle = idle + 1 if calls == before else 0
