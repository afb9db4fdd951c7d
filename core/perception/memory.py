"""Haptic memory: per-material Gaussians over the interaction parameters and the MAP rule (seed 000, sec. 6.6).

Each reference material m gets one 2-D Gaussian over the kinesthetic parameters N = (n1, n2) (eq. 6.13) and one
over the cutaneous parameters A = (a1, a2) (eq. 6.14), learned from the per-press fits of a training session, plus
a prior P(M). The posterior of eq. 6.11 is computed in log space (log-sum-exp), so a press far from every material
still gives a finite posterior; the category is its argmax (MAP, eq. 6.12 / 6.18).

Parameter vectors are always ``[n1, n2, a1, a2]`` (the order of
:attr:`palpate.core.perception.fit.PressFit.params`). The interaction parameters stay in the units of the fit
(:data:`palpate.core.perception.fit.FIT_UNITS`: c_P in counts, c_D in mm, c_A in mm^2, as in the seed's tables);
nothing here converts units.

Memories are stored as versioned JSON holding the learned parameters *and* the training data, so a stored memory
can be re-fitted and audited; nothing is ever pickled.
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.special import logsumexp

from palpate.core.errors import ValidationError

PARAM_COLUMNS = ("n1", "n2", "a1", "a2")
FORMAT_NAME = "palpate.haptic_memory"
FORMAT_VERSION = 1
#: Fewest presses per material: a 2-D covariance from two points is always singular.
MIN_SAMPLES = 3
#: Largest parameter magnitude accepted. Squared Mahalanobis distances of inputs beyond this could overflow
#: float64, and no 3/2-power fit produces such values.
MAX_ABS_PARAM = 1e100
DEFAULT_MIN_EIG = 1e-6


# --------------------------------------------------------------------------------------------------------------
# input validation


def _as_params(params, what: str = "params") -> np.ndarray:
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
    bad = ~np.isfinite(arr) | (np.abs(arr) > MAX_ABS_PARAM)
    if bad.any():
        row, col = (int(i) for i in np.argwhere(bad)[0])
        raise ValidationError(
            f"{what}[{row}] column '{PARAM_COLUMNS[col]}' is {arr[row, col]!r}; expected a finite number "
            f"with magnitude <= {MAX_ABS_PARAM:g}"
        )
    return arr


def _as_labels(labels, n: int) -> list[str]:
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


def _unique_in_order(names: Iterable[str]) -> list[str]:
    return list(dict.fromkeys(names))


# --------------------------------------------------------------------------------------------------------------
# Gaussian pieces


def regularise_covariance(cov: np.ndarray, min_eig: float, fallback_var: np.ndarray) -> tuple[np.ndarray, float]:
    """Load the diagonal of a covariance just enough that it is well conditioned relative to each dimension's scale.

    The covariance is looked at in units of each dimension's own standard deviation (its correlation matrix), so
    the test does not depend on whether n1 is in the hundreds and n2 in the units. If the smallest eigenvalue of
    that matrix is below ``min_eig`` times the largest, the smallest relative loading ``lam`` is added:
    ``cov + lam * diag(scale**2)``, which makes the ratio exactly ``min_eig``.

    Args:
        cov: (d, d) symmetric positive semi-definite covariance.
        min_eig: smallest accepted eigenvalue ratio (1 / largest accepted condition number), in (0, 1).
        fallback_var: (d,) variance to use as a dimension's scale where its own variance is zero (e.g. the
            variance of that column over the whole training set).

    Returns:
        (regularised covariance, lam); lam = 0.0 when nothing was added.
    """
    var = np.diag(cov).copy()
    scale2 = np.where(var > 0, var, fallback_var)
    if np.any(scale2 <= 0) or not np.all(np.isfinite(scale2)):
        raise ValidationError("cannot regularise a covariance: a parameter is constant over all the training data")
    s = np.sqrt(scale2)
    corr = cov / np.outer(s, s)
    eig = np.linalg.eigvalsh(corr)
    e_min, e_max = float(eig[0]), float(eig[-1])
    if e_max <= 0:
        # Identical presses: no spread was observed at all, so any loading is "the smallest"; take min_eig.
        return cov + min_eig * np.diag(scale2), float(min_eig)
    if e_min >= min_eig * e_max:
        return cov.copy(), 0.0
    # Exact loading for the bar, nudged up so rounding never leaves the result just under it.
    lam = float((min_eig * e_max - e_min) / (1.0 - min_eig) * (1.0 + 1e-9))
    return cov + lam * np.diag(scale2), lam


def _cholesky(cov: np.ndarray, what: str) -> np.ndarray:
    try:
        return np.linalg.cholesky(cov)
    except np.linalg.LinAlgError:
        raise ValidationError(f"{what} is not positive definite: {cov.tolist()}") from None


def gaussian_log_pdf(x: np.ndarray, means: np.ndarray, covs: np.ndarray) -> np.ndarray:
    """Log density of every row of x under each of M Gaussians, vectorised.

    Args:
        x: (n, d) points.
        means: (M, d) means.
        covs: (M, d, d) positive-definite covariances.

    Returns:
        (n, M) log densities.
    """
    chol = np.linalg.cholesky(covs)  # (M, d, d)
    eye = np.broadcast_to(np.eye(covs.shape[-1]), covs.shape)
    chol_inv = np.linalg.solve(chol, eye)  # (M, d, d), lower triangular
    diff = x[:, None, :] - means[None, :, :]  # (n, M, d)
    z = np.einsum("mij,nmj->nmi", chol_inv, diff)
    maha = np.einsum("nmi,nmi->nm", z, z)
    log_det = 2.0 * np.log(np.diagonal(chol, axis1=-2, axis2=-1)).sum(axis=-1)  # (M,)
    d = x.shape[1]
    return -0.5 * (maha + log_det[None, :] + d * math.log(2.0 * math.pi))


# --------------------------------------------------------------------------------------------------------------
# the memory


class HapticMemory:
    """Bayesian haptic memory of seed 000 (eq. 6.10-6.14): per material, N(mu_N, Sigma_N) x N(mu_A, Sigma_A) x prior.

    Args:
        materials: material names in the order of the model's columns; None takes them from the training labels
            in order of first appearance.
        prior: P(M): None for uniform, a sequence aligned with ``materials``, or a mapping name -> weight.
            Normalised to sum to 1; zero weights are allowed (that material is then never chosen).
        min_eig: smallest accepted eigenvalue of each covariance relative to its largest, in per-dimension
            standard-deviation units (see :func:`regularise_covariance`). The thesis data need no loading.
        ddof: covariance estimator: 0 divides by n (population; reproduces Table 6.6 of seed 000), 1 by n - 1.

    After :meth:`fit`: ``materials`` (list[str]), ``prior`` (M,), ``means_N``, ``means_A`` (M, 2), ``covs_N``,
    ``covs_A`` (M, 2, 2) (regularised, as used), ``regularisation`` ({material: {"N": lam, "A": lam}}, the
    relative diagonal loading applied), ``training_params`` (n, 4) and ``training_labels``.
    """

    def __init__(self, materials: Sequence[str] | None = None, prior=None, min_eig: float = DEFAULT_MIN_EIG,
                 ddof: int = 0):
        if materials is not None:
            materials = list(materials) if not isinstance(materials, str) else materials
            materials = _as_labels(materials, len(materials))
            if len(set(materials)) != len(materials):
                raise ValidationError(f"materials has duplicate names: {materials}")
            if not materials:
                raise ValidationError("materials is empty; expected at least one material name")
        if not (isinstance(min_eig, (int, float)) and 0.0 < float(min_eig) < 1.0):
            raise ValidationError(f"min_eig must be a number in (0, 1), got {min_eig!r}")
        if isinstance(ddof, bool) or not isinstance(ddof, (int, np.integer)) or ddof not in (0, 1):
            raise ValidationError(f"ddof must be 0 (divide by n) or 1 (divide by n - 1), got {ddof!r}")
        self._materials_arg = materials
        self._prior_arg = prior
        self.min_eig = float(min_eig)
        self.ddof = int(ddof)
        self.materials: list[str] = list(materials) if materials is not None else []
        self.prior: np.ndarray | None = None
        self.means_N = self.covs_N = self.means_A = self.covs_A = None
        self.regularisation: dict[str, dict[str, float]] = {}
        self.training_params: np.ndarray | None = None
        self.training_labels: list[str] = []

    # ---- training -------------------------------------------------------------------------------------------

    def fit(self, params, labels: Sequence[str]) -> HapticMemory:
        """Learn each material's Gaussians from per-press parameters.

        Args:
            params: (n, 4) array, columns [n1, n2, a1, a2], one row per press.
            labels: n material names.

        Returns:
            self. Raises ValidationError for non-finite values, wrong shapes, labels outside ``materials`` or
            fewer than :data:`MIN_SAMPLES` presses for a material.
        """
        x = _as_params(params)
        labs = _as_labels(labels, x.shape[0])
        materials = list(self._materials_arg) if self._materials_arg is not None else _unique_in_order(labs)
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
        prior = _normalise_prior(self._prior_arg, materials)
        fallback = x.var(axis=0)
        means_N, covs_N, means_A, covs_A = [], [], [], []
        reg: dict[str, dict[str, float]] = {}
        for k, m in enumerate(materials):
            xm = x[lab_idx == k]
            mu = xm.mean(axis=0)
            d = xm - mu
            cov4 = d.T @ d / (len(xm) - self.ddof)
            cN, lamN = regularise_covariance(cov4[:2, :2], self.min_eig, fallback[:2])
            cA, lamA = regularise_covariance(cov4[2:, 2:], self.min_eig, fallback[2:])
            means_N.append(mu[:2])
            means_A.append(mu[2:])
            covs_N.append(cN)
            covs_A.append(cA)
            reg[m] = {"N": lamN, "A": lamA}
        self.materials = materials
        self.prior = prior
        self.means_N, self.covs_N = np.array(means_N), np.array(covs_N)
        self.means_A, self.covs_A = np.array(means_A), np.array(covs_A)
        self.regularisation = reg
        self.training_params = x.copy()
        self.training_labels = labs
        return self

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
        """Train from a params CSV (see :func:`read_params_csv`) or from rows (mappings with material,n1,n2,a1,a2).

        Keyword arguments go to the constructor.
        """
        if isinstance(path_or_rows, (str, Path)):
            params, labels, _ = read_params_csv(path_or_rows)
        else:
            params, labels = _rows_to_params(path_or_rows)
        return cls(**kwargs).fit(params, labels)

    # ---- inference ------------------------------------------------------------------------------------------

    def _check_fitted(self) -> None:
        if self.means_N is None:
            raise ValidationError("this HapticMemory is not trained yet; call fit() or load() first")

    def log_likelihood(self, params) -> np.ndarray:
        """log P(n | M) + log P(a | M) for every press and material (eq. 6.13, 6.14), shape (n, M)."""
        self._check_fitted()
        x = _as_params(params)
        return gaussian_log_pdf(x[:, :2], self.means_N, self.covs_N) + gaussian_log_pdf(
            x[:, 2:], self.means_A, self.covs_A
        )

    def predict_log_proba(self, params) -> np.ndarray:
        """Log posterior log P(M | n, a) (eq. 6.11), shape (n, M), normalised with log-sum-exp."""
        ll = self.log_likelihood(params)
        with np.errstate(divide="ignore"):  # a zero prior is allowed and means log P(M) = -inf
            log_prior = np.log(self.prior)
        joint = ll + log_prior[None, :]
        out = joint - logsumexp(joint, axis=1, keepdims=True)
        if np.isnan(out).any():  # unreachable for validated input; never hand NaN onwards
            row = int(np.argwhere(np.isnan(out))[0, 0])
            raise ValidationError(f"params[{row}]: posterior is not finite; log-likelihoods {ll[row].tolist()}")
        return out

    def predict_proba(self, params) -> np.ndarray:
        """Posterior P(M | n, a) (eq. 6.11), shape (n, M); each row sums to 1."""
        return np.exp(self.predict_log_proba(params))

    def predict(self, params) -> list[str]:
        """MAP material name per press (eq. 6.12)."""
        idx = np.argmax(self.predict_log_proba(params), axis=1)
        return [self.materials[i] for i in idx]

    def index_of(self, labels: Sequence[str]) -> np.ndarray:
        """Column index of each material name; ValidationError for a name the memory does not know."""
        self._check_fitted()
        labels = list(labels) if not isinstance(labels, str) else labels
        labs = _as_labels(labels, len(labels))
        lookup = {m: i for i, m in enumerate(self.materials)}
        for i, lab in enumerate(labs):
            if lab not in lookup:
                raise ValidationError(f"labels[{i}] is {lab!r}, not a material of this memory {self.materials}")
        return np.array([lookup[lab] for lab in labs], dtype=int)

    def score(self, params, labels: Sequence[str]) -> float:
        """Fraction of presses whose MAP material equals the label."""
        x = _as_params(params)
        truth = self.index_of(_as_labels(labels, x.shape[0]))
        return float(np.mean(np.argmax(self.predict_log_proba(x), axis=1) == truth))

    def refit(self) -> HapticMemory:
        """A new memory trained on the stored training data with the same settings (for auditing)."""
        self._check_fitted()
        prior = dict(zip(self.materials, self.prior.tolist(), strict=True))
        return HapticMemory(self.materials, prior, self.min_eig, self.ddof).fit(
            self.training_params, self.training_labels
        )

    # ---- files ----------------------------------------------------------------------------------------------

    def to_dict(self) -> dict:
        """The JSON-ready description (format, version, settings, learned parameters, training data)."""
        self._check_fitted()
        from palpate.core import __version__

        return {
            "format": FORMAT_NAME,
            "version": FORMAT_VERSION,
            "palpate_version": __version__,
            "param_columns": list(PARAM_COLUMNS),
            "materials": list(self.materials),
            "prior": self.prior.tolist(),
            "ddof": self.ddof,
            "min_eig": self.min_eig,
            "means_N": self.means_N.tolist(),
            "covs_N": self.covs_N.tolist(),
            "means_A": self.means_A.tolist(),
            "covs_A": self.covs_A.tolist(),
            "regularisation": {m: dict(v) for m, v in self.regularisation.items()},
            "training": {"params": self.training_params.tolist(), "labels": list(self.training_labels)},
        }

    def to_json(self) -> str:
        """Serialise to JSON text (floats round-trip exactly)."""
        return json.dumps(self.to_dict(), indent=1, allow_nan=False)

    def save(self, path: str | Path) -> None:
        """Write the memory as JSON to ``path``."""
        Path(path).write_text(self.to_json() + "\n", encoding="utf-8")

    @classmethod
    def from_dict(cls, doc, source: str = "<memory>", audit: bool = True) -> HapticMemory:
        """Rebuild a memory from :meth:`to_dict` output, validating every key.

        Args:
            doc: the decoded JSON object.
            source: name used in error messages (usually the file path).
            audit: also re-fit the stored training data and require the stored parameters to match it.
        """
        return _memory_from_dict(cls, doc, source, audit)

    @classmethod
    def load(cls, path: str | Path, audit: bool = True) -> HapticMemory:
        """Read a memory saved by :meth:`save`; ValidationError naming the file and key for anything wrong."""
        path = Path(path)
        try:
            text = path.read_text(encoding="utf-8")
        except OSError as exc:
            raise ValidationError(f"{path}: cannot read haptic memory: {exc.strerror or exc}") from None
        except UnicodeDecodeError:
            raise ValidationError(f"{path}: not a UTF-8 JSON haptic memory") from None

        def _no_constants(name):
            raise ValidationError(f"{path}: contains {name}; expected finite numbers only")

        try:
            doc = json.loads(text, parse_constant=_no_constants)
        except json.JSONDecodeError as exc:
            raise ValidationError(f"{path}:{exc.lineno}: not valid JSON: {exc.msg}") from None
        return cls.from_dict(doc, source=str(path), audit=audit)


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


def _rows_to_params(rows) -> tuple[np.ndarray, list[str]]:
    params, labels = [], []
    for i, row in enumerate(rows):
        if not isinstance(row, Mapping):
            raise ValidationError(f"row {i} is a {type(row).__name__}; expected a mapping with material,n1,n2,a1,a2")
        missing = [k for k in ("material", *PARAM_COLUMNS) if k not in row]
        if missing:
            raise ValidationError(f"row {i} lacks key(s) {missing}; expected material,n1,n2,a1,a2")
        vals = []
        for k in PARAM_COLUMNS:
            try:
                vals.append(float(row[k]))
            except (TypeError, ValueError):
                raise ValidationError(f"row {i}: column {k!r}: {row[k]!r} is not a number") from None
        params.append(vals)
        labels.append(row["material"])
    if not params:
        raise ValidationError("no rows; expected one row per press with material,n1,n2,a1,a2")
    return _as_params(np.array(params)), _as_labels(labels, len(params))


# --------------------------------------------------------------------------------------------------------------
# JSON validation


def _get(doc: Mapping, key: str, source: str):
    if key not in doc:
        raise ValidationError(f"{source}: missing key '{key}'")
    return doc[key]


def _array(value, key: str, source: str, shape: tuple) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValidationError(f"{source}: key '{key}' must be an array of numbers with shape {shape}") from None
    if arr.shape != shape:
        raise ValidationError(f"{source}: key '{key}' has shape {arr.shape}, expected {shape}")
    if not np.all(np.isfinite(arr)):
        raise ValidationError(f"{source}: key '{key}' holds non-finite numbers")
    return arr


def _memory_from_dict(cls, doc, source: str, audit: bool) -> HapticMemory:
    if not isinstance(doc, Mapping):
        raise ValidationError(f"{source}: expected a JSON object, got {type(doc).__name__}")
    fmt = _get(doc, "format", source)
    if fmt != FORMAT_NAME:
        raise ValidationError(f"{source}: key 'format' is {fmt!r}, expected {FORMAT_NAME!r}")
    version = _get(doc, "version", source)
    if version != FORMAT_VERSION:
        raise ValidationError(f"{source}: key 'version' is {version!r}; this palpate reads version {FORMAT_VERSION}")
    materials = _get(doc, "materials", source)
    if (not isinstance(materials, list) or not materials
            or not all(isinstance(m, str) and m.strip() for m in materials) or len(set(materials)) != len(materials)):
        raise ValidationError(f"{source}: key 'materials' must be a non-empty list of distinct names")
    m = len(materials)
    ddof = _get(doc, "ddof", source)
    min_eig = _get(doc, "min_eig", source)
    if isinstance(ddof, bool) or ddof not in (0, 1):
        raise ValidationError(f"{source}: key 'ddof' is {ddof!r}, expected 0 or 1")
    if isinstance(min_eig, bool) or not isinstance(min_eig, (int, float)) or not 0 < min_eig < 1:
        raise ValidationError(f"{source}: key 'min_eig' is {min_eig!r}, expected a number in (0, 1)")
    prior = _array(_get(doc, "prior", source), "prior", source, (m,))
    if np.any(prior < 0) or not np.isclose(prior.sum(), 1.0, rtol=0, atol=1e-9):
        raise ValidationError(f"{source}: key 'prior' must be >= 0 and sum to 1, got {prior.tolist()}")
    arrays = {}
    for key, shape in (("means_N", (m, 2)), ("means_A", (m, 2)), ("covs_N", (m, 2, 2)), ("covs_A", (m, 2, 2))):
        arrays[key] = _array(_get(doc, key, source), key, source, shape)
    for key in ("covs_N", "covs_A"):
        for k, c in enumerate(arrays[key]):
            if not np.array_equal(c, c.T):
                raise ValidationError(f"{source}: key '{key}' [{materials[k]}] is not symmetric")
            _cholesky(c, f"{source}: key '{key}' [{materials[k]}]")
    reg = _get(doc, "regularisation", source)
    if not isinstance(reg, Mapping) or set(reg) != set(materials):
        raise ValidationError(f"{source}: key 'regularisation' must map every material to {{'N': lam, 'A': lam}}")
    regularisation = {}
    for name in materials:
        entry = reg[name]
        if not isinstance(entry, Mapping) or set(entry) != {"N", "A"}:
            raise ValidationError(f"{source}: key 'regularisation.{name}' must be {{'N': lam, 'A': lam}}")
        for part in ("N", "A"):
            v = entry[part]
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
                raise ValidationError(f"{source}: key 'regularisation.{name}.{part}' is {v!r}, expected a number >= 0")
        regularisation[name] = {"N": float(entry["N"]), "A": float(entry["A"])}
    training = _get(doc, "training", source)
    if not isinstance(training, Mapping):
        raise ValidationError(f"{source}: key 'training' must be an object with 'params' and 'labels'")
    t_labels = _get(training, "labels", f"{source}: training")
    if not isinstance(t_labels, list):
        raise ValidationError(f"{source}: key 'training.labels' must be a list of material names")
    t_params = _array(_get(training, "params", f"{source}: training"), "training.params", source, (len(t_labels), 4))
    unknown = sorted({lab for lab in t_labels if lab not in materials}, key=str)
    if unknown:
        raise ValidationError(f"{source}: key 'training.labels' names {unknown}, not in 'materials'")

    prior_map = dict(zip(materials, prior.tolist(), strict=True))
    mem = cls(materials=materials, prior=prior_map, min_eig=float(min_eig), ddof=ddof)
    mem.prior = prior
    mem.means_N, mem.means_A = arrays["means_N"], arrays["means_A"]
    mem.covs_N, mem.covs_A = arrays["covs_N"], arrays["covs_A"]
    mem.regularisation = regularisation
    mem.training_params = t_params
    mem.training_labels = list(t_labels)
    if audit:
        try:
            ref = mem.refit()
        except ValidationError as exc:
            raise ValidationError(f"{source}: key 'training' cannot be re-fitted: {exc}") from None
        for key in ("means_N", "covs_N", "means_A", "covs_A"):
            if not np.allclose(getattr(ref, key), arrays[key], rtol=1e-9, atol=0.0):
                raise ValidationError(
                    f"{source}: key '{key}' does not match a re-fit of key 'training' (ddof={ddof}); the file was "
                    "edited or corrupted (load with audit=False to accept it)"
                )
    return mem


# --------------------------------------------------------------------------------------------------------------
# CSV


def read_params_csv(path: str | Path) -> tuple[np.ndarray, list[str], dict[str, np.ndarray]]:
    """Read per-press interaction parameters from a CSV file.

    The header names the columns (any order, case-insensitive); ``material,n1,n2,a1,a2`` are required, any others
    (e.g. run, phi_n, phi_a) are kept. Blank lines and lines starting with ``#`` are skipped.

    Returns:
        (params (n, 4) [n1, n2, a1, a2], labels (n material names), extra columns: name -> (n,) array, float when
        every value is a finite number, str otherwise).

    Raises ValidationError naming the file, line and column of the first bad entry, e.g.
    ``params.csv:7: column 'a1': 'abc' is not a number``.
    """
    path = Path(path)
    name = path.name
    try:
        text = path.read_text(encoding="utf-8-sig")
    except OSError as exc:
        raise ValidationError(f"{path}: cannot read params CSV: {exc.strerror or exc}") from None
    except UnicodeDecodeError as exc:
        raise ValidationError(f"{path}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None

    lines = [(i + 1, line) for i, line in enumerate(text.splitlines())]
    content = [(no, line) for no, line in lines if line.strip() and not line.lstrip().startswith("#")]
    if not content:
        raise ValidationError(f"{name}: empty; expected a header with material,n1,n2,a1,a2 and one row per press")
    parsed = []
    for no, line in content:
        # One physical line per record, so every error can name its line.
        try:
            parsed.append((no, next(csv.reader([line], strict=True))))
        except csv.Error as exc:
            raise ValidationError(f"{name}:{no}: not a CSV record: {exc}") from None

    head_no, header = parsed[0]
    header = [h.strip().lower() for h in header]
    dupes = sorted({h for h in header if header.count(h) > 1})
    if dupes:
        raise ValidationError(f"{name}:{head_no}: header repeats column(s) {dupes}")
    if any(not h for h in header):
        raise ValidationError(f"{name}:{head_no}: header has an empty column name (column {header.index('') + 1})")
    missing = [c for c in ("material", *PARAM_COLUMNS) if c not in header]
    if missing:
        raise ValidationError(
            f"{name}:{head_no}: header lacks column(s) {', '.join(repr(c) for c in missing)}; expected at least "
            f"material,n1,n2,a1,a2 (got {','.join(header)})"
        )
    rows = parsed[1:]
    if not rows:
        raise ValidationError(f"{name}: header only; expected one row per press after line {head_no}")
    col = {h: i for i, h in enumerate(header)}
    params = np.empty((len(rows), 4))
    labels: list[str] = []
    raw_extra: dict[str, list[str]] = {h: [] for h in header if h not in ("material", *PARAM_COLUMNS)}
    for r, (no, row) in enumerate(rows):
        if len(row) != len(header):
            raise ValidationError(f"{name}:{no}: has {len(row)} fields, expected {len(header)} ({','.join(header)})")
        label = row[col["material"]].strip()
        if not label:
            raise ValidationError(f"{name}:{no}: column 'material': empty; expected a material name")
        labels.append(label)
        for j, c in enumerate(PARAM_COLUMNS):
            cell = row[col[c]].strip()
            try:
                v = float(cell)
            except ValueError:
                raise ValidationError(f"{name}:{no}: column '{c}': {cell!r} is not a number") from None
            if not math.isfinite(v) or abs(v) > MAX_ABS_PARAM:
                raise ValidationError(f"{name}:{no}: column '{c}': {cell!r} is not a finite number")
            params[r, j] = v
        for h in raw_extra:
            raw_extra[h].append(row[col[h]].strip())
    extra = {h: _column_array(vals) for h, vals in raw_extra.items()}
    return params, labels, extra


def _column_array(values: list[str]) -> np.ndarray:
    try:
        arr = np.array([float(v) for v in values])
    except ValueError:
        return np.array(values, dtype=str)
    return arr if np.all(np.isfinite(arr)) else np.array(values, dtype=str)


# --------------------------------------------------------------------------------------------------------------
# cross-validation


@dataclass
class CrossValidation:
    """Result of :func:`leave_one_out`. Rows are the true material, columns the perceived one.

    Attributes:
        materials: names, in row/column order.
        counts: (M, M) number of presses of material i classified (MAP) as j.
        confusion: (M, M) counts divided by each row's total (Table 6.7 layout).
        mean_posterior: (M, M) mean posterior P(M = j | press) over the presses of material i.
        posteriors: (n, M) posterior of each held-out press, in input order.
        truth: (n,) index of each press's true material.
    """

    materials: list[str]
    counts: np.ndarray
    confusion: np.ndarray
    mean_posterior: np.ndarray
    posteriors: np.ndarray
    truth: np.ndarray

    @property
    def predicted(self) -> np.ndarray:
        """(n,) MAP material index of each held-out press."""
        return np.argmax(self.posteriors, axis=1)

    @property
    def accuracy(self) -> float:
        """Fraction of all presses classified correctly."""
        return float(np.trace(self.counts) / self.counts.sum())

    @property
    def per_material_accuracy(self) -> np.ndarray:
        """(M,) fraction of each material's presses classified correctly (the confusion diagonal)."""
        return np.diag(self.confusion).copy()

    def to_dict(self) -> dict:
        """JSON-ready summary: materials, confusion, mean_posterior, counts, accuracy."""
        return {
            "materials": list(self.materials),
            "confusion": self.confusion.tolist(),
            "mean_posterior": self.mean_posterior.tolist(),
            "counts": self.counts.astype(int).tolist(),
            "accuracy": self.accuracy,
            "per_material_accuracy": self.per_material_accuracy.tolist(),
        }


