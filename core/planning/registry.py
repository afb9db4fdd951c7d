"""Policies by name, and the stop rules of an exploration.

:data:`POLICY_NAMES` is the one list of policy names (the scenario schema and the command line take it from here).
"""

from __future__ import annotations

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.mapping.probability import entropy_unchecked
from palpate.core.planning.info_gain import InfoGain
from palpate.core.planning.policies import MaxEntropy, Predefined, RandomCells, Raster

POLICY_NAMES = ("predefined", "raster", "random", "max_entropy", "info_gain")


def make_policy(name: str, *, cells: list[tuple[int, int]] | None = None, repeats: int = 1, seed: int = 0,
                stride: int = 1, memory=None, travel_cost_per_mm: float = 0.0, max_depth: float | None = None,
                samples_per_material: int = 6, passes: int | None = 1, objective: str = "accuracy",
                feature_size: float | None = None, certainty: float = 1.0, lateral: bool = False):
    """Build a policy by name (one of :data:`POLICY_NAMES`); ``predefined`` needs ``cells``, ``info_gain`` a
    trained ``memory``; ``passes``, ``certainty`` and ``lateral`` are the post-processing's (see
    ``Grid2D.postprocessed`` and ``VoxelGrid.postprocessed``);
    ``objective`` and ``feature_size`` (m, the belief's correlation length; None = one cell) are info_gain's (see
    :class:`InfoGain`)."""
    if not (np.isfinite(travel_cost_per_mm) and travel_cost_per_mm >= 0):
        raise ValidationError(f"travel_cost_per_mm must be a finite number >= 0, got {travel_cost_per_mm!r}")
    if name == "predefined":
        return Predefined(list(cells or []), repeats)
    if name == "raster":
        return Raster(stride)
    if name == "random":
        return RandomCells(seed)
    if name == "max_entropy":
        return MaxEntropy(travel_cost_per_mm, max_depth, passes, certainty, lateral)
    if name == "info_gain":
        if memory is None:
            raise ValidationError("the info_gain policy needs a trained haptic memory")
        return InfoGain(memory, travel_cost_per_mm, max_depth, samples_per_material, seed, passes,
                        objective=objective, correlation_mm=None if feature_size is None else feature_size * 1e3,
                        certainty=certainty, lateral=lateral)
    raise ValidationError(f"unknown exploration policy {name!r}; known: {', '.join(POLICY_NAMES)}")


def stop_reason(post, *, mean_entropy: float | None = None, max_entropy: float | None = None) -> str | None:
    """Which entropy stop rule the post-processed map meets ("mean_entropy" or "max_entropy"), or None.

    Args:
        post: the post-processed map (the one the run reports).
        mean_entropy: stop once the mean cell entropy is at most this (map's base units).
        max_entropy: stop once every cell's entropy is at most this.
    """
    if mean_entropy is None and max_entropy is None:
        return None
    h = entropy_unchecked(np.asarray(post.probabilities), post.base)
    if mean_entropy is not None and float(h.mean()) <= mean_entropy:
        return "mean_entropy"
    if max_entropy is not None and float(h.max()) <= max_entropy:
        return "max_entropy"
    return None
