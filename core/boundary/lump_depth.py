"""How deep a buried lump lies, and of what, from the press over it.

A press over a lump reads harder (or softer) than the material on top, and by how much changes as it presses in: a
lump deep down is felt only late in the press, a shallow one early. The press's contact intensity c_P (the pad's
summed reading) against its indentation c_D, over the mean curve of the top material's training presses, is compared
in log with :mod:`.lump_templates` at the contrast of each other reference material (their moduli as the boundary
reading reads them, :mod:`.moduli`). The template that fits best gives the lump's top depth, its material and a
shape; the reading is only as good as the contact law the templates come from (a linear-elastic sample on its axis).
Everything is a ratio of the same pad's readings, so no gain is needed and it runs on real streams alike.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from palpate.core.boundary.lump_templates import LumpTemplates
from palpate.core.boundary.moduli import MaterialModuli
from palpate.core.boundary.templates import bracket
from palpate.core.errors import ValidationError

#: Fewest indentations of the templates a press must reach to be read.
MIN_POINTS = 3
#: The reading's step in top depth, m: templates are interpolated linearly between their stored tops.
TOP_STEP = 1e-4
#: Spread of a press's log c_P ratio about its template, per depth: mostly the templates' own error (an on-axis
#: lump of a few shapes against lumps of any shape beside the press). Chosen on tuning scenes (voxel_lumps.py seeds
#: 0-47, 44 lumps read) as the smallest value whose spread holds the true top within one / two spreads of the read
#: one 68% / 95% of the time (0.2: 50 / 86%, 0.25: 59 / 91%, 0.3: 64 / 95%, 0.4: 70 / 98%).
MISFIT_SD = 0.3
#: Spread added in quadrature to the posterior's, m: one press cannot tell a small shallow lump from a large deep one,
#: and the posterior, whose templates are all on the press's axis, does not see how far that trade reaches. Chosen on
#: tuning scenes (voxel_lumps.py seeds 0-95, 88 lumps read) as the value whose spread holds the true top within one /
#: two spreads 68% / 95% of the time (0: 52 / 85%, 1: 61 / 91%, 1.5: 66 / 93%, 1.75: 70 / 95%, 2: 73 / 97%).
TOP_SD_FLOOR = 1.75e-3


@dataclass(frozen=True)
class LumpDepth:
    """A lump read from one press.

    Attributes:
        material: the reference material it is read as.
        top: depth of its top below the surface, m.
        top_sd: the posterior spread of the top about ``top``, m.
        p_material: the posterior probability of ``material``.
        shape: the best template's shape ("layer", "sphere" or "cylinder").
        radius: its radius, m (0 for a layer).
        rms: its root-mean-square misfit in log c_P.
        rms_plain: the same for no lump (the press's curve against the top material's).
    """

    material: str
    top: float
    top_sd: float
    p_material: float
    shape: str
    radius: float
    rms: float
    rms_plain: float

    def to_dict(self) -> dict:
        """JSON-ready form (summary.json)."""
        return {"material": self.material, "top_m": self.top, "top_sd_m": self.top_sd, "p_material": self.p_material,
                "shape": self.shape, "radius_m": self.radius, "rms_log": self.rms, "rms_log_plain": self.rms_plain}


@dataclass(frozen=True)
class LumpEvidence:
    """What lump depths are read from: the templates, each reference material's mean log c_P at the templates'
    depths (:func:`reference_curves`), and per boundary reading of a map, its press's (:func:`press_curve`)."""

    templates: LumpTemplates
    references: dict[str, np.ndarray]
    curves: tuple[np.ndarray, ...]


def press_curve(c_D, c_P, depths) -> np.ndarray:
    """log c_P of a press phase (samples from contact to its deepest point) at the indentations ``depths`` (m),
    linear between samples; NaN past the press's deepest point and where c_P is not positive."""
    c_D, c_P = np.asarray(c_D, dtype=float).ravel(), np.asarray(c_P, dtype=float).ravel()
    depths = np.asarray(depths, dtype=float)
    ok = np.isfinite(c_D) & np.isfinite(c_P)
    if c_D.shape != c_P.shape or ok.sum() < 2:
        return np.full(len(depths), np.nan)
    order = np.argsort(c_D[ok], kind="stable")
    value = np.interp(depths, c_D[ok][order], c_P[ok][order], left=np.nan, right=np.nan)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(value > 0, np.log(np.where(value > 0, value, 1.0)), np.nan)