def leave_one_out(params, labels: Sequence[str], **memory_kwargs) -> CrossValidation:
    """Leave-one-out cross-validation of the haptic memory (seed 000, sec. 6.8.2, Table 6.7).

    Each press is held out in turn; a memory is trained on all the others (for its own material that is the
    other n-1 presses, as in the thesis) and the held-out press is classified by MAP.

    Args:
        params: (n, 4) [n1, n2, a1, a2].
        labels: n material names.
        **memory_kwargs: passed to :class:`HapticMemory` (materials, prior, min_eig, ddof).

    Needs at least MIN_SAMPLES + 1 presses per material.
    """
    x = _as_params(params)
    labs = _as_labels(labels, x.shape[0])
    full = HapticMemory(**memory_kwargs).fit(x, labs)
    materials = full.materials
    truth = full.index_of(labs)
    counts_per = np.bincount(truth, minlength=len(materials))
    for name, c in zip(materials, counts_per, strict=True):
        if c < MIN_SAMPLES + 1:
            raise ValidationError(
                f"material {name!r} has {c} presses; leave-one-out needs at least {MIN_SAMPLES + 1}"
            )
    kwargs = dict(memory_kwargs)
    kwargs["materials"] = materials
    post = np.empty((len(x), len(materials)))
    keep = np.ones(len(x), dtype=bool)
    for i in range(len(x)):
        keep[i] = False
        mem = HapticMemory(**kwargs).fit(x[keep], [lab for lab, k in zip(labs, keep, strict=True) if k])
        post[i] = mem.predict_proba(x[i])[0]
        keep[i] = True
    m = len(materials)
    counts = np.zeros((m, m))
    np.add.at(counts, (truth, np.argmax(post, axis=1)), 1)
    mean_post = np.zeros((m, m))
    np.add.at(mean_post, truth, post)
    mean_post /= counts_per[:, None]
    return CrossValidation(
        materials=list(materials),
        counts=counts,
        confusion=counts / counts_per[:, None],
        mean_posterior=mean_post,
        posteriors=post,
        truth=truth,
    )
