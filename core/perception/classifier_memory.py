"""Any classifier with ``fit(X, y)`` and ``predict_proba(X)`` (a scikit-learn estimator, a pipeline, one's own) as
the haptic memory of a run: :class:`ClassifierMemory` gives it what the run loop asks of a memory (materials in the
scenario's order, a posterior per press whose columns follow them, JSON without pickle, leave-one-out).

A press's features are the rows of ``X`` (by default its fitted [n1, n2, a1, a2]; a feature extractor may give
others, :mod:`palpate.core.perception.feature_extractors`). The posterior's columns are the memory's materials; a
material the classifier never saw in training gets probability 0 (the map clamps it to its floor). The wrapped
estimator is copied before it is fitted (``estimator_``), so the one given stays unfitted, as scikit-learn's
meta-estimators do.
"""

from __future__ import annotations

import copy
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Protocol

import numpy as np

from palpate.core import __version__, files, plugins
from palpate.core.errors import ValidationError
from palpate.core.perception.crossval import CrossValidation, crossval_result
from palpate.core.perception.estimator import ClassifierParams, check_fitted
from palpate.core.perception.feature_extractors import extractor_name, press_features
from palpate.core.perception.memory import HapticMemory
from palpate.core.perception.params import as_labels, unique_in_order

#: The name a run records for palpate's own classifier, the haptic memory.
HAPTIC_MEMORY = plugins.CLASSIFIERS.builtin[0]
FORMAT_NAME = "palpate.classifier_memory"
FORMAT_VERSION = 1


class ClassifierFactory(Protocol):
    """A classifier plugin (entry-point group ``palpate.classifiers``, ``palpate.register_classifier``): called with
    no arguments, it returns a new unfitted classifier with ``fit(X, y)``, ``predict_proba(X)`` and, once fitted,
    ``classes_`` (a scikit-learn classifier class such as ``LogisticRegression`` is one as it is)."""

    def __call__(self):  # pragma: no cover - protocol
        ...


def classifier_for(classifier: str, features: str, materials: Sequence[str]) -> tuple[ClassifierMemory | None,
                                                                                      dict[str, str]]:
    """The classifier memory a run trains for the named classifier and feature extractor (None: palpate's haptic
    memory over the power-law features, the run's own path), and where each name came from."""
    found_c = plugins.resolve(plugins.CLASSIFIERS, classifier)
    found_f = plugins.resolve(plugins.FEATURES, features)
    origins = {"classifier": found_c.origin, "features": found_f.origin}
    if found_c.obj is None and found_f.obj is None:
        return None, origins
    return build_classifier_memory(found_c, found_f, materials), origins


def build_classifier_memory(classifier: plugins.Plugin, features: plugins.Plugin,
                            materials: Sequence[str]) -> ClassifierMemory:
    """A new unfitted classifier memory from resolved plugins (a built-in's ``obj`` is None: the haptic memory, the
    power-law features), as a run builds it and a replay builds it again from the run's ``memory.json``."""
    estimator = HapticMemory(list(materials)) if classifier.obj is None else classifier.obj()
    extractor = features.obj
    # the file records the extractor's name, and a replay resolves that name: it must be the registered one
    if extractor is not None and getattr(extractor, "name", None) != features.name:
        extractor = _Named(features.name, extractor)
    return ClassifierMemory(estimator, list(materials), classifier.name, extractor)


class _Named:
    """An extractor under the name it was registered by (a plain function's ``__name__``, or its own ``name``, may
    differ)."""

    def __init__(self, name: str, extract):
        self.name, self.extract = name, extract

    def __call__(self, result):
        return self.extract(result)


def as_features(X, where: str = "X") -> np.ndarray:
    """``X`` as a finite (n, d) float array; ValidationError naming ``where`` otherwise."""
    try:
        x = np.asarray(X, dtype=float)
    except (TypeError, ValueError):
        raise ValidationError(f"{where} must be numbers, one row per press") from None
    if x.ndim == 1:
        x = x[None, :]
    if x.ndim != 2 or x.shape[0] == 0 or x.shape[1] == 0:
        raise ValidationError(f"{where} must be a non-empty (presses, features) array, got shape {x.shape}")
    if not np.all(np.isfinite(x)):
        row = int(np.argwhere(~np.isfinite(x))[0, 0])
        raise ValidationError(f"{where}[{row}] is not finite: {x[row].tolist()}")
    return x


