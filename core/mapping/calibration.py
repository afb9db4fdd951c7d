"""Maps whose confidence can be trusted: what one press is allowed to claim, and how to measure calibration.

A haptic memory's Gaussians are far apart, so a press's posterior is ~0.9999 for one material even where the press
straddled a wall or blurred a one-cell feature and read the wrong material. Fused as it is, such a press makes a
map cell (and, through eq. 6.15, its neighbours) certain and wrong. :func:`press_evidence` tempers what a press
contributes:

    p  proportional to  posterior ** temperature           (the memory's likelihood tempered; uniform prior)
    p  <-  reliability * p + (1 - reliability) / M        (a press misreads, for reasons the memory cannot see,
                                                           with probability ~ 1 - reliability)

With both at 1 a press fuses exactly as seed 001 eq. 2 says. The extrapolation's own certainty is a parameter of
:func:`palpate.core.mapping.extrapolation.extrapolate_plane`.

Neither sees walls: a press whose contact straddled a wall reads a blend, or the neighbour's material, as surely as
any other. The map can see where that may have happened, after the fact: two pressed cells sharing an edge that
read differently have a wall between them, within the contact's reach of both presses (a press at a cell's centre
reaches half a cell past its edges once the contact radius is about half a cell; a diagonal neighbour's corner
is further, and a wall cutting a diagonal pair cuts an edge pair too). :func:`wall_tempered` lowers both cells'
certainty at post-processing time, so a later press beside an earlier one lowers the earlier cell too, and eq. 6.15
then spreads the lower certainty.

:func:`reliability_table` measures calibration the usual way: cells binned by the confidence of their most probable
material, the accuracy of each bin against its mean confidence, and the expected calibration error (ECE), the
count-weighted mean gap. Cells whose top two materials tie claim nothing and are left out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.mapping.accuracy import decided_labels
from palpate.core.mapping.neighbourhood import shift_slices


def check_unit_interval(value: float, name: str) -> float:
    """A number in (0, 1] (a reliability, temperature or certainty); ValidationError naming it otherwise."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)) or not (
            np.isfinite(value) and 0 < value <= 1):
        raise ValidationError(f"{name} must be a number in (0, 1], got {value!r}")
    return float(value)


#: The settings of :class:`MapCalibration`, in the order files write them.
CALIBRATION_KEYS = ("press_temperature", "press_reliability", "extrapolation_certainty", "wall_reliability")


@dataclass(frozen=True)
class MapCalibration:
    """How far a map trusts one press and its own extrapolation; every setting in (0, 1], 1 = the seeds' maps.

    Attributes:
        press_temperature: exponent of the memory's likelihood (:func:`press_evidence`).
        press_reliability: probability that a press reads what it says (:func:`press_evidence`).
        extrapolation_certainty: share of an eq. 6.15 estimate kept per pass
            (:func:`palpate.core.mapping.extrapolation.extrapolate_plane`).
        wall_reliability: reliability of a pressed cell whose pressed edge-neighbour reads a wholly different
            material, applied when the map is post-processed (:func:`wall_tempered`; 2-D maps). A run reports,
            saves and scores the tempered map; its policies plan on the map without it.
    """

    press_temperature: float = 1.0
    press_reliability: float = 1.0
    extrapolation_certainty: float = 1.0
    wall_reliability: float = 1.0

    def __post_init__(self) -> None:
        for key in CALIBRATION_KEYS:
            check_unit_interval(getattr(self, key), key)

    def evidence(self, posterior) -> np.ndarray:
        """:func:`press_evidence` with these settings (checked once, when they were made)."""
        return _evidence(posterior, self.press_temperature, self.press_reliability)

    def to_dict(self) -> dict:
        return {key: getattr(self, key) for key in CALIBRATION_KEYS}

    @classmethod
    def from_dict(cls, doc, source: str = "<map calibration>") -> MapCalibration:
        """Settings written by :meth:`to_dict`; a missing key takes the seeds' value (1), anything else wrong is a
        ValidationError naming ``source`` and the key."""
        if not isinstance(doc, dict):
            raise ValidationError(f"{source}: expected a table of calibration settings, got {type(doc).__name__}")
        unknown = sorted(set(doc) - set(CALIBRATION_KEYS))
        if unknown:
            raise ValidationError(f"{source}: unknown calibration key(s) {unknown}")
        try:
            return cls(**doc)
        except ValidationError as exc:
            raise ValidationError(f"{source}: {exc}") from None


