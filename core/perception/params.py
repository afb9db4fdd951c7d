"""Per-press interaction parameters as the haptic memory takes them: rows of ``[n1, n2, a1, a2]`` and material labels.

The parameters stay in the units of the fit (:data:`palpate.core.perception.fit.FIT_UNITS`: c_P in counts, c_D in
mm, c_A in mm^2, as in the seed's tables).
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from palpate.core.errors import ValidationError

PARAM_COLUMNS = ("n1", "n2", "a1", "a2")
#: Largest parameter magnitude accepted. Squared Mahalanobis distances of inputs beyond this could overflow
#: float64, and no 3/2-power fit produces such values.
MAX_ABS_PARAM = 1e100


def as_params(params, what: str = "params") -> np.ndarray:
    """Return params as a finite float (n, 4) array or raise ValidationError naming the bad entry."""
    try:
        arr = np.asarray(params, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValidationError(f"{what} must be numbers [n1, n2, a1, a2], got {type(params).__name__}: {exc}") from None
    if arr.ndim == 1 and arr.shape[0] == 4:
        arr = arr[None, :]
    if arr.ndim != 2 or arr.shape[1] != 4:
        raise ValidationError(f"{what} must have shape (n, 4) with columns n1, n2, a1, a2; got shape {arr.shape}")
    if arr.shape[0] == 0:
        raise ValidationError(f"{what} is empty; expected at least one row [n1, n2, a1, a2]")
    # NaN fails the comparison too, so one reduction checks every entry; the culprit is looked for only then.
    if not np.abs(arr).max() <= MAX_ABS_PARAM:
        bad = ~np.isfinite(arr) | (np.abs(arr) > MAX_ABS_PARAM)
        row, col = (int(i) for i in np.argwhere(bad)[0])
        raise ValidationError(
            f"{what}[{row}] column '{PARAM_COLUMNS[col]}' is {arr[row, col]!r}; expected a finite number "
            f"with magnitude <= {MAX_ABS_PARAM:g}"
        )
    return arr


def as_labels(labels, n: int) -> list[str]:
    if isinstance(labels, str):
        raise ValidationError("labels must be a sequence of material names, one per row, not a single string")
    try:
        out = list(labels)
    except TypeError:
        raise ValidationError(f"labels must be a sequence of material names, got {type(labels).__name__}") from None
    if len(out) != n:
        raise ValidationError(f"labels has {len(out)} entries but params has {n} rows; expected one label per row")
    for i, lab in enumerate(out):
        if not isinstance(lab, str) or not lab.strip():
            raise ValidationError(f"labels[{i}] is {lab!r}; expected a non-empty material name")
    return [lab.strip() for lab in out]


def unique_in_order(names: Iterable[str]) -> list[str]:
    return list(dict.fromkeys(names))
