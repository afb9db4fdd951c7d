"""A run's ``memory.json``, whatever judged its presses: palpate's haptic memory (format ``palpate.haptic_memory``,
:meth:`~palpate.core.perception.memory.HapticMemory.load`) or a classifier plugin (format
``palpate.classifier_memory``, :meth:`~palpate.core.perception.classifier_memory.ClassifierMemory.to_dict`).

A classifier memory file holds no model (never a pickle): names, materials and the training rows. Reading one finds
the classifier and the feature extractor again by the names the run resolved them by (:mod:`palpate.core.plugins`:
built in, ``palpate.register_classifier`` / ``register_features`` in this process, or an installed entry point),
builds the memory exactly as the run built it and fits it to the stored rows again, as the run fitted it.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from palpate.core import files, limits, plugins
from palpate.core.errors import PalpateError, ValidationError
from palpate.core.files import brief
from palpate.core.perception.classifier_memory import FORMAT_NAME as CLASSIFIER_FORMAT
from palpate.core.perception.classifier_memory import FORMAT_VERSION as CLASSIFIER_VERSION
from palpate.core.perception.classifier_memory import HAPTIC_MEMORY, ClassifierMemory, build_classifier_memory
from palpate.core.perception.feature_extractors import DEFAULT_FEATURES, extractor_name
from palpate.core.perception.memory import NO_AUDIT, HapticMemory
from palpate.core.perception.memory_file import FORMAT_NAME as HAPTIC_FORMAT

#: Longest plugin name or classifier description accepted from a file (characters): names are identifiers, and
#: a description is a short repr; anything longer is not what palpate wrote.
MAX_NAME = 200
MAX_DESCRIPTION = 20_000
_ADDRESS = re.compile(r" at 0x[0-9a-fA-F]+")
_REGISTER = {plugins.CLASSIFIERS.group: "register_classifier", plugins.FEATURES.group: "register_features"}


@dataclass(frozen=True)
class ClassifierRecord:
    """A classifier memory file's content, validated: the classifier's and feature extractor's registered names,
    the unfitted classifier's description as the run wrote it, the materials (posterior columns) and the training
    rows ``X`` (n, d; units the extractor's own) with their material labels."""

    classifier: str
    features: str
    estimator: str
    materials: tuple[str, ...]
    X: np.ndarray
    labels: tuple[str, ...]


def _name(doc: Mapping, key: str, source: str, longest: int = MAX_NAME) -> str:
    if key not in doc:
        raise ValidationError(f"{source}: missing key '{key}'")
    v = doc[key]
    if not isinstance(v, str) or not v.strip() or len(v) > longest:
        raise ValidationError(f"{source}: key '{key}' must be a non-empty string of at most {longest} characters, "
                              f"got {brief(v)}")
    return v


def _rows(value, n: int, source: str) -> np.ndarray:
    """``training.X`` as an (n, d) finite float array; each fault named by its row."""
    if not isinstance(value, list) or len(value) != n:
        raise ValidationError(f"{source}: key 'training.X' must be a list of {n} rows (one per label), got "
                              f"{brief(value)}")
    width = None
    for i, row in enumerate(value):
        if not isinstance(row, list) or not row:
            raise ValidationError(f"{source}: key 'training.X' row {i} must be a non-empty list of numbers, got "
                                  f"{brief(row)}")
        if width is not None and len(row) != width:
            raise ValidationError(f"{source}: key 'training.X' row {i} has {len(row)} values, row 0 has {width}; "
                                  "every press gives the same number of features")
        width = len(row)
        if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in row):
            raise ValidationError(f"{source}: key 'training.X' row {i} holds something other than numbers: "
                                  f"{brief(row)}")
    x = np.asarray(value, dtype=float)
    if not np.all(np.isfinite(x)):
        row = int(np.argwhere(~np.isfinite(x))[0, 0])
        raise ValidationError(f"{source}: key 'training.X' row {row} is not finite: {brief(value[row])}")
    return x


