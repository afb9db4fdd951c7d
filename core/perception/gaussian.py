"""Gaussian pieces of the haptic memory: covariance regularisation and log densities.

A memory is fixed once fitted, so its Cholesky factors are computed once (:class:`GaussianFactors`) and every
press only does the triangular products.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from palpate.core.errors import ValidationError

_LOG_2PI = math.log(2.0 * math.pi)


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


def cholesky_checked(cov: np.ndarray, what: str) -> np.ndarray:
    try:
        return np.linalg.cholesky(cov)
    except np.linalg.LinAlgError:
        raise ValidationError(f"{what} is not positive definite: {cov.tolist()}") from None


@dataclass(frozen=True)
class GaussianFactors:
    """Precomputed factors of M Gaussians in d dimensions:
    log N(x) = -(|L_m^-1 (x - mu_m)|^2 + log det Sigma_m + d log 2 pi) / 2.

    Attributes:
        means: (M, d).
        chol_inv: (M, d, d) inverse Cholesky factors (lower triangular).
        log_det: (M,) log det Sigma_m.
    """

    means: np.ndarray
    chol_inv: np.ndarray
    log_det: np.ndarray

    @classmethod
    def of(cls, means: np.ndarray, covs: np.ndarray) -> GaussianFactors:
        """Factor positive-definite covariances (M, d, d) once."""
        chol = np.linalg.cholesky(covs)  # (M, d, d)
        eye = np.broadcast_to(np.eye(covs.shape[-1]), covs.shape)
        chol_inv = np.linalg.solve(chol, eye)
        log_det = 2.0 * np.log(np.diagonal(chol, axis1=-2, axis2=-1)).sum(axis=-1)
        return cls(np.asarray(means, dtype=float), chol_inv, log_det)

    def log_pdf(self, x: np.ndarray) -> np.ndarray:
        """(n, M) log densities of the rows of x (n, d)."""
        diff = x[:, None, :] - self.means  # (n, M, d)
        z = np.einsum("mij,nmj->nmi", self.chol_inv, diff)
        maha = (z * z).sum(axis=-1)
        d = self.means.shape[1]
        return -0.5 * (maha + self.log_det + d * _LOG_2PI)


def gaussian_log_pdf(x: np.ndarray, means: np.ndarray, covs: np.ndarray) -> np.ndarray:
    """Log density of every row of x under each of M Gaussians, vectorised.

    Args:
        x: (n, d) points.
        means: (M, d) means.
        covs: (M, d, d) positive-definite covariances.

    Returns:
        (n, M) log densities.
    """
    return GaussianFactors.of(means, covs).log_pdf(x)