def result_curve(result, depths) -> np.ndarray:
    """:func:`press_curve` of a perceived press (a PressResult; all NaN when no press was found)."""
    if result is None or result.press is None:
        return np.full(len(depths), np.nan)
    return press_curve(result.press.c_D, result.press.c_P, depths)


def reference_curves(presses: dict[str, tuple], depths) -> dict[str, np.ndarray]:
    """Per reference material, the mean of its presses' :func:`result_curve` (NaN at a depth none reached)."""
    out = {}
    for name, results in presses.items():
        rows = np.array([result_curve(r, depths) for r in results]).reshape(-1, len(depths))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # a depth no press reached stays NaN
            out[name] = np.nanmean(rows, axis=0) if len(rows) else np.full(len(depths), np.nan)
    return out


def _fine_tops(templates: LumpTemplates) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Tops every TOP_STEP over the stored range and, per fine top, the stored pair and weight around it."""
    tops = templates.tops
    fine = np.arange(tops[0], tops[-1] + TOP_STEP / 2, TOP_STEP) if len(tops) > 1 else tops.copy()
    return (fine, *bracket(tops, fine))


def read_lump_depth(curve: np.ndarray, top: str, evidence: LumpEvidence, moduli: MaterialModuli,
                    sign: str | None = None) -> LumpDepth | None:
    """The lump under a press whose :func:`press_curve` is ``curve``, on the material ``top``, among reference
    materials harder (``sign`` "harder"), softer ("softer") or either (None) than ``top``: the material, template
    and top depth that fit the curve's ratio to ``top``'s best, with the top's spread about it (with
    :data:`TOP_SD_FLOOR`) and the material's probability under a posterior over all of them (flat prior, Gaussian
    misfit of :data:`MISFIT_SD` per depth in log). None when fewer than :data:`MIN_POINTS` depths are known, no
    material qualifies, or no lump fits better than none.

    Raises:
        ValidationError: a curve of another length than the templates' depths.
    """
    t = evidence.templates
    curve = np.asarray(curve, dtype=float)
    if curve.shape != t.depths.shape:
        raise ValidationError(f"read_lump_depth: a curve has one value per template depth ({len(t.depths)}), got "
                              f"shape {curve.shape}")
    if top not in evidence.references or top not in moduli.materials:
        return None
    ratio = curve - evidence.references[top]
    ok = np.isfinite(ratio)
    if ok.sum() < MIN_POINTS:
        return None
    rms_plain = float(np.sqrt(np.mean(ratio[ok] ** 2)))
    fine, k, w = _fine_tops(t)
    names, rms = [], []
    for name in moduli.materials:
        if name == top or name not in evidence.references:
            continue
        contrast = float(np.exp(moduli.log_mean[moduli.materials.index(name)]
                                - moduli.log_mean[moduli.materials.index(top)]))
        if contrast == 1 or (sign == "harder" and contrast < 1) or (sign == "softer" and contrast > 1):
            continue
        table = t.at_contrast(contrast)[..., ok]  # (K, T, d)
        lower, upper = table[:, k], table[:, np.minimum(k + 1, len(t.tops) - 1)]
        model = (1 - w)[None, :, None] * lower + w[None, :, None] * upper  # (K, fine T, d)
        names.append(name)
        rms.append(np.sqrt(np.mean((ratio[ok] - model) ** 2, axis=-1)))
    if not names or float(np.min(rms)) >= rms_plain:
        return None
    rms_all = np.stack(rms)  # (materials, K, fine T)
    m, s, j = np.unravel_index(int(np.argmin(rms_all)), rms_all.shape)
    log_like = -0.5 * ok.sum() * (rms_all / MISFIT_SD) ** 2
    post = np.exp(log_like - log_like.max())
    post /= post.sum()
    spread = float(np.sqrt(post.sum(axis=(0, 1)) @ (fine - fine[j]) ** 2 + TOP_SD_FLOOR**2))
    return LumpDepth(names[m], float(fine[j]), spread, min(float(post[m].sum()), 1.0), t.shapes[s], float(t.radii[s]),
                     float(rms_all[m, s, j]), rms_plain)
