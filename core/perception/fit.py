"""Cutaneous and kinesthetic interaction laws of one press (eq. 6.5, 6.6, 6.16, 6.17 of seed 000).

    c_P = a1 c_A^(3/2) + a2     (cutaneous, A = (a1, a2), residual Phi_A)
    c_P = n1 c_D^(3/2) + n2     (kinesthetic, N = (n1, n2), residual Phi_N)

Both laws are linear in (k1, k2) once x is raised to 3/2, so least squares in x^(3/2) is the maximum-likelihood
estimate under Gaussian noise on c_P, as the seed asks. Standard errors come from the residual variance with n - 2
degrees of freedom.

Units of the interaction parameters: fits use c_D in mm and c_A in mm^2 (see :data:`FIT_UNITS`), with c_P in
counts (or N when calibrated). SI metres would put c_D^(3/2) around 1e-4 and c_A^(3/2) around 1e-7, giving
parameters of order 1e6-1e9 that are badly conditioned and not comparable with the seed's Tables 6.3-6.5. So n1 is
in counts/mm^1.5, a1 in counts/mm^3, n2 and a2 in counts.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from palpate.core.errors import FitError
from palpate.core.perception.segment import Press

FIT_UNITS = {"c_D": "mm", "c_A": "mm^2"}
"""Units in which c_D and c_A enter the fits (c_P stays in counts, or N when calibrated)."""

_M_TO_MM = 1e3
_M2_TO_MM2 = 1e6

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class PowerLawFit:
    """Least-squares fit of y = k1 x^exponent + k2.

    Attributes:
        k1, k2: estimates.
        phi: sum of squared residuals (eq. 6.16 / 6.17).
        se_k1, se_k2: standard errors from the residual variance (n - 2 degrees of freedom).
        n: number of samples.
        cov_k1k2: covariance of the two estimates.
        exponent: the power applied to x.
    """

    k1: float
    k2: float
    phi: float
    se_k1: float
    se_k2: float
    n: int
    cov_k1k2: float = 0.0
    exponent: float = 1.5

    def predict(self, x) -> np.ndarray:
        """Model value k1 x^exponent + k2 at x (x >= 0)."""
        return self.k1 * np.asarray(x, dtype=float) ** self.exponent + self.k2


def fit_power_law(x, y, exponent: float = 1.5) -> PowerLawFit:
    """Fit y = k1 x^exponent + k2 by least squares (the MLE under Gaussian noise on y).

    x^exponent is centred and scaled before solving, so the result stays accurate whatever the units of x.

    Args:
        x: abscissa, >= 0, shape (n,) (e.g. c_D in mm or c_A in mm^2).
        y: ordinate, shape (n,) (c_P).
        exponent: the power law's exponent (3/2 for a spherical indenter).

    Returns:
        A :class:`PowerLawFit` with finite estimates, residual sum and standard errors.

    Raises:
        FitError: fewer than 3 samples, mismatched lengths, NaN/inf, negative x, constant x, all-zero y, or a
            result that would not be finite.
    """
    x, y = _samples(x, y, exponent)
    with np.errstate(over="ignore", invalid="ignore"):  # bad samples are named below, not warned about
        return _power_law(x, y, exponent)


def _samples(x, y, exponent: float) -> tuple[np.ndarray, np.ndarray]:
    """x and y as 1-D float arrays of the same length >= 3, for an exponent that is positive and finite."""
    x = np.asarray(x, dtype=float).reshape(-1)
    y = np.asarray(y, dtype=float).reshape(-1)
    if not (math.isfinite(exponent) and exponent > 0):
        raise FitError(f"exponent must be a positive finite number, got {exponent!r}")
    if x.shape != y.shape:
        raise FitError(f"x and y must have the same length, got {len(x)} and {len(y)}")
    if len(x) < 3:
        raise FitError(f"a 2-parameter fit needs at least 3 samples, got {len(x)}")
    return x, y


def _power_law(x: np.ndarray, y: np.ndarray, exponent: float) -> PowerLawFit:
    """:func:`fit_power_law` of arrays from :func:`_samples`, under the caller's np.errstate."""
    n = len(x)
    u = x**exponent
    # sum / n is np.mean's arithmetic, without its wrapper
    u_mean = float(u.sum()) / n
    y_mean = float(y.sum()) / n
    # The means check the samples: NaN or inf in x or y, a negative x (NaN power) and an overflowing x^exponent
    # all make one of them non-finite, and only all-zero y gives a zero mean with nothing to fit. Only then are
    # the samples searched for what is wrong.
    if not (math.isfinite(u_mean) and math.isfinite(y_mean)) or y_mean == 0.0:
        _check_samples(x, y, u, exponent)
    du = u - u_mean
    scale = math.sqrt(float((du * du).sum()) / n)
    # Constant x (up to rounding) leaves the slope undefined. max(u) <= n mean(u), so the second test runs only
    # when the first, cheaper one cannot decide.
    if scale <= 2e-12 * n * u_mean and scale <= 1e-12 * max(u_mean, float(u.max())):
        raise FitError(f"x is constant ({x[0]:g}) over all {n} samples: the slope k1 is undefined")
    z = du / scale
    yc = y - y_mean
    szz = float(z @ z)  # = n by construction, kept explicit for clarity of the formulas below
    b1 = float(z @ yc) / szz
    k1 = b1 / scale
    k2 = y_mean - k1 * u_mean
    resid = yc - b1 * z
    phi = float(resid @ resid)
    s2 = phi / (n - 2)
    var_k1 = s2 / (szz * scale**2)
    var_k2 = s2 / n + u_mean**2 * var_k1
    cov = -u_mean * var_k1
    if not all(map(math.isfinite, (k1, k2, phi, var_k1, var_k2, cov))):
        raise FitError(f"fit of {n} samples did not give finite estimates (x up to {x.max():g}, |y| up to "
                       f"{np.abs(y).max():g}); rescale the data")
    return PowerLawFit(k1=k1, k2=k2, phi=phi, se_k1=math.sqrt(var_k1), se_k2=math.sqrt(var_k2), n=n,
                       cov_k1k2=cov, exponent=float(exponent))


