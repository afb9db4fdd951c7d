"""Per-press feature extractors: what a classifier sees of one perceived press.

A feature extractor is any callable ``extract(result) -> 1-D float array | None`` over a
:class:`~palpate.core.perception.press.PressResult` (its press-phase samples ``result.press`` — t s, c_P counts,
c_A m^2, c_D m — and its 3/2-power fits ``result.fit``); None means the press gives no row (it is left out of
training and changes no map cell). It should say its name in a ``name`` attribute (else its ``__name__`` is used)
and may list its columns in ``columns``. Every press of a run must give rows of the same length.

:func:`power_law` is palpate's own: the fitted [n1, n2, a1, a2] of seed 000 (eq. 6.5, 6.6), the haptic memory's input.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.perception.params import PARAM_COLUMNS

#: The name of :func:`power_law` (the default features of a run).
DEFAULT_FEATURES = "power_law"


@runtime_checkable
class FeatureExtractor(Protocol):
    """What a per-press feature extractor is (``palpate.features`` plugins, ``palpate.register_features``)."""

    def __call__(self, result) -> np.ndarray | None:  # pragma: no cover - protocol
        """The press's features, a 1-D float array (units the extractor's own), or None for no row."""
        ...


def power_law(result) -> np.ndarray | None:
    """The fitted interaction parameters [n1, n2, a1, a2] (c_P = n1 c_D^1.5 + n2, c_A = a1 c_D^1.5 + a2: counts,
    m^2 against m), or None when the press could not be fitted."""
    return None if result.fit is None else result.fit.params


power_law.name = DEFAULT_FEATURES
power_law.columns = PARAM_COLUMNS


def extractor_name(extractor) -> str:
    """The name a run records for ``extractor`` (None: the default, :func:`power_law`)."""
    if extractor is None:
        return DEFAULT_FEATURES
    return str(getattr(extractor, "name", None) or getattr(extractor, "__name__", type(extractor).__name__))


def press_features(result, extractor=None) -> np.ndarray | None:
    """The features of one perceived press by ``extractor`` (None: :func:`power_law`), checked: a finite 1-D float
    array, or None. ValidationError naming the extractor for anything else."""
    x = (extractor or power_law)(result)
    if x is None:
        return None
    try:
        x = np.asarray(x, dtype=float)
    except (TypeError, ValueError):
        raise ValidationError(f"feature extractor {extractor_name(extractor)!r} returned {type(x).__name__}; "
                              "expected a 1-D array of numbers or None") from None
    if x.ndim != 1 or x.size == 0 or not np.all(np.isfinite(x)):
        raise ValidationError(f"feature extractor {extractor_name(extractor)!r} returned {x.size} values of shape "
                              f"{x.shape}; expected a non-empty 1-D array of finite numbers, or None")
    return x
