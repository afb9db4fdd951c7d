"""Where a wall lies within one press, read from its taxel image: a Bayesian comparison of the image against
boundary templates (:mod:`.templates`).

Hypotheses are one material (``plain``) or a wall at every angle, offset and contrast of the templates. Each
template is scaled to the image by weighted least squares (the materials' moduli are unknown; a linear contact's
pressure scales with them) and scored by a Gaussian likelihood whose spread per sensel is the sensor's noise plus a
model error proportional to the predicted reading; sensels read as zero (at or below the noise floor) only count
where the template predicts more than the floor. The posterior over the grid gives the reading and its uncertainty.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from palpate.core.boundary.templates import REFERENCE_MODULUS, BoundaryTemplates
from palpate.core.errors import ValidationError

#: Model error per sensel, a share of its predicted reading (the image rung against the 3-D FE is 5-15% of peak rms
#: beside walls); tuned on the FE reference's tuning cases (benchmarks/boundary_reading.py).
MODEL_ERROR = 0.25
#: Prior probability of one material under the press.
PRIOR_PLAIN = 0.5
#: Walls farther from the axis than this count as "not within reach", m.
REACH = 0.0055


@dataclass(frozen=True)
class NoiseModel:
    """The reading's sensor model, in the image's units (counts for raw frames, Pa for pressures).

    Attributes:
        noise: standard deviation of one reading (sensor noise and quantisation together).
        floor: readings at or below this are reported as zero.
        ceiling: the largest reading (saturated sensels say only "at least this"); infinity when none.
        model_error: model error as a share of the predicted reading.
    """

    noise: float
    floor: float = 0.0
    ceiling: float = np.inf
    model_error: float = MODEL_ERROR

    def __post_init__(self) -> None:
        if not (self.noise > 0 and 0 <= self.floor < self.ceiling and 0 <= self.model_error < 1):
            raise ValidationError("NoiseModel: noise must be > 0, 0 <= floor < ceiling and model_error in [0, 1)")


@dataclass(frozen=True)
class BoundaryReading:
    """What one press says about a wall under it, in the pad's frame rotated by the given yaw (the world's frame
    when the pad is aligned with it).

    Attributes:
        p_boundary: probability that a wall lies within ``reach`` of the press axis.
        angle: direction of the wall's normal towards the harder side, rad (posterior circular mean over walls).
        angle_sd: its circular standard deviation, rad.
        offset: signed distance from the press axis to the wall along the normal, m (negative: the axis is on the
            harder side), posterior mean over walls, weighted by the cosine of
            their angle to ``angle`` (walls facing away left out).
        offset_sd: its standard deviation, m.
        contrast: posterior median of the harder over the softer modulus, given a wall.
        reach: the distance ``p_boundary`` counts walls within, m.
        posterior: probabilities of the walls over (angles, offsets), summed over contrasts; with ``p_plain`` they
            sum to 1.
        p_plain: probability of one material.
        angles, offsets: the grid of ``posterior`` (rad in the reading's frame, m).
        log_soft, log_hard: posterior means, given a wall, of the log moduli of the softer and the harder side, and
            log_plain: the log modulus of one material: log(Pa x image units per Pa) (see :meth:`moduli`).
    """

    p_boundary: float
    angle: float
    angle_sd: float
    offset: float
    offset_sd: float
    contrast: float
    reach: float
    posterior: np.ndarray
    p_plain: float
    angles: np.ndarray
    offsets: np.ndarray
    log_soft: float = float("nan")
    log_hard: float = float("nan")
    log_plain: float = float("nan")

    def moduli(self, gain: float) -> tuple[float, float, float]:
        """The softer side's, the harder side's and the one-material modulus, Pa, for images in units of ``gain``
        per Pa (counts: the pad's gain; Pa: 1). Linear elasticity on the templates' block: a thinner or layered
        object reads stiffer, alike for every press on it."""
        return tuple(float(np.exp(v) / gain) for v in (self.log_soft, self.log_hard, self.log_plain))

    @property
    def normal(self) -> np.ndarray:
        """Unit normal of the wall towards the harder side, (2,)."""
        return np.array([np.cos(self.angle), np.sin(self.angle)])

    @property
    def tangent(self) -> np.ndarray:
        """Unit vector along the wall, the normal turned a quarter turn anticlockwise, (2,)."""
        return np.array([-np.sin(self.angle), np.cos(self.angle)])

    @property
    def foot(self) -> np.ndarray:
        """The wall's nearest point to the press axis, m, relative to the axis, (2,)."""
        return self.offset * self.normal


def _log_likelihood(image: np.ndarray, templates: np.ndarray, noise: NoiseModel) -> tuple[np.ndarray, np.ndarray]:
    """Log-likelihood of ``image`` (S,) under each template (H, S) scaled by its best factor, and that factor."""
    t = templates
    # Least-squares scale first, then once more weighted by the spread that scale implies.
    scale = (t @ image) / np.maximum(np.einsum("hs,hs->h", t, t), 1e-300)
    for _ in range(2):
        pred = scale[:, None] * t
        var = noise.noise**2 + (noise.model_error * pred) ** 2
        w = 1.0 / var
        scale = np.einsum("hs,hs,s->h", w, t, image) / np.maximum(np.einsum("hs,hs,hs->h", w, t, t), 1e-300)
    pred = np.maximum(scale, 0.0)[:, None] * t
    var = noise.noise**2 + (noise.model_error * pred) ** 2
    resid = image[None, :] - pred
    # A zero reading says only "at or below the floor": no penalty where the template predicts as little.
    zero = image[None, :] <= 0.0
    resid = np.where(zero, np.maximum(pred - noise.floor, 0.0), resid)
    # Likewise a saturated reading says only "at least the ceiling".
    full = image[None, :] >= noise.ceiling
    resid = np.where(full, np.maximum(noise.ceiling - pred, 0.0), resid)
    return -0.5 * np.sum(resid**2 / var + np.log(var), axis=1), np.maximum(scale, 1e-300)


def read_boundary(image: np.ndarray, depth: float, templates: BoundaryTemplates, noise: NoiseModel, *,
                  yaw: float = 0.0, reach: float = REACH, prior_plain: float = PRIOR_PLAIN) -> BoundaryReading:
    """Read a wall from one taxel image.

    Args:
        image: the pad's readings at the press's deepest point, (rows, cols), row 0 at the pad's +y (counts or Pa,
            the units of ``noise``); values at or below the floor as zero.
        depth: the indentation at that image, m.
        templates: boundary templates for this pad.
        noise: the sensor model.
        yaw: rotation of the pad's frame in the output frame, rad (0: pad x along world x).
        reach: distance the returned ``p_boundary`` counts walls within, m.
        prior_plain: prior probability of one material.

    Raises:
        ValidationError: an image of another shape, not finite or negative, a depth outside (0, radius), or
            an image with no contact.
    """
    img = np.asarray(image, dtype=float)
    pad = templates.pad
    if img.shape != (pad.rows, pad.cols):
        raise ValidationError(f"read_boundary: the templates are for a {pad.rows}x{pad.cols} pad, got an image of "
                              f"shape {img.shape}")
    if not np.all(np.isfinite(img)) or np.any(img < 0):
        raise ValidationError("read_boundary: image readings must be finite and >= 0")
    if not 0 < depth < pad.radius:
        raise ValidationError(f"read_boundary: depth must be in (0, {pad.radius}) m, got {depth}")
    if not img.max() > noise.floor:
        raise ValidationError("read_boundary: no sensel reads above the floor (no contact to read)")
    if not 0 < prior_plain < 1:
        raise ValidationError(f"read_boundary: prior_plain must be in (0, 1), got {prior_plain}")
    wall, plain = templates.at_depth(depth)
    n_a, n_o, n_c = wall.shape[:3]
    flat = np.concatenate([wall.reshape(-1, img.size), plain.reshape(1, -1)])
    ll, scale = _log_likelihood(img.ravel(), flat, noise)
    prior = np.full(ll.shape, (1 - prior_plain) / (ll.size - 1))
    prior[-1] = prior_plain
    logp = ll + np.log(prior)
    p = np.exp(logp - logp.max())
    p /= p.sum()
    p_plain = float(p[-1])
    walls = p[:-1].reshape(n_a, n_o, n_c)
    post = walls.sum(axis=2)
    log_soft = np.log(scale[:-1]).reshape(n_a, n_o, n_c)
    mass = max(float(walls.sum()), 1e-300)
    log_soft_mean = float(np.sum(walls * log_soft) / mass)
    log_hard_mean = float(np.sum(walls * (log_soft + np.log(templates.contrasts))) / mass)
    scales = (log_soft_mean, log_hard_mean, float(np.log(scale[-1])))
    return _summary(post, walls.sum(axis=(0, 1)), p_plain, templates, yaw, reach, scales)


def _summary(post: np.ndarray, by_contrast: np.ndarray, p_plain: float, templates: BoundaryTemplates, yaw: float,
             reach: float, scales: tuple[float, float, float]) -> BoundaryReading:
    log_moduli = tuple(v + np.log(REFERENCE_MODULUS) for v in scales)
    angles = templates.angles + yaw
    offsets = templates.offsets
    total = post.sum()
    if total <= 0:
        return BoundaryReading(0.0, 0.0, np.pi, 0.0, float(np.ptp(offsets)), 1.0, reach, post, p_plain, angles,
                               offsets, *log_moduli)
    pa = post.sum(axis=1) / total
    vec = np.sum(pa * np.exp(1j * angles))
    angle = float(np.angle(vec))
    r = min(abs(vec), 1.0)
    angle_sd = float(np.sqrt(-2 * np.log(max(r, 1e-12))))
    # Walls facing the other way say nothing about this offset; weighted smoothly so that the reading turns with
    # the image exactly (a hard cut would flip grid angles on its edge by rounding).
    po = np.clip(np.cos(angles - angle), 0.0, None) @ post
    po = po / po.sum() if po.sum() > 0 else np.full(len(offsets), 1.0 / len(offsets))
    offset = float(po @ offsets)
    offset_sd = float(np.sqrt(max(po @ (offsets - offset) ** 2, 0.0)))
    cdf = np.cumsum(by_contrast / by_contrast.sum())
    contrast = float(templates.contrasts[min(int(np.searchsorted(cdf, 0.5)), len(cdf) - 1)])
    within = np.abs(offsets) <= reach
    p_boundary = float(post[:, within].sum())
    return BoundaryReading(p_boundary, angle, angle_sd, offset, offset_sd, contrast, reach, post, p_plain, angles,
                           offsets, *log_moduli)
