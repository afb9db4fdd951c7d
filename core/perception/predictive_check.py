"""A predictive check of realism: does the real per-press table look like one more simulated session?

A simulator is realistic for a real table when the table cannot be told from the sessions the simulator makes. Given
the real table and S fresh simulated sessions (each one training session: the same references pressed as the real
ones were), :func:`predictive_check` judges, per material:

* **Classifier two-sample test** (Lopez-Paz & Oquab 2017): for each session, a linear discriminant (LDA, covariance
  shrunk 10% towards the identity, equal priors) tells the real presses from the session's, leave-one-out; its
  accuracy is ~0.5 or below when they come from one distribution. The check holds when the mean accuracy over the
  sessions is at most :data:`C2ST_MAX` (0.70).
* **Energy distance** (Szekely & Rizzo 2004) of the real presses to the pooled sessions, against the distribution of
  the same distance of each session to the pooled others (leave one session out). The check holds when the real
  table's distance is no larger than the largest session's (rank p-value >= 1 / (S + 1)).

and over all materials **bands**: per material the real table's CV of n1 and of a1 and its spread (the mean
distance between two of its presses in standardised [n1, n2, a1, a2], the energy distance's own within-sample term),
and the first reference's leave-one-out mean posterior of itself (Table 6.7's 0.82), must each lie in the 0.5-99.5%
range of the sessions' values; at most :data:`BAND_MISSES_ALLOWED` (one) of these may miss. The spread band is there
because a table too tight is hard to see otherwise: the energy distance of 10 presses barely grows when they are
0.6 times as spread as the sessions', and a single CV of 10 presses is a weak test (without it the rule failed such a
table in 67% of trials, with it in >= 95%). The share of presses with n2 < 0 and the other references' leave-one-out
posteriors are banded and reported too, but do not vote: a share of 10 presses and a posterior saturated at 1 have
bands too coarse to judge by.

The verdict passes when every material's two tests hold and the bands miss at most once. Both tests read the
[n1, n2, a1, a2] columns, each divided by the pooled sessions' standard deviation (one scale for the real table and
every session, so they are exchangeable when the simulator is right).

Size and power (benchmarks/realism_predictive.py; docs/results.md, "The predictive check"): with S = 100 fresh
sessions of a Gaussian simulator fitted to seed 000's table, a real table drawn from the simulator passed in 95 of 100
trials; one with twice or 0.6 times the spread, or with the cutaneous locations of the shipped profile, failed in
100, 97 and 100 of 100 (on 300 more trials each, the first passed in 278 and the third failed in 289).
These rates hold for S = 100, hence :data:`MIN_SESSIONS`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.perception.memory import MIN_SAMPLES
from palpate.core.perception.param_stats import PARAM_INDEX, PressTable
from palpate.core.perception.realism_targets import loo_self

#: Mean leave-one-out accuracy over sessions at or below which the classifier cannot tell real from simulated.
C2ST_MAX = 0.70
#: Covariance shrinkage of the discriminant (towards the identity, in standardised columns).
SHRINKAGE = 0.1
#: The bands: the range of the sessions' values a real statistic must lie in.
BAND_QUANTILES = (0.005, 0.995)
#: Decisive bands that may miss with the verdict still passing.
BAND_MISSES_ALLOWED = 1
#: Fewest simulated sessions judged: the size and power were measured with 100; with fewer the 0.5-99.5% bands come
#: close to the sessions' extremes and the energy rank coarse, so a right simulator fails more often (it passed in
#: 88 of 100 trials with 50 sessions, 60 of 100 with 20).
MIN_SESSIONS = 100
#: Banded statistics per material, in order; "cv n1", "cv a1" and "spread" vote for every material, "loo" for the
#: first only.
BAND_STATISTICS = ("cv n1", "cv a1", "spread", "n2<0", "loo")
#: The statistics that vote for every material.
DECISIVE = ("cv n1", "cv a1", "spread")


def lda_loo_accuracy(x0: np.ndarray, x1: np.ndarray, shrinkage: float = SHRINKAGE) -> float:
    """Leave-one-out accuracy of a two-class linear discriminant telling rows ``x0`` (n0, d) from ``x1`` (n1, d).

    The discriminant is scikit-learn's ``LinearDiscriminantAnalysis(solver="lsqr", shrinkage=shrinkage,
    priors=[0.5, 0.5])``: the covariance is the classes' ML covariances averaged with equal weights, then shrunk
    towards tr / d times the identity; a point on the boundary goes to class 0. Every held-out row is judged by the
    discriminant of the other rows, computed in closed form (rank-one downdates, no refit). Each class needs >= 3 rows.
    """
    a, b = np.asarray(x0, dtype=float), np.asarray(x1, dtype=float)
    if a.ndim != 2 or b.ndim != 2 or a.shape[1] != b.shape[1] or len(a) < 3 or len(b) < 3:
        raise ValidationError(f"lda_loo_accuracy: two (n, d) arrays of one d and >= 3 rows each needed, got "
                              f"{a.shape} and {b.shape}")
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))) or not 0.0 <= shrinkage <= 1.0:
        raise ValidationError(f"lda_loo_accuracy: finite rows and a shrinkage in [0, 1] needed (got {shrinkage})")
    d = a.shape[1]
    x = np.vstack([a, b])
    cls = np.r_[np.zeros(len(a), dtype=int), np.ones(len(b), dtype=int)]
    counts = np.array([len(a), len(b)], dtype=float)
    mu = np.stack([a.mean(axis=0), b.mean(axis=0)])                     # (2, d)
    scatter = np.stack([(a - mu[0]).T @ (a - mu[0]), (b - mu[1]).T @ (b - mu[1])])  # (2, d, d)
    # per held-out row i of class c: that class's mean and scatter without it (exact downdate)
    r = x - mu[cls]                                                       # (n, d)
    nc = counts[cls]
    mu_c = mu[cls] - r / (nc - 1.0)[:, None]
    sc_c = scatter[cls] - (nc / (nc - 1.0))[:, None, None] * r[:, :, None] * r[:, None, :]
    mu_o, sc_o, no = mu[1 - cls], scatter[1 - cls], counts[1 - cls]
    cov = 0.5 * (sc_c / (nc - 1.0)[:, None, None] + sc_o / no[:, None, None])
    trace = np.trace(cov, axis1=1, axis2=2)
    cov = (1.0 - shrinkage) * cov + (shrinkage * trace / d)[:, None, None] * np.eye(d)
    mu0 = np.where((cls == 0)[:, None], mu_c, mu_o)
    mu1 = np.where((cls == 1)[:, None], mu_c, mu_o)
    w = np.linalg.solve(cov, (mu1 - mu0)[:, :, None])[:, :, 0]
    score = np.einsum("nd,nd->n", w, x - 0.5 * (mu0 + mu1))
    return float(np.mean((score > 0).astype(int) == cls))


def session_energy(real: np.ndarray, sessions: Sequence[np.ndarray]) -> tuple[float, np.ndarray]:
    """Energy distance (V-statistic, as :func:`~palpate.core.perception.param_stats.energy_distance` with unit
    scale) of ``real`` (n, d) to the pooled ``sessions`` (each (m_s, d)), and (S,) of each session to the pooled
    others. One distance matrix of the pooled rows gives every leave-one-session-out distance by block sums."""
    from scipy.spatial.distance import cdist  # lazily: a run that asks for no check never loads it

    z = np.vstack(sessions)
    sizes = np.array([len(s) for s in sessions])
    starts = np.r_[0, np.cumsum(sizes)[:-1]]
    blocks = np.add.reduceat(np.add.reduceat(cdist(z, z), starts, axis=0), starts, axis=1)  # (S, S) sums
    total, rows, own = blocks.sum(), blocks.sum(axis=1), np.diag(blocks)
    rest = len(z) - sizes
    null = 2.0 * (rows - own) / (sizes * rest) - own / sizes**2 - (total - 2.0 * rows + own) / rest**2
    stat = 2.0 * cdist(real, z).mean() - cdist(real, real).mean() - total / len(z) ** 2
    return max(float(stat), 0.0), np.maximum(null, 0.0)


@dataclass(frozen=True)
class MaterialVerdict:
    """The two tests of one material.

    Attributes:
        material: its name.
        c2st: mean over sessions of the real-vs-session leave-one-out accuracy.
        c2st_sessions: (S,) each session's accuracy.
        energy: energy distance of the real presses to the pooled sessions (standardised columns).
        energy_sessions: (S,) each session's distance to the pooled others.
        energy_p: rank p-value (1 + #{session >= real}) / (S + 1).
    """

    material: str
    c2st: float
    c2st_sessions: np.ndarray
    energy: float
    energy_sessions: np.ndarray
    energy_p: float

    @property
    def c2st_passed(self) -> bool:
        """The classifier cannot tell the real presses from a session's (mean accuracy <= :data:`C2ST_MAX`)."""
        return self.c2st <= C2ST_MAX

    @property
    def energy_passed(self) -> bool:
        """The real table is no farther from the sessions than the farthest session is from the others."""
        return self.energy <= float(np.max(self.energy_sessions))


@dataclass(frozen=True)
class Band:
    """One real statistic against the 0.5-99.5% range of the sessions' (``decisive``: it votes in the verdict)."""

    material: str
    statistic: str
    real: float
    low: float
    high: float
    decisive: bool

    @property
    def inside(self) -> bool:
        """low <= real <= high."""
        return self.low <= self.real <= self.high


@dataclass(frozen=True)
class PredictiveCheck:
    """The verdict of :func:`predictive_check`.

    Attributes:
        sessions: S, the simulated sessions judged against.
        materials: one :class:`MaterialVerdict` per material, in the references' order.
        bands: every :class:`Band`, materials in order, statistics in :data:`BAND_STATISTICS` order.
    """

    sessions: int
    materials: tuple[MaterialVerdict, ...]
    bands: tuple[Band, ...]

    @property
    def band_misses(self) -> int:
        """Decisive bands the real statistic lies outside."""
        return sum(b.decisive and not b.inside for b in self.bands)

    def material_passed(self, material: str) -> bool:
        """Both tests of ``material`` hold and none of its decisive bands misses."""
        v = next(m for m in self.materials if m.material == material)
        bands_ok = all(b.inside for b in self.bands if b.material == material and b.decisive)
        return v.c2st_passed and v.energy_passed and bands_ok

    @property
    def passed(self) -> bool:
        """Every material's two tests hold and at most :data:`BAND_MISSES_ALLOWED` decisive bands miss."""
        tests = all(m.c2st_passed and m.energy_passed for m in self.materials)
        return tests and self.band_misses <= BAND_MISSES_ALLOWED

    def to_dict(self) -> dict:
        """JSON-ready: the rule, per material its tests, bands and verdict, and the overall verdict."""
        out: dict = {"sessions": self.sessions, "rule": RULE, "passed": self.passed,
                     "band_misses": self.band_misses, "materials": {}}
        for m in self.materials:
            out["materials"][m.material] = {
                "passed": self.material_passed(m.material),
                "c2st": {"accuracy": m.c2st, "max": C2ST_MAX, "passed": m.c2st_passed},
                "energy": {"real": m.energy, "sessions_max": float(np.max(m.energy_sessions)),
                           "sessions_median": float(np.median(m.energy_sessions)), "p": m.energy_p,
                           "passed": m.energy_passed},
                "bands": {b.statistic: {"real": b.real, "low": b.low, "high": b.high, "inside": b.inside,
                                        "decisive": b.decisive} for b in self.bands if b.material == m.material},
            }
        return out


RULE = (f"passes when, for every material, the mean leave-one-out accuracy of a shrinkage LDA telling the real "
        f"presses from a simulated session's is <= {C2ST_MAX} and the real table's energy distance to the pooled "
        f"sessions is <= the largest session's to the others, and at most {BAND_MISSES_ALLOWED} of the decisive bands "
        f"(CV of n1 and a1 per material, the first reference's leave-one-out self posterior) leaves the sessions' "
        f"{100 * BAND_QUANTILES[0]:g}-{100 * BAND_QUANTILES[1]:g}% range")


def _band_values(table: PressTable, materials: Sequence[str], loo: np.ndarray, scales: np.ndarray) -> np.ndarray:
    """(M, 5) the :data:`BAND_STATISTICS` of one table (``scales`` (M, 4): the columns' standardisation)."""
    from scipy.spatial.distance import cdist

    out = np.empty((len(materials), len(BAND_STATISTICS)))
    for i, name in enumerate(materials):
        r = table.of(name)
        with np.errstate(divide="ignore", invalid="ignore"):
            cv = r[:, [0, 3]].std(axis=0, ddof=1) / np.abs(r[:, [0, 3]].mean(axis=0))
        z = r[:, list(PARAM_INDEX)] / scales[i]
        spread = float(np.mean(cdist(z, z)))
        out[i] = [cv[0], cv[1], spread, np.mean(r[:, 1] < 0), loo[i]]
    return out


def predictive_check(real: PressTable, sessions: Sequence[PressTable], materials: Sequence[str], *,
                     session_loo: np.ndarray | None = None, real_loo: np.ndarray | None = None) -> PredictiveCheck:
    """Judge whether ``real`` looks like one more of the simulated ``sessions`` (module docstring: the rule).

    Args:
        real: the real per-press table.
        sessions: S >= :data:`MIN_SESSIONS` simulated training sessions of the same references.
        materials: the references, in order (the first's leave-one-out posterior votes); each in every table
            with >= MIN_SAMPLES + 1 presses (leave-one-out holds one out of a Gaussian's).
        session_loo: (S, M) each session's leave-one-out mean posterior of each material itself, when already
            known (a run's cross-validation); else computed as a run does
            (:func:`~palpate.core.perception.realism_targets.loo_self`).
        real_loo: (M,) the same of the real table.
    """
    names = tuple(materials)
    if len(sessions) < MIN_SESSIONS:
        raise ValidationError(f"predictive check: {len(sessions)} simulated sessions; at least {MIN_SESSIONS} are "
                              "needed (raise the number of sessions)")
    for t, what in [(real, "the real table")] + [(s, f"session {k}") for k, s in enumerate(sessions)]:
        for name in names:
            if len(t.of(name)) < MIN_SAMPLES + 1:
                raise ValidationError(f"predictive check: {what} has {len(t.of(name))} presses of {name!r}; "
                                      f"at least {MIN_SAMPLES + 1} are needed")
    s_loo = (np.array([loo_self(s, names) for s in sessions]) if session_loo is None
             else np.asarray(session_loo, dtype=float))
    r_loo = loo_self(real, names) if real_loo is None else np.asarray(real_loo, dtype=float).reshape(-1)
    if s_loo.shape != (len(sessions), len(names)) or r_loo.shape != (len(names),):
        raise ValidationError(f"predictive check: leave-one-out posteriors of shape ({len(sessions)}, {len(names)}) "
                              f"and ({len(names)},) needed, got {s_loo.shape} and {r_loo.shape}")
    idx = list(PARAM_INDEX)
    verdicts, scales = [], []
    for name in names:
        sess = [s.of(name)[:, idx] for s in sessions]
        sd = np.vstack(sess).std(axis=0, ddof=1)
        scale = np.where(sd > 0, sd, 1.0)
        scales.append(scale)
        sess = [s / scale for s in sess]
        x = real.of(name)[:, idx] / scale
        acc = np.array([lda_loo_accuracy(x, s) for s in sess])
        energy, null = session_energy(x, sess)
        p = (1.0 + np.sum(null >= energy)) / (len(null) + 1.0)
        verdicts.append(MaterialVerdict(name, float(acc.mean()), acc, energy, null, float(p)))
    sc = np.array(scales)
    sim_vals = np.array([_band_values(s, names, s_loo[k], sc) for k, s in enumerate(sessions)])  # (S, M, 5)
    real_vals = _band_values(real, names, r_loo, sc)
    low, high = np.nanquantile(sim_vals, BAND_QUANTILES, axis=0)
    bands = tuple(Band(name, stat, float(real_vals[i, j]), float(low[i, j]), float(high[i, j]),
                       stat in DECISIVE or (stat == "loo" and i == 0))
                  for i, name in enumerate(names) for j, stat in enumerate(BAND_STATISTICS))
    return PredictiveCheck(len(sessions), tuple(verdicts), bands)