def _check_samples(x: np.ndarray, y: np.ndarray, u: np.ndarray, exponent: float) -> None:
    """FitError naming the first bad sample (non-finite, negative x), all-zero y or an overflowing x^exponent."""
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
        bad = int(np.argmax(~(np.isfinite(x) & np.isfinite(y))))
        raise FitError(f"non-finite sample at index {bad}: x={x[bad]!r}, y={y[bad]!r}")
    if np.any(x < 0):
        bad = int(np.argmax(x < 0))
        raise FitError(f"x must be >= 0 (an indentation or an area), got x={x[bad]!r} at index {bad}")
    if not np.any(y != 0):
        raise FitError(f"all {len(y)} y samples are zero: no contact intensity to fit")
    if not np.all(np.isfinite(u)):
        raise FitError(f"x^{exponent} overflows; x up to {x.max():g} is out of range")


@dataclass(frozen=True)
class PressFit:
    """Interaction parameters of one press (units in :data:`FIT_UNITS`).

    Attributes:
        n1, n2, phi_n: kinesthetic law c_P = n1 c_D^1.5 + n2 (c_D in mm) and its residual sum Phi_N.
        a1, a2, phi_a: cutaneous law c_P = a1 c_A^1.5 + a2 (c_A in mm^2) and its residual sum Phi_A.
        se_n1, se_n2, se_a1, se_a2: standard errors.
        n: number of press-phase samples used.
        press_index: :attr:`Press.index` of the press.
        location: (x, y) of the press, m.
        calibrated: True when c_P (hence n1, n2, a1, a2, phi) is in N rather than counts.
        features: "both", or "kinesthetic" when only the kinesthetic law was fitted (no contact area: c_P from a
            force, :mod:`~palpate.core.perception.force_channel`); a1, a2, phi_a and their errors are then 0.
    """

    n1: float
    n2: float
    phi_n: float
    a1: float
    a2: float
    phi_a: float
    se_n1: float
    se_n2: float
    se_a1: float
    se_a2: float
    n: int
    press_index: int = -1
    location: tuple[float, float] = (0.0, 0.0)
    calibrated: bool = False
    features: str = "both"

    @property
    def params(self) -> np.ndarray:
        """[n1, n2, a1, a2] in the units of :data:`FIT_UNITS`."""
        return np.array([self.n1, self.n2, self.a1, self.a2])

    @property
    def N(self) -> np.ndarray:  # noqa: N802 - the seed's name for the kinesthetic parameters
        """Kinesthetic parameters (n1, n2)."""
        return np.array([self.n1, self.n2])

    @property
    def A(self) -> np.ndarray:  # noqa: N802 - the seed's name for the cutaneous parameters
        """Cutaneous parameters (a1, a2)."""
        return np.array([self.a1, self.a2])


