"""The layered memory (:mod:`palpate.core.perception.layered_memory`) as a scikit-learn classifier over presses.

``X`` is a sequence of perceived presses (:class:`~palpate.core.perception.press.PressResult`), not a table: a layer
is judged by a fit to the press cut at that layer's depth, so the estimator needs each press's samples. scikit-learn
indexes such an ``X`` as a list, so ``clone``, ``cross_val_score`` and ``GridSearchCV`` work with it unchanged.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.perception.estimator import ClassifierParams, check_fitted
from palpate.core.perception.layered_memory import LayeredMemory, train_layered_memory
from palpate.core.perception.memory import DEFAULT_MIN_EIG, HapticMemory
from palpate.core.perception.params import as_labels, unique_in_order


class LayeredMemoryClassifier(ClassifierParams):
    """Judges a press by its deepest voxel layer (seed 001: deeper layers discriminate better).

    Args:
        cell: voxel side, m (the depth of one layer).
        n_layers: layers of a column.
        materials: material names in column order (None: from the labels, in order of first appearance).
        min_eig, ddof: the haptic memories' settings (:class:`~palpate.core.perception.memory.HapticMemory`).

    After :meth:`fit`: ``layered_`` (the :class:`~palpate.core.perception.layered_memory.LayeredMemory`: a
    whole-press memory and one judge per layer) and ``materials``.
    """

    _PARAMS = (("cell", "cell"), ("n_layers", "n_layers"), ("materials", "materials_arg"), ("min_eig", "min_eig"),
               ("ddof", "ddof"))

    def __init__(self, cell: float = 0.0025, n_layers: int = 6, materials: Sequence[str] | None = None,
                 min_eig: float = DEFAULT_MIN_EIG, ddof: int = 0):
        self.cell = cell
        self.n_layers = n_layers
        self.materials_arg = materials
        self.min_eig = min_eig
        self.ddof = ddof
        self.materials: list[str] = []
        self.layered_: LayeredMemory | None = None

    @property
    def fitted(self) -> bool:
        """True once :meth:`fit` has run."""
        return self.layered_ is not None

    def fit(self, X: Sequence, labels: Sequence[str]) -> LayeredMemoryClassifier:
        """Train the whole-press memory on the presses' fits and a judge per layer on the presses cut at its depth.

        Args:
            X: perceived presses (PressResult); presses without a fit are left out of the whole-press memory.
            labels: one material name per press.
        """
        presses = _presses(X)
        labs = as_labels(labels, len(presses))
        materials = list(self.materials_arg) if self.materials_arg is not None else unique_in_order(labs)
        fitted = [i for i, r in enumerate(presses) if r.fit is not None]
        full = HapticMemory(materials, min_eig=self.min_eig, ddof=self.ddof).fit(
            np.array([presses[i].fit.params for i in fitted]).reshape(-1, 4), [labs[i] for i in fitted])
        training = {m: [r for r, lab in zip(presses, labs, strict=True) if lab == m] for m in materials}
        self.layered_ = train_layered_memory(full, training, float(self.cell), int(self.n_layers))
        self.materials = materials
        return self

    def predict_proba(self, X: Sequence) -> np.ndarray:
        """Per press, the posterior of the deepest layer it gives evidence for; the whole-press memory's where no
        layer does; the prior where the press has no fit at all. Shape (n, M)."""
        check_fitted(self)
        layered = self.layered_
        out = np.tile(layered.full.prior, (len(X), 1))
        for i, r in enumerate(_presses(X)):
            if r.fit is None:
                continue
            pr = r.press
            posts = [p for p in layered.layer_posteriors(pr.t, pr.c_P, pr.c_A, pr.c_D) if p is not None]
            out[i] = posts[-1] if posts else layered.full.predict_proba(r.fit.params[None, :])[0]
        return out

    def predict(self, X: Sequence) -> list[str]:
        """The most probable material per press."""
        return [self.materials[i] for i in np.argmax(self.predict_proba(X), axis=1)]

    def score(self, X: Sequence, labels: Sequence[str]) -> float:
        """Fraction of presses whose most probable material is the label."""
        predicted = self.predict(X)
        return float(np.mean([p == t for p, t in zip(predicted, as_labels(labels, len(predicted)), strict=True)]))


def _presses(X) -> list:
    presses = list(X)
    for i, r in enumerate(presses):
        if not (hasattr(r, "fit") and hasattr(r, "press")):
            raise ValidationError(f"X[{i}] is a {type(r).__name__}; the layered memory judges perceived presses "
                                  "(PressResult, from perceive_press)")
    if not presses:
        raise ValidationError("X is empty; expected one perceived press per label")
    return presses