#: The seeds' maps: a press fuses its posterior as it is, eq. 6.15 copies its neighbours with full confidence.
SEED_CALIBRATION = MapCalibration()
#: What a scenario uses unless it says otherwise: chosen with physics presses on the tuning seeds of
#: benchmarks/exploration_families.py (walls anywhere under 10-20 mm cells), whose report-only seeds measure it;
#: the wall reliability on raster's maps of 48 tuning scenes, benchmarks/exploration_wall_sweep.py
#: (docs/results.md, "Maps beside walls").
DEFAULT_CALIBRATION = MapCalibration(press_reliability=0.94, extrapolation_certainty=0.95, wall_reliability=0.7)


def press_evidence(posterior, *, temperature: float = 1.0, reliability: float = 1.0) -> np.ndarray:
    """What one press tells a map cell, shape (M,) (or (..., M)): the memory's posterior tempered and mixed with
    a uniform misreading (module docstring). Rows sum to 1.

    Args:
        posterior: the memory's per-press posterior over the M reference materials (uniform prior).
        temperature: exponent of the likelihood, (0, 1]; 1 = as the memory says.
        reliability: probability that the press reads what it says, (0, 1]; 1 = never misreads.
    """
    temperature = check_unit_interval(temperature, "press temperature")
    reliability = check_unit_interval(reliability, "press reliability")
    return _evidence(posterior, temperature, reliability)


def _evidence(posterior, temperature: float, reliability: float) -> np.ndarray:
    """:func:`press_evidence` with checked settings; the posterior is still checked (no NaN reaches a map)."""
    p = np.asarray(posterior, dtype=float)
    # non-negative (NaN fails the comparison) and finite (an inf shows in the sum)
    if p.ndim < 1 or p.shape[-1] < 2 or not (p.min() >= 0 and math.isfinite(float(p.sum()))):
        raise ValidationError(f"press posterior must be finite probabilities over >= 2 materials, got {p!r}")
    if temperature != 1.0:
        with np.errstate(divide="ignore"):
            logp = temperature * np.log(p)
        logp -= logp.max(axis=-1, keepdims=True)
        p = np.exp(logp)
    p = p / p.sum(axis=-1, keepdims=True)
    if reliability != 1.0:
        p = reliability * p + (1.0 - reliability) / p.shape[-1]
    return p


def wall_tempered(p: np.ndarray, explored: np.ndarray, reliability: float) -> np.ndarray:
    """A 2-D map's cells with each pressed cell's certainty lowered where a pressed edge-neighbour disagrees.

    Each pressed cell c is mixed with a uniform misreading, p_c <- r_c p_c + (1 - r_c) / M, with
    r_c = 1 - (1 - reliability) D_c and D_c the largest total-variation distance, 1/2 sum_m |p_c,m - p_n,m| in
    [0, 1], between c and a pressed cell n sharing an edge with it: both sides of a wall are lowered, a cell whose
    neighbours read as it does keeps its values exactly, and an unpressed neighbour (which says nothing) counts
    for nothing. The mixing keeps each cell's most probable material.

    Args:
        p: validated probabilities, shape (ny, nx, M).
        explored: (ny, nx) mask of pressed cells.
        reliability: r_c of a cell beside a wholly different one, (0, 1]; 1 returns ``p`` itself (the seeds' maps).

    Returns:
        ``p`` when ``reliability`` is 1, else a new array.
    """
    reliability = check_unit_interval(reliability, "wall reliability")
    if reliability == 1.0:
        return p
    ny, nx = explored.shape
    d = np.zeros((ny, nx))
    for dy, dx in ((0, 1), (1, 0)):  # each edge once; both of its cells get its distance
        a, b = shift_slices(dy, dx, ny, nx)
        tv = 0.5 * np.abs(p[a] - p[b]).sum(axis=-1)
        tv *= explored[a] & explored[b]
        np.maximum(d[a], tv, out=d[a])
        np.maximum(d[b], tv, out=d[b])
    keep = (1.0 - (1.0 - reliability) * np.minimum(d, 1.0))[..., None]
    return keep * p + (1.0 - keep) / p.shape[-1]


