"""scikit-learn's estimator protocol, met by duck typing: palpate's classifiers work with ``sklearn.base.clone``,
``cross_val_score``, ``GridSearchCV`` and ``Pipeline`` without core importing scikit-learn.

scikit-learn finds what an estimator is from four things, all given here:

- ``get_params`` / ``set_params`` over the constructor's parameters, and nothing else (``clone`` rebuilds an
  estimator as ``type(est)(**est.get_params(deep=False))`` and checks every value came back as the same object);
- ``classes_`` and ``__sklearn_is_fitted__`` once fitted;
- ``__sklearn_tags__`` (scikit-learn >= 1.6 asks every estimator for its tags: a classifier's tags make
  ``cross_val_score`` stratify its folds). The tags are scikit-learn's own dataclasses, so that method imports
  scikit-learn: only scikit-learn ever calls it, and then it is installed;
- ``_estimator_type = "classifier"`` (what scikit-learn before 1.6 read instead of tags).
"""

from __future__ import annotations

import numpy as np

from palpate.core.errors import NotFittedError, ValidationError


class ClassifierParams:
    """Mixin: scikit-learn's parameter and tag protocol for a classifier whose constructor stores its settings.

    A subclass lists ``_PARAMS``: (constructor parameter, attribute it is stored in), in signature order, and has a
    ``fitted`` property and a ``materials`` list (the classes, in column order of ``predict_proba``).
    """

    _PARAMS: tuple[tuple[str, str], ...] = ()
    _estimator_type = "classifier"

    def get_params(self, deep: bool = True) -> dict:
        """The constructor's parameters (with ``deep``, also ``name__param`` of any estimator among them)."""
        out = {}
        for name, attr in self._PARAMS:
            value = getattr(self, attr)
            out[name] = value
            if deep and hasattr(value, "get_params") and not isinstance(value, type):
                out.update({f"{name}__{k}": v for k, v in value.get_params(deep=True).items()})
        return out

    def set_params(self, **params):
        """Set constructor parameters (``name__param`` reaches into a nested estimator); returns self."""
        attrs = dict(self._PARAMS)
        nested: dict[str, dict] = {}
        for key, value in params.items():
            name, _, sub = key.partition("__")
            if name not in attrs:
                raise ValidationError(f"{type(self).__name__} has no parameter {name!r}; its parameters: "
                                      f"{', '.join(attrs)}")
            if sub:
                nested.setdefault(name, {})[sub] = value
            else:
                setattr(self, attrs[name], value)
        for name, sub_params in nested.items():
            getattr(self, attrs[name]).set_params(**sub_params)
        return self

    def __sklearn_is_fitted__(self) -> bool:
        return bool(self.fitted)

    @property
    def classes_(self) -> np.ndarray:
        """The material names, in the column order of ``predict_proba`` (scikit-learn's ``classes_``)."""
        if not self.fitted:
            # AttributeError, as scikit-learn's fitted attributes do before fit (hasattr(est, "classes_") is False)
            raise AttributeError(f"{type(self).__name__} is not fitted yet, so it has no classes_")
        return np.asarray(self.materials)

    def __sklearn_tags__(self):
        from sklearn.utils import ClassifierTags, InputTags, Tags, TargetTags  # only scikit-learn calls this

        return Tags(estimator_type="classifier", target_tags=TargetTags(required=True),
                    classifier_tags=ClassifierTags(), input_tags=InputTags(), transformer_tags=None,
                    regressor_tags=None)

    def __repr__(self) -> str:
        args = ", ".join(f"{name}={getattr(self, attr)!r}" for name, attr in self._PARAMS)
        return f"{type(self).__name__}({args})"


def check_fitted(estimator) -> None:
    """NotFittedError naming the estimator unless it is fitted."""
    if not estimator.fitted:
        raise NotFittedError(f"this {type(estimator).__name__} is not trained yet (not fitted); call fit() first")
