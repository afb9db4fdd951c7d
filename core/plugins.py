"""Plugin registries: exploration policies, classifiers, per-press feature extractors and the backends of batched
simulated presses, found by name.

A name resolves, in this order, to palpate's own (built in), to one registered in this process
(:func:`register`, e.g. ``palpate.register_policy``), or to an entry point of another installed distribution
(groups ``palpate.policies``, ``palpate.classifiers``, ``palpate.features``, ``palpate.sim_backends``). A built-in
name cannot be taken; an in-process registration shadows an entry point of the same name. What each group's objects
must be is the protocol of its module: :mod:`palpate.core.planning.registry` (policy factories),
:mod:`palpate.core.perception.classifier_memory` (classifier factories),
:mod:`palpate.core.perception.feature_extractors` (extractors), ``palpate.sim.batch.backends`` (batch physics).

The in-process registrations are the one piece of module state palpate keeps: a registry a user fills on purpose,
read wherever a name is resolved (scenario loading, a run). :func:`unregister` removes one again.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from importlib.metadata import entry_points

from palpate.core.errors import ValidationError
from palpate.core.extras import missing_extra


@dataclass(frozen=True)
class Registry:
    """One kind of plugin.

    Attributes:
        group: its entry-point group.
        what: what its plugins are, for messages ("exploration policy").
        builtin: palpate's own names (their objects are resolved by the code that uses them).
    """

    group: str
    what: str
    builtin: tuple[str, ...]


@dataclass(frozen=True)
class Plugin:
    """A resolved name: the object, and where it came from ("palpate", "registered in process", or the entry
    point's distribution, version and target)."""

    name: str
    obj: object
    origin: str


POLICIES = Registry("palpate.policies", "exploration policy",
                    ("predefined", "raster", "random", "max_entropy", "info_gain", "boundary"))
CLASSIFIERS = Registry("palpate.classifiers", "classifier", ("haptic_memory",))
FEATURES = Registry("palpate.features", "feature extractor", ("power_law",))
#: physics of a batch of simulated presses (:mod:`palpate.sim.batch`); "cpu" is palpate's numpy backend
SIM_BACKENDS = Registry("palpate.sim_backends", "batch simulation backend", ("cpu",))

_REGISTERED: dict[str, dict[str, object]] = {POLICIES.group: {}, CLASSIFIERS.group: {}, FEATURES.group: {},
                                              SIM_BACKENDS.group: {}}
BUILTIN = "palpate"
IN_PROCESS = "registered in process"


def register(registry: Registry, name: str, obj, replace: bool = False) -> None:
    """Register ``obj`` under ``name`` for this process (``replace``: over an earlier registration)."""
    if not isinstance(name, str) or not name.strip() or name != name.strip():
        raise ValidationError(f"a {registry.what} name must be a non-empty string without surrounding spaces, "
                              f"got {name!r}")
    if name in registry.builtin:
        raise ValidationError(f"{name!r} is palpate's own {registry.what}; register yours under another name")
    if obj is None or not callable(obj):
        raise ValidationError(f"the {registry.what} {name!r} must be callable, got {type(obj).__name__}")
    own = _REGISTERED[registry.group]
    if name in own and not replace and own[name] is not obj:
        raise ValidationError(f"a {registry.what} named {name!r} is already registered in this process "
                              "(replace=True replaces it)")
    own[name] = obj


def unregister(registry: Registry, name: str) -> None:
    """Remove an in-process registration (nothing happens when there is none)."""
    _REGISTERED[registry.group].pop(name, None)


def _entry_points(registry: Registry) -> Mapping[str, object]:
    return {ep.name: ep for ep in entry_points(group=registry.group)}


def names(registry: Registry) -> list[str]:
    """Every name that resolves: built in, registered in process, then installed entry points (sorted)."""
    extra = set(_REGISTERED[registry.group]) | set(_entry_points(registry))
    return list(registry.builtin) + sorted(extra - set(registry.builtin))


def resolve(registry: Registry, name: str) -> Plugin:
    """The plugin ``name`` names (a built-in's ``obj`` is None). ValidationError listing the known names for an
    unknown one; MissingExtraError naming the extra when an entry point's module needs one not installed."""
    if name in registry.builtin:
        return Plugin(name, None, BUILTIN)
    own = _REGISTERED[registry.group]
    if name in own:
        return Plugin(name, own[name], IN_PROCESS)
    ep = _entry_points(registry).get(name)
    if ep is None:
        raise ValidationError(f"unknown {registry.what} {name!r}; known: {', '.join(names(registry))} (plugins: "
                              f"entry-point group {registry.group!r} or palpate.register_*)")
    try:
        obj = ep.load()
    except ImportError as exc:
        raise missing_extra(exc, f"the {registry.what} {name!r}") from None
    dist = f"{ep.dist.name} {ep.dist.version}" if ep.dist is not None else "an installed distribution"
    return Plugin(name, obj, f"{dist} ({ep.value})")
