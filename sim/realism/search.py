"""The searches of ``palpate calibrate realism``: where a fit goes after its start and Latin-hypercube design.

Both work in box positions u in [0, 1]^d (:class:`~palpate.sim.realism.calibrate.FreeParameter`) on a candidate
evaluation that simulates the tuning seeds with common random numbers, so the objective is a deterministic (if not
smooth) function of u. Each simulated candidate costs the same, so the budget counts candidates, whichever search
asks for them.

- ``nelder-mead``: the simplex from the best design point (derivative-free, robust to the objective's small
  steps, but it walks: with five or more parameters it stalls far above the objective's floor long before the
  budget is spent).
- ``least-squares``: a trust-region Gauss-Newton step on the residual vector ((sim - real) / tolerance per moment),
  its Jacobian from forward differences of ``step`` box widths (scipy's ``least_squares``, method ``trf``
  within the box). The residuals' structure is what the moments method has: each statistic is a nearly linear function
  of the parameters over a box width, which the Gauss-Newton model uses and the simplex does not.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from palpate.core.errors import ValidationError

#: The searches :func:`run_search` knows.
SEARCHES = ("nelder-mead", "least-squares")
#: Finite-difference step of the least-squares search, in box widths: the moments' Jacobian is measured with this
#: step (benchmarks/realism_identifiability.py); a smaller one sees the steps a press's fit takes, not the slope.
STEP = 0.05


class BudgetSpent(Exception):
    """Raised by a candidate evaluation once the budget is spent: ends whichever search asked."""


def run_search(search: str, residuals: Callable[[np.ndarray], np.ndarray], start: np.ndarray, remaining: int,
               step: float = STEP) -> None:
    """Spend up to ``remaining`` candidates improving on ``start`` (box positions) with ``search``.

    ``residuals(u)``: the residual vector of the candidate at u (its squared sum is the objective); it records every
    candidate itself and raises :class:`BudgetSpent` when the budget is gone, which ends the search quietly. The
    caller takes the best candidate from its own record.
    """
    if search not in SEARCHES:
        raise ValidationError(f"unknown search {search!r}; known: {', '.join(SEARCHES)}")
    if remaining <= 0:
        return
    try:
        if search == "nelder-mead":
            _nelder_mead(residuals, np.asarray(start, float), remaining)
        else:
            _least_squares(residuals, np.asarray(start, float), step)
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


def _least_squares(residuals, start: np.ndarray, step: float) -> None:
    from scipy.optimize import least_squares

    if not 0.0 < step < 0.5:
        raise ValidationError(f"the least-squares search's step must be in (0, 0.5) box widths, got {step}")

    def jacobian(u: np.ndarray) -> np.ndarray:
        # forward differences of a fixed step in box widths, turned inwards at the box's upper side (scipy's own
        # steps are relative to u, i.e. vanish near a box's lower end)
        r0 = residuals(u)
        cols = []
        for i in range(len(u)):
            h = step if u[i] + step <= 1.0 else -step
            cols.append((residuals(u + h * np.eye(len(u))[i]) - r0) / h)
        return np.column_stack(cols)

    least_squares(residuals, np.clip(start, 0.0, 1.0), jac=jacobian, bounds=(0.0, 1.0), method="trf", x_scale=1.0,
                  max_nfev=10_000)
