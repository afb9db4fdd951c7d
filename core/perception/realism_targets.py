"""The realism targets: how one training session's presses compare with a real per-press table.

Per reference material, four targets (docs/realism.md): the session's CV of n1 and of a1 within +-30% of the real
table's, the number of presses of 10 with n2 < 0 within 2 of the real table's, and the leave-one-out mean posterior
of the material itself within its band (Table 6.7: the first reference 0.82 +- 0.06, the others >= 0.95). Each is
checked on one session's presses (10 per material), so it is a statistic of 10 samples: benchmarks/realism_targets.py
applies :func:`check_targets` to simulated seeds, benchmarks/realism_ceiling.py to seeds drawn from a table's own
distribution (what a perfect simulator would hold).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.perception.crossval import leave_one_out
from palpate.core.perception.param_stats import PARAM_INDEX, PressTable, column_stats

#: The four targets of a material, in the column order of :attr:`TargetCheck.held`.
TARGETS = ("cv n1", "cv a1", "n2<0", "loo")
#: A session's CV may be this far from the real one, relatively (+-30%).
CV_TOLERANCE = 0.3
#: Presses of 10 with n2 < 0 a session may have more or fewer than the real table.
NEGATIVE_N2_TOLERANCE = 2.0
#: Leave-one-out self posterior band of the first reference (Table 6.7's 0.82 +- 0.06) and of the others.
FIRST_LOO_BAND = (0.76, 0.88)
OTHER_LOO_BAND = (0.95, 1.0)


def loo_band(index: int) -> tuple[float, float]:
    """The (low, high) band of the leave-one-out self posterior of the reference at ``index`` (0: Material_1)."""
    return FIRST_LOO_BAND if index == 0 else OTHER_LOO_BAND


def negative_difference_per_10(sim, real) -> float:
    """How many more presses of 10 have a negative value in ``sim`` than in ``real`` (1-D arrays of one column),
    rounded to 1e-9 so that counts of 10 compare exactly (10 (0.6 - 0.8) is -2.0000000000000004 in floats)."""
    s, r = np.asarray(sim, dtype=float), np.asarray(real, dtype=float)
    return round(10.0 * (float(np.mean(s < 0)) - float(np.mean(r < 0))), 9)


def loo_self(table: PressTable, materials: Sequence[str], groups: Sequence[np.ndarray] | None = None) -> np.ndarray:
    """(M,) leave-one-out mean posterior of each material itself, as a run computes it on its training presses
    (:func:`~palpate.core.perception.crossval.leave_one_out` on [n1, n2, a1, a2], the memory's defaults).

    ``groups``: per material, one integer per press; presses of one material sharing a group (copies of one press
    in a bootstrap resample) are held out together.
    """
    params = np.vstack([table.of(m)[:, list(PARAM_INDEX)] for m in materials])
    labels = [m for m in materials for _ in range(len(table.of(m)))]
    flat = None
    if groups is not None:
        per = [np.asarray(g, dtype=np.int64).reshape(-1) for g in groups]
        # offset each material's groups so that no group spans two materials
        offset = 1 + max((int(np.max(np.abs(g))) for g in per if len(g)), default=0)
        flat = np.concatenate([g + 2 * i * offset for i, g in enumerate(per)])
    cv = leave_one_out(params, labels, materials=list(materials), groups=flat)
    return np.diag(cv.mean_posterior).copy()


@dataclass(frozen=True)
class TargetCheck:
    """The targets of one session against a real table, per material (rows in ``materials`` order).

    Attributes:
        materials: names, in the references' order (the first has Table 6.7's 0.82 band).
        cv: (M, 2) the session's CV of n1 and of a1.
        real_cv: (M, 2) the real table's.
        negative_n2: (M,) presses of 10 with n2 < 0, the session's less the real table's.
        loo_self: (M,) the session's leave-one-out mean posterior of each material itself.
        held: (M, 4) whether each target of :data:`TARGETS` holds.
    """

    materials: tuple[str, ...]
    cv: np.ndarray
    real_cv: np.ndarray
    negative_n2: np.ndarray
    loo_self: np.ndarray
    held: np.ndarray

    @property
    def cv_ratio(self) -> np.ndarray:
        """(M, 2) session / real CV; inf where the real CV is 0 and the session's is not, 1 where both are 0."""
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = self.cv / self.real_cv
        return np.where((self.cv == 0) & (self.real_cv == 0), 1.0, ratio)

    @property
    def count(self) -> int:
        """How many of the M x 4 targets hold."""
        return int(self.held.sum())


def _cv(values: np.ndarray, what: str) -> float:
    cv = column_stats(values).cv
    if cv is None:
        raise ValidationError(f"{what}: the mean is 0, so the CV is undefined")
    return cv


def check_targets(sim: PressTable, real: PressTable, loo: np.ndarray, materials: Sequence[str]) -> TargetCheck:
    """The realism targets of a session's presses ``sim`` against ``real``, per material of ``materials`` (the
    scenario's references, in order; ``loo`` (M,) their leave-one-out self posteriors in that order).

    A CV target holds when the session's CV is within [0.7, 1.3] times the real one (so, where the real CV is 0,
    only when the session's is 0 too); the n2 target when :func:`negative_difference_per_10` is within +-2; the
    leave-one-out target when the posterior is within :func:`loo_band`.
    """
    names = tuple(materials)
    loo = np.asarray(loo, dtype=float).reshape(-1)
    if loo.shape != (len(names),) or not np.all(np.isfinite(loo)):
        raise ValidationError(f"check_targets: {len(names)} finite leave-one-out posteriors needed, got {loo}")
    cv = np.array([[_cv(sim.of(m)[:, j], f"{m} {c} (session)") for j, c in ((0, "n1"), (3, "a1"))] for m in names])
    real_cv = np.array([[_cv(real.of(m)[:, j], f"{m} {c} (real)") for j, c in ((0, "n1"), (3, "a1"))]
                        for m in names])
    neg = np.array([negative_difference_per_10(sim.of(m)[:, 1], real.of(m)[:, 1]) for m in names])
    # relative closeness written as a product, so that a real CV of 0 needs a session CV of 0 (no 0 / 0)
    cv_ok = np.abs(cv - real_cv) <= CV_TOLERANCE * real_cv * (1.0 + 1e-12)
    bands = np.array([loo_band(i) for i in range(len(names))])
    loo_ok = (bands[:, 0] <= loo) & (loo <= bands[:, 1])
    held = np.column_stack([cv_ok, np.abs(neg) <= NEGATIVE_N2_TOLERANCE, loo_ok])
    return TargetCheck(names, cv, real_cv, neg, loo, held)