def parse_classifier_memory(doc, source: str = "<classifier memory>") -> ClassifierRecord:
    """Validate a decoded classifier memory document key by key; ValidationError naming ``source`` and the key."""
    if not isinstance(doc, Mapping):
        raise ValidationError(f"{source}: expected a JSON object, got {type(doc).__name__}")
    fmt = doc.get("format")
    if fmt != CLASSIFIER_FORMAT:
        raise ValidationError(f"{source}: key 'format' is {brief(fmt)}, expected {CLASSIFIER_FORMAT!r}")
    version = doc.get("version")
    if isinstance(version, bool) or version != CLASSIFIER_VERSION:
        raise ValidationError(f"{source}: key 'version' is {brief(version)}; this palpate reads version "
                              f"{CLASSIFIER_VERSION} of {CLASSIFIER_FORMAT}")
    classifier, features = _name(doc, "classifier", source), _name(doc, "features", source)
    estimator = _name(doc, "estimator", source, MAX_DESCRIPTION)
    params = doc.get("params", {})  # the classifier's settings as text: read by people, not by palpate
    if not isinstance(params, Mapping) or not all(isinstance(v, str) and len(v) <= MAX_DESCRIPTION
                                                  for v in params.values()):
        raise ValidationError(f"{source}: key 'params' must be an object of setting -> text, got {brief(params)}")
    materials = doc.get("materials")
    if (not isinstance(materials, list) or not materials
            or not all(isinstance(m, str) and m.strip() for m in materials) or len(set(materials)) != len(materials)):
        raise ValidationError(f"{source}: key 'materials' must be a non-empty list of distinct names, got "
                              f"{brief(materials)}")
    limits.check("materials", f"{source}: key 'materials'", len(materials))
    training = doc.get("training")
    if not isinstance(training, Mapping) or set(training) != {"X", "labels"}:
        raise ValidationError(f"{source}: key 'training' must be an object with exactly 'X' and 'labels'")
    labels = training["labels"]
    if not isinstance(labels, list) or not labels or not all(isinstance(lab, str) for lab in labels):
        raise ValidationError(f"{source}: key 'training.labels' must be a non-empty list of material names")
    unknown = sorted(set(labels) - set(materials))
    if unknown:
        raise ValidationError(f"{source}: key 'training.labels' names {brief(unknown)}, not in 'materials' "
                              f"{brief(materials)}")
    x = _rows(training["X"], len(labels), source)
    return ClassifierRecord(classifier, features, estimator, tuple(materials), x, tuple(labels))


def _resolve(registry: plugins.Registry, name: str, source: str) -> plugins.Plugin:
    try:
        return plugins.resolve(registry, name)
    except ValidationError:
        raise ValidationError(
            f"{source}: the run's {registry.what} {name!r} is neither palpate's own nor installed nor registered "
            f"here: install the package that provides it (entry-point group {registry.group!r}) or call "
            f"palpate.{_REGISTER[registry.group]}({name!r}, ...) first; known: {', '.join(plugins.names(registry))}"
        ) from None


def _plain(description: str) -> str:
    """A classifier's repr without object addresses (a callable setting prints one, different in every process)."""
    return _ADDRESS.sub("", description)


def classifier_memory_from_dict(doc, source: str = "<classifier memory>", audit: bool = True) -> ClassifierMemory:
    """Rebuild the classifier memory a run trained from its ``memory.json`` document, validating every key.

    The classifier and the feature extractor are resolved by the names the file records (ValidationError naming
    the plugin, its entry-point group and ``palpate.register_classifier`` / ``register_features`` when one
    resolves nowhere), built as the run built them and fitted to the stored training rows. A deterministic
    classifier gives the run's posteriors bit for bit; one with randomness only when its factory seeds it (e.g.
    ``random_state=0``), otherwise the refit may differ from the run's.

    Args:
        doc: the decoded JSON object.
        source: name used in error messages (usually the file path).
        audit: also require the classifier built now to describe itself (its repr, settings included) as the one
            the run trained did: a plugin changed since the run is refused.
    """
    rec = parse_classifier_memory(doc, source)
    memory = build_classifier_memory(_resolve(plugins.CLASSIFIERS, rec.classifier, source),
                                     _resolve(plugins.FEATURES, rec.features, source), rec.materials)
    name = rec.classifier
    if audit and _plain(repr(memory.estimator)) != _plain(rec.estimator):
        raise ValidationError(f"{source}: key 'estimator': the classifier {name!r} here is "
                              f"{brief(repr(memory.estimator))}, the run trained {brief(rec.estimator)}; its "
                              f"posteriors may differ from the run's ({NO_AUDIT})")
    try:
        return memory.fit(rec.X, list(rec.labels))
    except PalpateError as exc:
        raise ValidationError(f"{source}: key 'training' cannot be fitted by classifier {name!r}: {exc}") from None
    except (ValueError, TypeError, ArithmeticError) as exc:  # the plugin's own complaint about these rows
        raise ValidationError(f"{source}: key 'training' cannot be fitted by classifier {name!r}: "
                              f"{type(exc).__name__}: {exc}") from None


