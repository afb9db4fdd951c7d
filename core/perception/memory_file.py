"""The haptic memory's JSON file: its format, and the validation of every key on read.

A memory file holds the learned parameters *and* the training data, so a stored memory can be re-fitted and
audited; nothing is ever pickled. This module turns a decoded document into a :class:`MemoryRecord` (validated
arrays, no model); :class:`~palpate.core.perception.memory.HapticMemory` builds itself from one.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from palpate.core import files, limits
from palpate.core.errors import ValidationError
from palpate.core.perception.gaussian import cholesky_checked

FORMAT_NAME = "palpate.haptic_memory"
FORMAT_VERSION = 1
#: Version 2 adds key ``features`` ("kinesthetic": no cutaneous model); a memory with both models is written as
#: version 1, and version 1 files read as "both".
FEATURES_VERSION = 2


@dataclass(frozen=True)
class MemoryRecord:
    """A memory file's content, validated: settings, learned parameters (as stored) and training data."""

    materials: tuple[str, ...]
    prior: np.ndarray
    ddof: int
    min_eig: float
    means_N: np.ndarray
    covs_N: np.ndarray
    means_A: np.ndarray
    covs_A: np.ndarray
    regularisation: dict[str, dict[str, float]]
    training_params: np.ndarray
    training_labels: tuple[str, ...]
    features: str = "both"


def read_json(path: str | Path) -> dict:
    """Decode a memory file (bounded, see :mod:`palpate.core.files`); ValidationError naming the file (and line)."""
    return files.read_json(path, "haptic memory")


def _get(doc: Mapping, key: str, source: str):
    if key not in doc:
        raise ValidationError(f"{source}: missing key '{key}'")
    return doc[key]


def _array(value, key: str, source: str, shape: tuple) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValidationError(f"{source}: key '{key}' must be an array of numbers with shape {shape}") from None
    if arr.shape != shape:
        raise ValidationError(f"{source}: key '{key}' has shape {arr.shape}, expected {shape}")
    if not np.all(np.isfinite(arr)):
        raise ValidationError(f"{source}: key '{key}' holds non-finite numbers")
    return arr


def _regularisation(reg, materials: list[str], source: str) -> dict[str, dict[str, float]]:
    if not isinstance(reg, Mapping) or set(reg) != set(materials):
        raise ValidationError(f"{source}: key 'regularisation' must map every material to {{'N': lam, 'A': lam}}")
    out = {}
    for name in materials:
        entry = reg[name]
        if not isinstance(entry, Mapping) or set(entry) != {"N", "A"}:
            raise ValidationError(f"{source}: key 'regularisation.{name}' must be {{'N': lam, 'A': lam}}")
        for part in ("N", "A"):
            v = entry[part]
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
                raise ValidationError(f"{source}: key 'regularisation.{name}.{part}' is {files.brief(v)}, expected "
                                      "a number >= 0")
        out[name] = {"N": float(entry["N"]), "A": float(entry["A"])}
    return out


def parse_memory(doc, source: str = "<memory>") -> MemoryRecord:
    """Validate a decoded memory document key by key; ValidationError naming ``source`` and the key."""
    if not isinstance(doc, Mapping):
        raise ValidationError(f"{source}: expected a JSON object, got {type(doc).__name__}")
    fmt = _get(doc, "format", source)
    if fmt != FORMAT_NAME:
        raise ValidationError(f"{source}: key 'format' is {files.brief(fmt)}, expected {FORMAT_NAME!r}")
    version = _get(doc, "version", source)
    if version not in (FORMAT_VERSION, FEATURES_VERSION):
        raise ValidationError(f"{source}: key 'version' is {files.brief(version)}; this palpate reads versions "
                              f"{FORMAT_VERSION} and {FEATURES_VERSION}")
    features = _get(doc, "features", source) if version == FEATURES_VERSION else "both"
    if features not in ("both", "kinesthetic"):
        raise ValidationError(f"{source}: key 'features' is {files.brief(features)}, expected 'both' or "
                              "'kinesthetic'")
    materials = _get(doc, "materials", source)
    if (not isinstance(materials, list) or not materials
            or not all(isinstance(m, str) and m.strip() for m in materials) or len(set(materials)) != len(materials)):
        raise ValidationError(f"{source}: key 'materials' must be a non-empty list of distinct names")
    m = len(materials)
    limits.check("materials", f"{source}: key 'materials'", m)
    ddof = _get(doc, "ddof", source)
    min_eig = _get(doc, "min_eig", source)
    if isinstance(ddof, bool) or ddof not in (0, 1):
        raise ValidationError(f"{source}: key 'ddof' is {files.brief(ddof)}, expected 0 or 1")
    if isinstance(min_eig, bool) or not isinstance(min_eig, (int, float)) or not 0 < min_eig < 1:
        raise ValidationError(f"{source}: key 'min_eig' is {files.brief(min_eig)}, expected a number in (0, 1)")
    prior = _array(_get(doc, "prior", source), "prior", source, (m,))
    if np.any(prior < 0) or not np.isclose(prior.sum(), 1.0, rtol=0, atol=1e-9):
        raise ValidationError(f"{source}: key 'prior' must be >= 0 and sum to 1, got {files.brief(prior.tolist())}")
    arrays = {}
    for key, shape in (("means_N", (m, 2)), ("means_A", (m, 2)), ("covs_N", (m, 2, 2)), ("covs_A", (m, 2, 2))):
        arrays[key] = _array(_get(doc, key, source), key, source, shape)
    for key in ("covs_N", "covs_A"):
        for k, c in enumerate(arrays[key]):
            if not np.array_equal(c, c.T):
                raise ValidationError(f"{source}: key '{key}' [{materials[k]}] is not symmetric")
            cholesky_checked(c, f"{source}: key '{key}' [{materials[k]}]")
    regularisation = _regularisation(_get(doc, "regularisation", source), materials, source)
    training = _get(doc, "training", source)
    if not isinstance(training, Mapping):
        raise ValidationError(f"{source}: key 'training' must be an object with 'params' and 'labels'")
    t_labels = _get(training, "labels", f"{source}: training")
    if not isinstance(t_labels, list) or not all(isinstance(lab, str) for lab in t_labels):
        raise ValidationError(f"{source}: key 'training.labels' must be a list of material names")
    t_params = _array(_get(training, "params", f"{source}: training"), "training.params", source, (len(t_labels), 4))
    unknown = sorted({lab for lab in t_labels if lab not in materials}, key=str)
    if unknown:
        raise ValidationError(f"{source}: key 'training.labels' names {files.brief(unknown)}, not in 'materials'")
    return MemoryRecord(tuple(materials), prior, int(ddof), float(min_eig), arrays["means_N"], arrays["covs_N"],
                        arrays["means_A"], arrays["covs_A"], regularisation, t_params, tuple(t_labels), features)
