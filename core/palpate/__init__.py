"""palpate: haptic softness perception by press-and-release palpation, simulated or real.

The public API (``docs/api.md``), all in SI units (m, N, s, Pa)::

    import palpate
    scenario = palpate.load_scenario("sweeps/tiny_base")          # a shipped name or a .toml path
    one = palpate.press(scenario, "Block", cell=(1, 1))            # frames, poses, truth, fitted parameters
    training = palpate.train_memory(scenario)                      # memory, leave-one-out, every press
    result = palpate.run(scenario, "runs/tiny", policy="random")   # what ``palpate run`` writes

Every name is imported on first use, so ``import palpate`` costs nothing and never loads the simulator; the
subpackages are :mod:`palpate.core` (perception, maps, planning, run loop), :mod:`palpate.sim` and
:mod:`palpate.hardware`. This package lives in ``core/palpate/`` of the source tree (see setup.py).
"""

from __future__ import annotations

import importlib

#: public name -> module that defines it
_EXPORTS = {
    "__version__": "palpate.core",
    "load_scenario": "palpate.api",
    "press": "palpate.api",
    "PressOutcome": "palpate.api",
    "train_memory": "palpate.api",
    "run": "palpate.api",
    "RunResult": "palpate.api",
    "with_settings": "palpate.api",
    "register_policy": "palpate.api",
    "register_classifier": "palpate.api",
    "register_features": "palpate.api",
    "unregister": "palpate.api",
    "available": "palpate.api",
    "PolicyContext": "palpate.core.planning.registry",
    "Policy": "palpate.core.planning.registry",
    "PolicyFactory": "palpate.core.planning.registry",
    "Target": "palpate.core.planning.policies",
    "ClassifierFactory": "palpate.core.perception.classifier_memory",
    "FeatureExtractor": "palpate.core.perception.feature_extractors",
    "Scenario": "palpate.core.world.scenario",
    "TrainingResult": "palpate.core.session.training",
    "HapticMemory": "palpate.core.perception.memory",
    "ClassifierMemory": "palpate.core.perception.classifier_memory",
    "load_memory": "palpate.core.perception.memory_loading",
    "LayeredMemoryClassifier": "palpate.core.perception.layered_estimator",
    "CrossValidation": "palpate.core.perception.crossval",
    "PressRecording": "palpate.core.perception.streams",
    "PressResult": "palpate.core.perception.press",
    "PalpateError": "palpate.core.errors",
    "ValidationError": "palpate.core.errors",
}

__all__ = sorted(_EXPORTS)
#: submodules reached as attributes too, imported on first use (not in __all__: ``palpate.gym`` needs gymnasium)
_SUBMODULES = ("gym",)


def __getattr__(name: str):
    if name in _SUBMODULES:
        return importlib.import_module(f"palpate.{name}")
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'palpate' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value  # later look-ups skip this function
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_EXPORTS) | set(_SUBMODULES))
