"""Haptic memory: per-material Gaussians over the interaction parameters and the MAP rule (seed 000, sec. 6.6).

Each reference material m gets one 2-D Gaussian over the kinesthetic parameters N = (n1, n2) (eq. 6.13) and one
over the cutaneous parameters A = (a1, a2) (eq. 6.14), learned from the per-press fits of a training session, plus
a prior P(M). The posterior of eq. 6.11 is computed in log space (log-sum-exp), so a press far from every material
still gives a finite posterior; the category is its argmax (MAP, eq. 6.12 / 6.18).

Parameter vectors are always ``[n1, n2, a1, a2]`` (:data:`~palpate.core.perception.params.PARAM_COLUMNS`, the order
of :attr:`palpate.core.perception.fit.PressFit.params`), in the units of the fit; nothing here converts units.

:class:`HapticMemory` is a scikit-learn classifier (duck-typed, :mod:`palpate.core.perception.estimator`: ``clone``,
``cross_val_score`` and ``Pipeline`` work with it; core does not import scikit-learn): the constructor only stores
its settings, :meth:`fit` validates them and learns, ``get_params`` returns them, and predicting before :meth:`fit`
(or :meth:`load`) raises :class:`~palpate.core.errors.NotFittedError`. The Gaussians are factored once, when fitted
or loaded.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from palpate.core import __version__, files
from palpate.core.errors import NotFittedError, ValidationError
from palpate.core.perception.estimator import ClassifierParams
from palpate.core.perception.gaussian import GaussianFactors, regularise_covariance
from palpate.core.perception.memory_file import FEATURES_VERSION, FORMAT_NAME, FORMAT_VERSION, parse_memory, read_json
from palpate.core.perception.params import PARAM_COLUMNS, as_labels, as_params, unique_in_order
from palpate.core.perception.params_table import read_params_csv, rows_to_params

#: Fewest presses per material: a 2-D covariance from two points is always singular.
MIN_SAMPLES = 3
DEFAULT_MIN_EIG = 1e-6
#: The recovery an audit error names: a memory that fails its audit can still be read on purpose.
NO_AUDIT = "to use it anyway: --no-audit on palpate memory show or palpate replay, audit=False in Python"


def _check_settings(materials, min_eig, ddof) -> list[str] | None:
    """Validated constructor settings (called by :meth:`HapticMemory.fit`, as scikit-learn does)."""
    if materials is not None:
        if isinstance(materials, str):
            raise ValidationError("materials must be a sequence of material names, not a single string")
        materials = as_labels(list(materials), len(list(materials)))
        if len(set(materials)) != len(materials):
            raise ValidationError(f"materials has duplicate names: {materials}")
        if not materials:
            raise ValidationError("materials is empty; expected at least one material name")
    if isinstance(min_eig, bool) or not (isinstance(min_eig, (int, float)) and 0.0 < float(min_eig) < 1.0):
        raise ValidationError(f"min_eig must be a number in (0, 1), got {min_eig!r}")
    if isinstance(ddof, bool) or not isinstance(ddof, (int, np.integer)) or ddof not in (0, 1):
        raise ValidationError(f"ddof must be 0 (divide by n) or 1 (divide by n - 1), got {ddof!r}")
    return materials


class HapticMemory(ClassifierParams):
    """Bayesian haptic memory of seed 000 (eq. 6.10-6.14): per material, N(mu_N, Sigma_N) x N(mu_A, Sigma_A) x prior.

    Args:
        materials: material names in the order of the model's columns; None takes them from the training labels
            in order of first appearance.
        prior: P(M): None for uniform, a sequence aligned with ``materials``, or a mapping name -> weight.
            Normalised to sum to 1; zero weights are allowed (that material is then never chosen).
        min_eig: smallest accepted eigenvalue of each covariance relative to its largest, in per-dimension
            standard-deviation units (see :func:`~palpate.core.perception.gaussian.regularise_covariance`). The
            thesis data need no loading.
        ddof: covariance estimator: 0 divides by n (population; reproduces Table 6.6 of seed 000), 1 by n - 1.

    After :meth:`fit`: ``materials`` (list[str]), ``prior`` (M,), ``means_N``, ``means_A`` (M, 2), ``covs_N``,
    ``covs_A`` (M, 2, 2) (regularised, as used), ``regularisation`` ({material: {"N": lam, "A": lam}}, the
    relative diagonal loading applied), ``training_params`` (n, 4) and ``training_labels``; ``classes_`` (the
    materials as an array, scikit-learn's name).
    """

    _PARAMS = (("materials", "materials_arg"), ("prior", "prior_arg"), ("min_eig", "min_eig"), ("ddof", "ddof"),
               ("features", "features"))

    def __init__(self, materials: Sequence[str] | None = None, prior=None, min_eig: float = DEFAULT_MIN_EIG,
                 ddof: int = 0, features: str = "both"):
        self.materials_arg = materials
        self.prior_arg = prior
        self.min_eig = min_eig
        self.ddof = ddof
        # "both", or "kinesthetic": no cutaneous model (presses measured as a force, with no contact area)
        self.features = features
        self.materials: list[str] = []
        self.prior: np.ndarray | None = None
        self.means_N = self.covs_N = self.means_A = self.covs_A = None
        self.regularisation: dict[str, dict[str, float]] = {}
        self.training_params: np.ndarray | None = None
        self.training_labels: list[str] = []
        self._factors_N: GaussianFactors | None = None
        self._factors_A: GaussianFactors | None = None
        self._log_prior: np.ndarray | None = None

    # ---- training -------------------------------------------------------------------------------------------

    def fit(self, params, labels: Sequence[str]) -> HapticMemory:
        """Learn each material's Gaussians from per-press parameters.

        Args:
            params: (n, 4) array, columns [n1, n2, a1, a2], one row per press.
            labels: n material names.

        Returns:
            self. Raises ValidationError for bad settings, non-finite values, wrong shapes, labels outside
            ``materials`` or fewer than :data:`MIN_SAMPLES` presses for a material.
        """
        materials_arg = _check_settings(self.materials_arg, self.min_eig, self.ddof)
        min_eig, ddof = float(self.min_eig), int(self.ddof)
        x = as_params(params)
        labs = as_labels(labels, x.shape[0])
        materials = list(materials_arg) if materials_arg is not None else unique_in_order(labs)
        unknown = sorted(set(labs) - set(materials))
        if unknown:
            raise ValidationError(f"labels name material(s) {unknown} not in materials {materials}")
        lab_idx = np.array([materials.index(lab) for lab in labs])
        counts = np.bincount(lab_idx, minlength=len(materials))
        for m, c in zip(materials, counts, strict=True):
            if c < MIN_SAMPLES:
                raise ValidationError(
                    f"material {m!r} has {c} press(es); at least {MIN_SAMPLES} are needed to learn a 2-D Gaussian"
                )
        prior = _normalise_prior(self.prior_arg, materials)
        fallback = x.var(axis=0)
        means_N, covs_N, means_A, covs_A = [], [], [], []
        reg: dict[str, dict[str, float]] = {}
        for k, m in enumerate(materials):
            xm = x[lab_idx == k]
            mu = xm.mean(axis=0)
            d = xm - mu
            cov4 = d.T @ d / (len(xm) - ddof)
            cN, lamN = regularise_covariance(cov4[:2, :2], min_eig, fallback[:2])
            if self.features == "kinesthetic":  # no cutaneous model: a placeholder never used to judge
                cA, lamA = np.eye(2), 0.0
            else:
                cA, lamA = regularise_covariance(cov4[2:, 2:], min_eig, fallback[2:])
            means_N.append(mu[:2])
            means_A.append(mu[2:])
            covs_N.append(cN)
            covs_A.append(cA)
            reg[m] = {"N": lamN, "A": lamA}
        if self.features not in ("both", "kinesthetic"):
            raise ValidationError(f"features must be 'both' or 'kinesthetic', got {self.features!r}")
        self._install(materials, prior, np.array(means_N), np.array(covs_N), np.array(means_A), np.array(covs_A),
                      reg, x.copy(), labs)
        return self

    def _install(self, materials, prior, means_N, covs_N, means_A, covs_A, reg, t_params, t_labels) -> None:
        """Set the learned state and factor the Gaussians once (every prediction reuses the factors)."""
        self.materials = list(materials)
        self.prior = prior
        self.means_N, self.covs_N, self.means_A, self.covs_A = means_N, covs_N, means_A, covs_A
        self.regularisation = reg
        self.training_params = t_params
        self.training_labels = list(t_labels)
        self._factors_N = GaussianFactors.of(means_N, covs_N)
        self._factors_A = GaussianFactors.of(means_A, covs_A)
        with np.errstate(divide="ignore"):  # a zero prior is allowed and means log P(M) = -inf
            self._log_prior = np.log(prior)

    def fit_presses(self, fits: Sequence, labels: Sequence[str]) -> HapticMemory:
        """Fit from press-fit objects (anything with ``.params`` = [n1, n2, a1, a2], e.g. ``PressFit``)."""
        rows = []
        for i, f in enumerate(fits):
            p = getattr(f, "params", None)
            if p is None:
                raise ValidationError(f"fits[{i}] ({type(f).__name__}) has no .params; expected [n1, n2, a1, a2]")
            p = np.asarray(p, dtype=float).reshape(-1)
            if p.shape != (4,):
                raise ValidationError(f"fits[{i}].params has {p.size} values; expected 4 [n1, n2, a1, a2]")
            rows.append(p)
        if not rows:
            raise ValidationError("fits is empty; expected one press fit per label")
        return self.fit(np.array(rows), labels)

    @classmethod
    def from_table(cls, path_or_rows, **kwargs) -> HapticMemory:
        """Train from a params CSV (see :func:`~palpate.core.perception.params_table.read_params_csv`) or from
        rows (mappings with material,n1,n2,a1,a2). Keyword arguments go to the constructor."""
        if isinstance(path_or_rows, (str, Path)):
            params, labels, _ = read_params_csv(path_or_rows)
        else:
            params, labels = rows_to_params(path_or_rows)
        return cls(**kwargs).fit(params, labels)

    # ---- inference ------------------------------------------------------------------------------------------

    @property
    def fitted(self) -> bool:
        """True once :meth:`fit` or :meth:`load` has given the memory its Gaussians."""
        return self._factors_N is not None

    def _check_fitted(self) -> None:
        if not self.fitted:
            raise NotFittedError("this HapticMemory is not trained yet (not fitted); call fit() or load() first")

    def log_likelihood(self, params, features: str = "both") -> np.ndarray:
        """log P(n | M) + log P(a | M) for every press and material (eq. 6.13, 6.14), shape (n, M); with
        ``features="kinesthetic"`` log P(n | M) alone (a press with no contact area: c_P from a force)."""
        self._check_fitted()
        x = as_params(params)
        if features == "kinesthetic":
            return self._factors_N.log_pdf(x[:, :2])
        if features != "both":
            raise ValidationError(f"features must be 'both' or 'kinesthetic', got {features!r}")
        if self.features == "kinesthetic":
            raise ValidationError("this haptic memory has a kinesthetic model only (trained on presses measured as a "
                                  "force); it cannot judge a press by its contact area too")
        return self._factors_N.log_pdf(x[:, :2]) + self._factors_A.log_pdf(x[:, 2:])

    def predict_log_proba(self, params, features: str = "both") -> np.ndarray:
        """Log posterior log P(M | n, a) (eq. 6.11), shape (n, M), normalised with log-sum-exp (``features``: see
        :meth:`log_likelihood`)."""
        ll = self.log_likelihood(params, features)
        joint = ll + self._log_prior
        out = joint - _logsumexp_rows(joint)
        if math.isnan(float(out.sum())):  # unreachable for validated input; never hand NaN onwards
            row = int(np.argwhere(np.isnan(out))[0, 0])
            raise ValidationError(f"params[{row}]: posterior is not finite; log-likelihoods {ll[row].tolist()}")
        return out

    def predict_proba(self, params, features: str = "both") -> np.ndarray:
        """Posterior P(M | n, a) (eq. 6.11), shape (n, M); each row sums to 1."""
        p = np.exp(self.predict_log_proba(params, features))
        # far from every mean the log-sum-exp's last bits make exp() sum to 1 only within ~1e-10; the rows are
        # probabilities, so they are made to sum to 1
        return p / p.sum(axis=1, keepdims=True)

    def predict(self, params, features: str = "both") -> list[str]:
        """MAP material name per press (eq. 6.12)."""
        idx = np.argmax(self.predict_log_proba(params, features), axis=1)
        return [self.materials[i] for i in idx]

    def index_of(self, labels: Sequence[str]) -> np.ndarray:
        """Column index of each material name; ValidationError for a name the memory does not know."""
        self._check_fitted()
        labels = list(labels) if not isinstance(labels, str) else labels
        labs = as_labels(labels, len(labels))
        lookup = {m: i for i, m in enumerate(self.materials)}
        for i, lab in enumerate(labs):
            if lab not in lookup:
                raise ValidationError(f"labels[{i}] is {lab!r}, not a material of this memory {self.materials}")
        return np.array([lookup[lab] for lab in labs], dtype=int)

    def score(self, params, labels: Sequence[str]) -> float:
        """Fraction of presses whose MAP material equals the label."""
        x = as_params(params)
        truth = self.index_of(as_labels(labels, x.shape[0]))
        return float(np.mean(np.argmax(self.predict_log_proba(x), axis=1) == truth))

    def refit(self) -> HapticMemory:
        """A new memory trained on the stored training data with the same settings (for auditing)."""
        self._check_fitted()
        prior = dict(zip(self.materials, self.prior.tolist(), strict=True))
        return HapticMemory(self.materials, prior, float(self.min_eig), int(self.ddof), self.features).fit(
            self.training_params, self.training_labels
        )

    # ---- files ----------------------------------------------------------------------------------------------

    def to_dict(self) -> dict:
        """The JSON-ready description (format, version, settings, learned parameters, training data)."""
        self._check_fitted()

        doc = {
            "format": FORMAT_NAME,
            "version": FORMAT_VERSION,
            "palpate_version": __version__,
            "param_columns": list(PARAM_COLUMNS),
            "materials": list(self.materials),
            "prior": self.prior.tolist(),
            "ddof": int(self.ddof),
            "min_eig": float(self.min_eig),
            "means_N": self.means_N.tolist(),
            "covs_N": self.covs_N.tolist(),
            "means_A": self.means_A.tolist(),
            "covs_A": self.covs_A.tolist(),
            "regularisation": {m: dict(v) for m, v in self.regularisation.items()},
            "training": {"params": self.training_params.tolist(), "labels": list(self.training_labels)},
        }
        if self.features != "both":  # version 1 files (both models) stay exactly as they were
            doc.update(version=FEATURES_VERSION, features=self.features)
        return doc

    def to_json(self) -> str:
        """Serialise to JSON text (floats round-trip exactly)."""
        import json

        return json.dumps(self.to_dict(), indent=1, allow_nan=False)

    def save(self, path: str | Path) -> None:
        """Write the memory as JSON to ``path``."""
        files.write_text(path, self.to_json() + "\n")

    @classmethod
    def from_dict(cls, doc, source: str = "<memory>", audit: bool = True) -> HapticMemory:
        """Rebuild a memory from :meth:`to_dict` output, validating every key.

        Args:
            doc: the decoded JSON object.
            source: name used in error messages (usually the file path).
            audit: also re-fit the stored training data and require the stored parameters to match it.
        """
        rec = parse_memory(doc, source)
        prior_map = dict(zip(rec.materials, rec.prior.tolist(), strict=True))
        mem = cls(materials=list(rec.materials), prior=prior_map, min_eig=rec.min_eig, ddof=rec.ddof,
                  features=rec.features)
        mem._install(rec.materials, rec.prior, rec.means_N, rec.covs_N, rec.means_A, rec.covs_A, rec.regularisation,
                     rec.training_params, rec.training_labels)
        if audit:
            try:
                ref = mem.refit()
            except ValidationError as exc:
                raise ValidationError(f"{source}: key 'training' cannot be re-fitted: {exc} ({NO_AUDIT})") from None
            for key in ("means_N", "covs_N") if rec.features == "kinesthetic" else ("means_N", "covs_N", "means_A",
                                                                                      "covs_A"):
                if not np.allclose(getattr(ref, key), getattr(rec, key), rtol=1e-9, atol=0.0):
                    raise ValidationError(
                        f"{source}: key '{key}' does not match a re-fit of key 'training' (ddof={rec.ddof}); the "
                        f"file was edited or corrupted ({NO_AUDIT})"
                    )
        return mem

    @classmethod
    def load(cls, path: str | Path, audit: bool = True) -> HapticMemory:
        """Read a memory saved by :meth:`save`; ValidationError naming the file and key for anything wrong."""
        return cls.from_dict(read_json(path), source=str(Path(path)), audit=audit)


def _logsumexp_rows(a: np.ndarray) -> np.ndarray:
    """log sum exp over each row, shape (n, 1): the largest term is kept out of the sum (as scipy does, for
    precision), without scipy's per-call overhead on a handful of materials. Rows hold at least one finite value."""
    a_max = a.max(axis=1, keepdims=True)
    is_max = a == a_max
    rest = np.exp(a - a_max)
    rest[is_max] = 0.0
    rest = rest.sum(axis=1, keepdims=True)
    if np.count_nonzero(is_max) == len(a):  # one largest term per row: log(1) = 0 and rest / 1 = rest
        return np.log1p(rest) + a_max
    n_max = is_max.sum(axis=1, keepdims=True)
    rest /= n_max
    return np.log1p(rest) + np.log(n_max.astype(float)) + a_max


def _normalise_prior(prior, materials: list[str]) -> np.ndarray:
    m = len(materials)
    if prior is None:
        return np.full(m, 1.0 / m)
    if isinstance(prior, Mapping):
        unknown = sorted(set(prior) - set(materials))
        if unknown:
            raise ValidationError(f"prior names material(s) {unknown} not in materials {materials}")
        missing = [name for name in materials if name not in prior]
        if missing:
            raise ValidationError(f"prior lacks material(s) {missing}; give a weight for every material")
        values = [prior[name] for name in materials]
    else:
        values = list(prior)
    try:
        p = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise ValidationError(f"prior must be numbers, got {values!r}") from None
    if p.shape != (m,):
        raise ValidationError(f"prior has {p.size} values but there are {m} materials {materials}")
    if not np.all(np.isfinite(p)) or np.any(p < 0) or p.sum() <= 0:
        raise ValidationError(f"prior must be finite, >= 0 and not all zero; got {p.tolist()}")
    return p / p.sum()
