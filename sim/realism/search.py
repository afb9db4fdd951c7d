"""The searches of ``palpate calibrate realism``: where a fit goes after its start and Latin-hypercube design.

Both work in box positions u in [0, 1]^d (:class:`~palpate.sim.realism.calibrate.FreeParameter`) on a candidate
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
  each model than the last time.
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


class BudgetSpent(Exception):
    """Raised by a candidate evaluation once the budget is spent: ends whichever search asked."""


def run_search(search: str, residuals: Callable[[np.ndarray], np.ndarray], start: np.ndarray, remaining: int,
               seed: int = 0) -> None:
    """Spend up to ``remaining`` candidates improving on ``start`` (box positions) with ``search``.

    ``residuals(u)``: the residual vector of the candidate at u (its squared sum is the objective); it records every
    candidate itself and raises :class:`BudgetSpent` when the budget is gone, which ends the search quietly. The
    caller takes the best candidate from its own record. ``seed``: the trust region's sampling (deterministic).
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
    minimize(lambda u: float(np.sum(residuals(u) ** 2)), start, method="Nelder-Mead", bounds=[(0.0, 1.0)] * d,
             options={"maxfev": remaining, "initial_simplex": simplex, "xatol": 1e-3, "fatol": 1e-3})


def _trust_region(residuals, start: np.ndarray, seed: int) -> None:
    from scipy.optimize import lsq_linear
    from scipy.stats import qmc

    d = len(start)
    rng = np.random.default_rng(seed)
    seen: list[tuple[np.ndarray, np.ndarray]] = []

    def evaluate(u: np.ndarray) -> np.ndarray:
        r = np.asarray(residuals(u), dtype=float)
        seen.append((np.clip(u, 0.0, 1.0), r))
        return r

    centre, r_centre, rho = np.clip(start, 0.0, 1.0), evaluate(start), RHO_START
    points_per_model, idle = 2 * d + 1, 0
    while idle < 100:  # otherwise it ends when the budget is spent (BudgetSpent)
        spent = len(seen)
        lo, hi = np.maximum(centre - rho, 0.0), np.minimum(centre + rho, 1.0)
        inside = [(u, r) for u, r in seen if np.all(u >= lo - 1e-12) and np.all(u <= hi + 1e-12)]
        need = points_per_model - len(inside)
        if need > 0:
            points = qmc.LatinHypercube(d=d, seed=rng).random(need)
            inside += [(u, evaluate(u)) for u in lo + points * (hi - lo)]
        u = np.array([p for p, _ in inside]) - centre
        coef, *_ = np.linalg.lstsq(np.column_stack([np.ones(len(u)), u]), np.array([q for _, q in inside]),
                                   rcond=None)
        b, jac = coef[0], coef[1:].T  # the smoothed residuals at the centre and their slope, per box width
        step = lsq_linear(jac, -b, bounds=(lo - centre, hi - centre)).x
        better = False
        if np.max(np.abs(step)) > 1e-9:
            r_trial = evaluate(centre + step)
            better = float(np.sum(r_trial ** 2)) < float(np.sum(r_centre ** 2))
        if better:
            rho = min(2.0 * rho, RHO_MAX) if np.any(np.abs(step) >= 0.99 * rho) else rho
            centre, r_centre = np.clip(centre + step, 0.0, 1.0), r_trial
        else:
            rho *= 0.5
            if rho < RHO_MIN:
                centre, r_centre = min(seen, key=lambda s: float(np.sum(s[1] ** 2)))
                rho, points_per_model = RHO_START, points_per_model + d
        idle = idle + 1 if len(seen) == spent else 0
