"""Policies by name (palpate's own and plugins), and the stop rules of an exploration.

:data:`POLICY_NAMES` are palpate's own policies; :func:`policy_names` adds the plugins (entry-point group
``palpate.policies`` and ``palpate.register_policy``), which the scenario schema accepts too. A plugin is a
:class:`PolicyFactory`: called once per explored object with a :class:`PolicyContext`, it returns a :class:`Policy`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from palpate.core import plugins
from palpate.core.errors import ValidationError
from palpate.core.mapping.geometry import MapGeometry
from palpate.core.mapping.probability import entropy_unchecked
from palpate.core.planning.boundary_seeking import BoundarySeeking
from palpate.core.planning.info_gain import InfoGain
from palpate.core.planning.policies import MaxEntropy, Predefined, RandomCells, Raster, Target

POLICY_NAMES = plugins.POLICIES.builtin


@runtime_checkable
class Policy(Protocol):
    """Where to press next (:mod:`palpate.core.planning.policies` describes the contract in full)."""

    def next_target(self, grid, post=None, last=None) -> Target | None:  # pragma: no cover - protocol
        """The next column to press, given the map as measured (``grid``: ``probabilities`` (ny, nx, M) or voxels
        (nx, ny, nz, M), ``explored``), its post-processed version ``post`` and the previous press's (ix, iy) ``last``;
        None when there is nothing left to press."""
        ...


@dataclass(frozen=True)
class PolicyContext:
    """What a policy plugin is built from, once per explored object.

    Attributes:
        name: the name it was asked for by.
        geometry: the object's map (shape, cell size m, origin m, 2-D or voxel).
        seed: the object's seed (a random policy draws from it).
        memory: the run's trained memory (``predict_proba``, ``materials``).
        regions: the scenario's predefined cells of the object, 0-based (ix, iy).
        budget: the press budget (``exploration.budget``).
        depth: the planned press depth, m.
        moduli: the reference materials' moduli as boundary readings read them (from the training presses), or
            None (:mod:`palpate.core.boundary.moduli`).
    """

    name: str
    geometry: MapGeometry
    seed: int
    memory: object
    regions: tuple[tuple[int, int], ...]
    budget: int
    depth: float
    moduli: object | None = None


class PolicyFactory(Protocol):
    """A policy plugin: ``factory(context) -> Policy`` (a class whose constructor takes the context will do)."""

    def __call__(self, context: PolicyContext) -> Policy:  # pragma: no cover - protocol
        ...


def policy_names() -> list[str]:
    """Every policy a scenario may name: palpate's own, then the plugins."""
    return plugins.names(plugins.POLICIES)


def build_policy(context: PolicyContext, **builtin_settings) -> tuple[Policy, plugins.Plugin]:
    """The policy ``context.name`` names and where it came from: palpate's own through :func:`make_policy` with
    ``builtin_settings``, a plugin through its factory (checked to have ``next_target``)."""
    found = plugins.resolve(plugins.POLICIES, context.name)
    if found.obj is None:
        return make_policy(context.name, **builtin_settings), found
    policy = found.obj(context)
    if not callable(getattr(policy, "next_target", None)):
        raise ValidationError(f"exploration policy {context.name!r} ({found.origin}): its factory returned "
                              f"{type(policy).__name__}, which has no next_target(grid, post, last) method")
    return policy, found


def make_policy(name: str, *, cells: list[tuple[int, int]] | None = None, repeats: int = 1, seed: int = 0,
                stride: int = 1, memory=None, travel_cost_per_mm: float = 0.0, max_depth: float | None = None,
                samples_per_material: int = 6, passes: int | None = 1, objective: str = "accuracy",
                feature_size: float | None = None, certainty: float = 1.0, lateral: bool = False,
                geometry: MapGeometry | None = None, moduli=None):
    """Build a policy by name (one of :data:`POLICY_NAMES`); ``predefined`` needs ``cells``, ``info_gain`` a
    trained ``memory``, ``boundary`` a trained ``memory`` and the 2-D map's ``geometry`` (``moduli``: see
    :class:`PolicyContext`); ``passes``, ``certainty`` and ``lateral`` are the post-processing's (see
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
    if name == "boundary":
        if memory is None or geometry is None:
            raise ValidationError("the boundary policy needs a trained haptic memory and the map's geometry")
        return BoundarySeeking(memory, geometry, moduli, travel_cost_per_mm, passes=passes, certainty=certainty,
                               seed=seed)
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