def fit_samples(c_P, c_A, c_D, *, where: str = "press", press_index: int = -1,
                location: tuple[float, float] = (0.0, 0.0), calibrated: bool = False) -> PressFit:
    """Fit both interaction laws to press-phase samples given as plain arrays.

    Args:
        c_P: contact intensity (counts, or N when ``calibrated``).
        c_A: contact area, m^2.
        c_D: indentation, m.
        where: how error messages name the samples.
        press_index, location, calibrated: copied into the result.

    Raises:
        FitError: naming the law (kinesthetic N or cutaneous A) when either fit is degenerate, e.g. a contact area
            that stays constant over the press phase.
    """
    try:
        fn, fa = _fit_laws(c_P, c_A, c_D)
    except FitError as exc:
        raise FitError(f"{where}: {exc}") from exc
    return _press_fit(fn, fa, press_index, location, calibrated)


def _fit_laws(c_P, c_A, c_D, features: str = "both") -> tuple[PowerLawFit, PowerLawFit | None]:
    """The kinesthetic and the cutaneous fit (None with ``features="kinesthetic"``); FitError names the law that
    failed."""
    with np.errstate(over="ignore", invalid="ignore"):  # bad samples are named, not warned about
        try:
            fn = _power_law(*_samples(np.asarray(c_D) * _M_TO_MM, c_P, 1.5), 1.5)
        except FitError as exc:
            raise FitError(f"kinesthetic fit (c_P vs c_D) failed: {exc}") from exc
        if features == "kinesthetic":
            return fn, None
        try:
            fa = _power_law(*_samples(np.asarray(c_A) * _M2_TO_MM2, c_P, 1.5), 1.5)
        except FitError as exc:
            raise FitError(f"cutaneous fit (c_P vs c_A) failed: {exc}") from exc
    return fn, fa


def _press_fit(fn: PowerLawFit, fa: PowerLawFit | None, press_index: int, location: tuple[float, float],
               calibrated: bool) -> PressFit:
    if fa is None:
        return PressFit(n1=fn.k1, n2=fn.k2, phi_n=fn.phi, a1=0.0, a2=0.0, phi_a=0.0, se_n1=fn.se_k1,
                        se_n2=fn.se_k2, se_a1=0.0, se_a2=0.0, n=fn.n, press_index=press_index, location=location,
                        calibrated=calibrated, features="kinesthetic")
    return PressFit(
        n1=fn.k1, n2=fn.k2, phi_n=fn.phi, a1=fa.k1, a2=fa.k2, phi_a=fa.phi,
        se_n1=fn.se_k1, se_n2=fn.se_k2, se_a1=fa.se_k1, se_a2=fa.se_k2,
        n=fn.n, press_index=press_index, location=location, calibrated=calibrated,
    )


def fit_press(press: Press, features: str = "both") -> PressFit:
    """Fit both interaction laws (or, with ``features="kinesthetic"``, the kinesthetic one) to the press phase of a
    segmented press (see :func:`fit_samples`)."""
    try:
        fn, fa = _fit_laws(press.c_P, press.c_A, press.c_D, features)
    except FitError as exc:
        raise FitError(f"press {press.index} at t={press.t_onset:.3f} s: {exc}") from exc
    return _press_fit(fn, fa, press.index, press.location, press.calibrated)


@dataclass(frozen=True)
class FitFailure:
    """A press whose fit failed, and why."""

    press_index: int
    t_onset: float
    reason: str


def fit_presses_reporting(presses: list[Press]) -> tuple[list[PressFit], list[FitFailure]]:
    """Fit every press; return the fits and, separately, the presses that could not be fitted with the reason."""
    fits: list[PressFit] = []
    failures: list[FitFailure] = []
    for press in presses:
        try:
            fits.append(fit_press(press))
        except FitError as exc:
            failures.append(FitFailure(press.index, press.t_onset, str(exc)))
    return fits, failures
