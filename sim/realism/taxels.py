"""The pad's non-ideal response: what a resistive taxel array adds between the pressure and its raw counts.

:class:`TaxelResponse` maps the mean pressure over each sensel at the frame times (Pa) to the pressure the sensor
*reports* (Pa), before :func:`palpate.sim.sensors.taxel_counts` applies the gain, noise, 8-bit rounding, saturation
and threshold. In order:

0. activation: a sensel's ink conducts only above its turn-on pressure (one per sensel, :func:`activation_map`);
   below it the sensel reads nothing, above it its whole pressure;
1. gain: the pad's sensitivity times each sensel's gain after equilibration (a session-long map) times the pad's
   drift for this press;
2. creep: under load the output rises by ``creep`` per decade of the time the sensel has been loaded
   (1 + creep log10(1 + t_loaded / 1 s); the clock restarts when the sensel unloads);
3. hysteresis: unloading reads higher than loading: y = p (1 + h) - h p^2 / p_peak, with p_peak the sensel's
   peak since it was last unloaded (y = p while loading, monotonic in p for h < 1);
4. crosstalk: each sensel reads ``crosstalk`` of each of its four neighbours;
5. non-linearity: the response compresses towards full scale, y / (1 + k y / full_scale).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from palpate.sim.realism.profile import TaxelRealism

#: Reference time of the creep law, s (Tekscan specifies creep per decade of time from ~1 s).
CREEP_REFERENCE_S = 1.0


#: How far, in standard deviations of a careful draw, a careless press's log-normal factor may go.
SPREAD_SIGMAS = 3.0


def lognormal(rng: np.random.Generator, cv: float, shape: tuple[int, ...] = (), spread: float = 1.0) -> np.ndarray:
    """Log-normal factors of mean 1 and coefficient of variation ``cv`` (ones, and nothing drawn, for cv <= 0).

    ``spread`` multiplies the log-deviation (a careless press's scale, :func:`palpate.sim.controller.tail_scale`),
    within :data:`SPREAD_SIGMAS` of a careful draw's (a finger's pulp is no softer or stiffer for being pressed
    carelessly: the careless press only reaches the ends of its range more often); 1 draws exactly as without it.
    """
    if cv <= 0:
        return np.ones(shape)
    s = np.sqrt(np.log1p(cv * cv))
    z = rng.standard_normal(shape)
    if spread != 1.0:
        z = np.clip(spread * z, -SPREAD_SIGMAS, SPREAD_SIGMAS)
    return np.exp(s * z - 0.5 * s * s)


def gain_map(realism: TaxelRealism, shape: tuple[int, int], rng: np.random.Generator) -> np.ndarray:
    """Per-sensel gains left after equilibration: log-normal, mean 1, coefficient of variation ``gain_spread``."""
    return lognormal(rng, realism.gain_spread, shape)


def activation_map(realism: TaxelRealism, shape: tuple[int, int], rng: np.random.Generator) -> np.ndarray:
    """Per-sensel turn-on pressures, Pa: log-normal, mean ``activation``, coefficient of variation ``activation_cv``.

    With no spread every sensel has the pad's one turn-on pressure and nothing is drawn (so a profile without a
    spread replays the draws it made before the spread existed).
    """
    if realism.activation <= 0:
        return np.zeros(shape)
    return realism.activation * lognormal(rng, realism.activation_cv, shape)


@dataclass(frozen=True)
class TaxelResponse:
    """The reported pressure of one press's frames (see the module docstring).

    Attributes:
        realism: the non-idealities.
        gains: (rows, cols) gain of each sensel for this press (equilibration map x drift).
        full_scale: pressure at which the counts saturate, Pa (255 / gain).
        activation: (rows, cols) turn-on pressure of each sensel, Pa (None: the pad's one ``realism.activation``).
    """

    realism: TaxelRealism
    gains: np.ndarray
    full_scale: float
    activation: np.ndarray | None = None

    def __call__(self, t: np.ndarray, pressure: np.ndarray) -> np.ndarray:
        """Reported pressure, Pa, shape (n, rows, cols), of true mean sensel pressures (n, rows, cols) at times t."""
        r = self.realism
        p = np.maximum(np.asarray(pressure, dtype=float), 0.0)
        turn_on = r.activation if self.activation is None else self.activation[None]
        p = np.where(p > turn_on, p, 0.0) * (r.sensitivity * self.gains)[None]
        loaded = p > 0
        if r.creep > 0:
            p = p * (1.0 + r.creep * np.log10(1.0 + _loaded_time(t, loaded) / CREEP_REFERENCE_S))
        if r.hysteresis > 0:
            peak = _running_peak(p, loaded)
            p = np.where(peak > 0, p * (1.0 + r.hysteresis) - r.hysteresis * p * p / np.maximum(peak, 1e-300), p)
        if r.crosstalk > 0:
            padded = np.pad(p, ((0, 0), (1, 1), (1, 1)))
            p = p + r.crosstalk * (padded[:, :-2, 1:-1] + padded[:, 2:, 1:-1] + padded[:, 1:-1, :-2]
                                   + padded[:, 1:-1, 2:])
        if r.nonlinearity > 0:
            p = p / (1.0 + r.nonlinearity * p / self.full_scale)
        return p


def _loaded_time(t: np.ndarray, loaded: np.ndarray) -> np.ndarray:
    """Time each sensel has been loaded without interruption at each frame, s, shape of ``loaded``."""
    last_unloaded = np.where(loaded, -np.inf, np.asarray(t, dtype=float)[:, None, None])
    last_unloaded = np.maximum.accumulate(last_unloaded, axis=0)
    return np.asarray(t, dtype=float)[:, None, None] - np.where(np.isfinite(last_unloaded), last_unloaded, t[0])


def _running_peak(p: np.ndarray, loaded: np.ndarray) -> np.ndarray:
    """Each sensel's peak since it was last unloaded, at each frame (0 while unloaded), of pressures ``p`` >= 0.

    A running maximum that restarts at every unloaded frame, as log2(frames) doubling steps over whole arrays
    (each frame takes the maximum of itself and the frame 2^j before it when no unloaded frame lies between):
    maxima are exact, so this equals the frame-by-frame recursion.
    """
    peak = np.where(loaded, p, 0.0)
    run = np.cumsum(~loaded, axis=0)  # a new run of loaded frames starts at each unloaded frame (its value 0)
    shift = 1
    while shift < len(peak):
        earlier = np.where(run[shift:] == run[:-shift], peak[:-shift], 0.0)
        peak[shift:] = np.maximum(peak[shift:], earlier)
        shift *= 2
    return peak