@dataclass(frozen=True)
class ReliabilityTable:
    """Calibration of a map's most probable material over a set of cells.

    Attributes:
        edges: (B + 1,) confidence bin edges, equal widths over [0, 1].
        count: (B,) cells per bin.
        confidence: (B,) mean confidence per bin (0 where empty).
        accuracy: (B,) fraction right per bin (0 where empty).
        ece: expected calibration error, sum over bins of count * |accuracy - confidence| / total.
        cells: cells counted (decided cells with a truth).
        undecided: cells left out because their top two materials tie.
    """

    edges: np.ndarray
    count: np.ndarray
    confidence: np.ndarray
    accuracy: np.ndarray
    ece: float
    cells: int
    undecided: int

    def to_dict(self) -> dict:
        """The table as summary.json reports it."""
        return {"ece": self.ece, "cells": self.cells, "undecided_cells_left_out": self.undecided,
                "bin_edges": [float(v) for v in self.edges], "count": [int(v) for v in self.count],
                "mean_confidence": [float(v) for v in self.confidence],
                "accuracy": [float(v) for v in self.accuracy]}


def calibration_sample(p, truth) -> tuple[np.ndarray, np.ndarray, int]:
    """(confidence, right, undecided count) of every decided cell with a truth (``truth >= 0``) of probabilities
    ``p`` (cell shape + (M,)); the confidence is the most probable material's probability."""
    p = np.asarray(p, dtype=float)
    truth = np.asarray(truth)
    if truth.shape != p.shape[:-1]:
        raise ValidationError(f"truth must have the map's cell shape {p.shape[:-1]}, got {truth.shape}")
    label, decided = decided_labels(p)
    has = truth >= 0
    keep = has & decided
    return p.max(axis=-1)[keep], (label == truth)[keep], int(np.count_nonzero(has & ~decided))


def reliability_table(confidence, right, *, bins: int = 10, undecided: int = 0) -> ReliabilityTable:
    """Bin (confidence, right) pairs into ``bins`` equal-width confidence bins over [0, 1] and compute
    the ECE. Raises ValidationError for mismatched or non-finite input; an empty sample gives ece 0, cells 0."""
    conf = np.asarray(confidence, dtype=float).ravel()
    ok = np.asarray(right, dtype=bool).ravel()
    if conf.shape != ok.shape:
        raise ValidationError(f"confidence and right must have the same length, got {conf.size} and {ok.size}")
    if not np.all(np.isfinite(conf)) or (conf < 0).any() or (conf > 1 + 1e-9).any():
        raise ValidationError("confidences must be finite probabilities")
    if isinstance(bins, bool) or not isinstance(bins, (int, np.integer)) or bins < 1:
        raise ValidationError(f"bins must be an integer >= 1, got {bins!r}")
    edges = np.linspace(0.0, 1.0, bins + 1)
    which = np.clip(np.searchsorted(edges, conf, side="right") - 1, 0, bins - 1)
    count = np.bincount(which, minlength=bins)
    conf_sum = np.bincount(which, weights=conf, minlength=bins)
    right_sum = np.bincount(which, weights=ok.astype(float), minlength=bins)
    mean_conf, acc, ece = binned_calibration(count, conf_sum, right_sum)
    return ReliabilityTable(edges, count, mean_conf, acc, ece, int(count.sum()), int(undecided))


def binned_calibration(count, conf_sum, right_sum) -> tuple[np.ndarray, np.ndarray, float]:
    """(mean confidence, accuracy, ECE) of reliability bins given per bin its count, summed confidence and number
    right (0 where a bin is empty; ECE 0 with no count). Bins of several samples summed bin by bin pool them."""
    count = np.asarray(count)
    conf_sum, right_sum = np.asarray(conf_sum, dtype=float), np.asarray(right_sum, dtype=float)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean_conf = np.where(count > 0, conf_sum / np.maximum(count, 1), 0.0)
        acc = np.where(count > 0, right_sum / np.maximum(count, 1), 0.0)
    total = count.sum()
    return mean_conf, acc, float(np.sum(count * np.abs(acc - mean_conf)) / total) if total else 0.0