def load_memory(path: str | Path, audit: bool = True) -> HapticMemory | ClassifierMemory:
    """The memory a run wrote to ``path`` (its ``memory.json``), of either format, fitted and ready to judge presses.

    ``palpate.haptic_memory``: as :meth:`HapticMemory.load` (``audit``: the stored Gaussians must match a re-fit of
    the stored training parameters). ``palpate.classifier_memory``: :func:`classifier_memory_from_dict` (the plugin
    must be installed or registered; ``audit``: it must still be the classifier the run trained). A classifier with
    randomness reproduces the run's posteriors only if its factory seeds it. ValidationError naming the file and
    the key for anything wrong.
    """
    source = str(Path(path))
    doc = files.read_json(path, "memory")
    fmt = doc.get("format") if isinstance(doc, Mapping) else None
    if fmt == CLASSIFIER_FORMAT:
        return classifier_memory_from_dict(doc, source, audit)
    if fmt == HAPTIC_FORMAT:
        return HapticMemory.from_dict(doc, source, audit)
    raise ValidationError(f"{source}: key 'format' is {brief(fmt)}; a memory is {HAPTIC_FORMAT!r} (palpate's haptic "
                          f"memory) or {CLASSIFIER_FORMAT!r} (a classifier plugin's)")


def memory_algorithms(memory: HapticMemory | ClassifierMemory) -> dict:
    """What judges presses with ``memory``, as a run's summary records it: ``{"classifier": name, "features":
    name, "origins": {"classifier": ..., "features": ...}}`` (an origin is where the name resolves now:
    "palpate", "registered in process", an installed distribution, or "given in Python" when it resolves
    nowhere)."""
    if not isinstance(memory, ClassifierMemory):
        return {"classifier": HAPTIC_MEMORY, "features": DEFAULT_FEATURES,
                "origins": {"classifier": plugins.BUILTIN, "features": plugins.BUILTIN}}
    names = {"classifier": memory.label, "features": extractor_name(memory.features)}
    origins = {}
    for key, registry in (("classifier", plugins.CLASSIFIERS), ("features", plugins.FEATURES)):
        try:
            origins[key] = plugins.resolve(registry, names[key]).origin
        except ValidationError:
            origins[key] = "given in Python"
    return names | {"origins": origins}


def check_replayable(memory: HapticMemory | ClassifierMemory, voxel_maps: Sequence[str], layers: bool,
                     source: str) -> None:
    """ValidationError unless ``memory`` can judge these maps: a classifier memory judges 2-D maps only (voxel
    layers are judged by per-layer haptic memories; a run refuses such a classifier too)."""
    if not isinstance(memory, ClassifierMemory):
        return
    if layers:
        raise ValidationError(f"{source}: per-layer memories go with palpate's haptic memory; this memory is "
                              f"classifier {memory.label!r} (a run with it maps in 2-D and writes no layers)")
    if voxel_maps:
        raise ValidationError(f"{source}: voxel map(s) {brief(list(voxel_maps))} are judged layer by layer by haptic "
                              f"memories; classifier {memory.label!r} judges 2-D maps only (replay with the run's "
                              "own memory.json)")
