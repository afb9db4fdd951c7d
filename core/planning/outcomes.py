"""What a press will probably say: per-press posteriors predicted from the haptic memory's own Gaussians, merged into
a small table of outcomes (what :mod:`~palpate.core.planning.info_gain` and
:mod:`~palpate.core.planning.expected_accuracy` take expectations over).
"""

from __future__ import annotations

import numpy as np

from palpate.core.errors import ValidationError


def outcome_posteriors(memory, samples_per_material: int = 6, seed: int = 0) -> np.ndarray:
    """Predicted per-press posteriors, shape (M, S, M): row [t, s] is the memory's posterior for the s-th
    parameter vector drawn from material t's Gaussians N(mu_N, Sigma_N) x N(mu_A, Sigma_A) (seed 000 eq. 6.13-6.14).

    Seeded, so a run is deterministic.
    """
    if isinstance(samples_per_material, bool) or not isinstance(samples_per_material, (int, np.integer)) \
            or samples_per_material < 1:
        raise ValidationError(f"samples_per_material must be an integer >= 1, got {samples_per_material!r}")
    if getattr(memory, "means_N", None) is None:
        raise ValidationError("info_gain needs a trained haptic memory (means and covariances per material)")
    rng = np.random.default_rng(seed)
    m = len(memory.materials)
    draws = []
    for t in range(m):
        n = rng.multivariate_normal(memory.means_N[t], memory.covs_N[t], samples_per_material)
        a = rng.multivariate_normal(memory.means_A[t], memory.covs_A[t], samples_per_material)
        draws.append(np.hstack([n, a]))
    q = memory.predict_proba(np.vstack(draws)).reshape(m, samples_per_material, m)
    return np.asarray(q, dtype=float)


def outcome_table(q: np.ndarray, resolution: float = 0.02) -> tuple[np.ndarray, np.ndarray]:
    """Merge predicted outcomes that differ by less than ``resolution`` in every probability.

    A well-separated memory predicts nearly the same posterior for most draws of a material; merging them keeps
    the expectation the same to that resolution and makes :func:`expected_gain` several times cheaper.

    Args:
        q: (M, S, M) from :func:`outcome_posteriors`.
        resolution: probability bin width.

    Returns:
        (outcomes (U, M): the mean posterior of each merged group, rows summing to 1;
         likelihood (M, U): fraction of material t's draws that fell in group u, rows summing to 1).
    """
    q = np.asarray(q, dtype=float)
    if q.ndim != 3 or q.shape[0] != q.shape[2] or q.shape[1] < 1:
        raise ValidationError(f"outcome posteriors must have shape (M, S, M), got {q.shape}")
    if not np.all(np.isfinite(q)) or (q < 0).any():
        raise ValidationError("outcome posteriors must be finite and non-negative")
    m, s, _ = q.shape
    flat = q.reshape(m * s, m)
    _, group = np.unique(np.round(flat / resolution), axis=0, return_inverse=True)
    group = group.reshape(-1)
    u = int(group.max()) + 1
    outcomes = np.zeros((u, m))
    np.add.at(outcomes, group, flat)
    outcomes /= np.bincount(group, minlength=u)[:, None]
    outcomes /= outcomes.sum(axis=1, keepdims=True)
    likelihood = np.zeros((m, u))
    np.add.at(likelihood, (np.repeat(np.arange(m), s), group), 1.0 / s)
    return outcomes, likelihood