class ClassifierMemory(ClassifierParams):
    """A classifier standing in for the haptic memory.

    Args:
        estimator: unfitted, with ``fit(X, y)``, ``predict_proba(X)`` and ``classes_`` after fitting (any
            scikit-learn classifier or pipeline ending in one).
        materials: the material names in column order; None takes them from the training labels in order of
            first appearance.
        name: what the run records as its classifier (default: the estimator's class name).
        features: the per-press feature extractor a run applies to each perceived press to get its row of ``X``
            (:mod:`palpate.core.perception.feature_extractors`); None: the fitted [n1, n2, a1, a2].

    After :meth:`fit`: ``estimator_`` (the fitted copy), ``materials``, ``training_X`` (n, d), ``training_labels``.
    """

    _PARAMS = (("estimator", "estimator"), ("materials", "materials_arg"), ("name", "name"), ("features", "features"))

    def __init__(self, estimator, materials: Sequence[str] | None = None, name: str | None = None, features=None):
        self.estimator = estimator
        self.materials_arg = materials
        self.name = name
        self.features = features
        self.materials: list[str] = []
        self.estimator_ = None
        self.training_X: np.ndarray | None = None
        self.training_labels: list[str] = []
        self._columns: np.ndarray | None = None

    @property
    def fitted(self) -> bool:
        """True once :meth:`fit` has run."""
        return self.estimator_ is not None

    @property
    def label(self) -> str:
        """The name a run records: ``name``, else the estimator's class name."""
        return self.name or type(self.estimator).__name__

    def press_features(self, result) -> np.ndarray | None:
        """The row of ``X`` for one perceived press (None when it gives none, e.g. it could not be fitted)."""
        return press_features(result, self.features)

    def fit(self, X, labels: Sequence[str]) -> ClassifierMemory:
        """Fit a copy of the estimator to per-press features ``X`` (n, d) and material names ``labels``."""
        for method in ("fit", "predict_proba"):
            if not callable(getattr(self.estimator, method, None)):
                raise ValidationError(f"classifier {self.label}: has no {method}() method; a memory needs fit(X, y) "
                                      "and predict_proba(X)")
        x = as_features(X)
        labs = as_labels(labels, x.shape[0])
        materials = list(self.materials_arg) if self.materials_arg is not None else unique_in_order(labs)
        unknown = sorted(set(labs) - set(materials))
        if unknown:
            raise ValidationError(f"labels name material(s) {unknown} not in materials {materials}")
        est = copy.deepcopy(self.estimator)
        est.fit(x, np.asarray(labs))
        classes = [str(c) for c in getattr(est, "classes_", ())]
        if not classes or not set(classes) <= set(materials):
            raise ValidationError(f"classifier {self.label}: classes_ {classes} after fitting are not among the "
                                  f"materials {materials}")
        self.estimator_, self.materials = est, materials
        self._columns = np.array([materials.index(c) for c in classes])
        self.training_X, self.training_labels = x.copy(), list(labs)
        return self

    def predict_proba(self, X, features: str = "both") -> np.ndarray:
        """Posterior over the materials, (n, M), rows summing to 1 (``features`` is accepted for the run loop's
        sake and ignored: the feature extractor decided what ``X`` holds)."""
        check_fitted(self)
        x = as_features(X)
        if x.shape[1] != self.training_X.shape[1]:
            raise ValidationError(f"X has {x.shape[1]} features per press; classifier {self.label} was trained on "
                                  f"{self.training_X.shape[1]}")
        p = np.asarray(self.estimator_.predict_proba(x), dtype=float)
        if p.shape != (len(x), len(self._columns)) or not np.all(np.isfinite(p)) or np.any(p < 0):
            raise ValidationError(f"classifier {self.label}: predict_proba gave {p.shape} values (finite, >= 0 "
                                  f"expected, one column per class {len(self._columns)})")
        out = np.zeros((len(x), len(self.materials)))
        out[:, self._columns] = p
        total = out.sum(axis=1, keepdims=True)
        if np.any(total <= 0):
            raise ValidationError(f"classifier {self.label}: predict_proba gave a row of zeros")
        return out / total

    def predict(self, X) -> list[str]:
        """The most probable material per press."""
        return [self.materials[i] for i in np.argmax(self.predict_proba(X), axis=1)]

    def score(self, X, labels: Sequence[str]) -> float:
        """Fraction of presses whose most probable material is the label."""
        predicted = self.predict(X)
        return float(np.mean([p == t for p, t in zip(predicted, as_labels(labels, len(predicted)), strict=True)]))

    def to_dict(self) -> dict:
        """JSON-ready description: the classifier's name and settings (as text), materials and training data.

        Never a pickle: the fitted model is rebuilt by fitting the same classifier to ``training`` again."""
        check_fitted(self)
        params = self.estimator.get_params(deep=False) if hasattr(self.estimator, "get_params") else {}
        return {"format": FORMAT_NAME, "version": FORMAT_VERSION, "palpate_version": __version__,
                "classifier": self.label, "features": extractor_name(self.features), "estimator": repr(self.estimator),
                "params": {k: repr(v) for k, v in params.items()}, "materials": list(self.materials),
                "training": {"X": self.training_X.tolist(), "labels": list(self.training_labels)}}

    def save(self, path: str | Path) -> None:
        """Write :meth:`to_dict` as JSON to ``path``."""
        files.write_text(path, json.dumps(self.to_dict(), indent=1, allow_nan=False) + "\n")

    def crossval(self, X, labels: Sequence[str]) -> CrossValidation:
        """Leave-one-out: each press judged by a copy of this memory fitted to every other press."""
        x = as_features(X)
        labs = as_labels(labels, x.shape[0])
        materials = list(self.materials_arg) if self.materials_arg is not None else unique_in_order(labs)
        post = np.empty((len(x), len(materials)))
        for i in range(len(x)):
            keep = np.arange(len(x)) != i
            held = ClassifierMemory(self.estimator, materials, self.name, self.features).fit(x[keep], [labs[j] for j in
                                                                                      np.flatnonzero(keep)])
            post[i] = held.predict_proba(x[i:i + 1])[0]
        return crossval_result(materials, np.array([materials.index(lab) for lab in labs]), post)
