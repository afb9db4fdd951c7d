"""The API reference's modules import and carry docstrings: every module docs/build_api.py documents, every public
function, class and method defined in it, and every name docs/api.md gives (``palpate.X`` and the top-level names)
resolves and has its own docstring. The HTML build itself runs in CI (docs/build_api.py, pdoc warnings fail it)."""

from __future__ import annotations

import importlib
import importlib.util
import inspect
import re
from pathlib import Path

import pytest

import palpate

DOCS = Path(__file__).resolve().parents[1] / "docs"
#: modules of optional extras, skipped (naming the extra) when it is not installed
EXTRA_MODULES = {"palpate.gym": "gymnasium", "palpate.core.session.explore_env": "gymnasium"}
#: entry-point groups docs/api.md names: not importable names
ENTRY_POINT_GROUPS = {"palpate.policies", "palpate.classifiers", "palpate.features", "palpate.commands",
                      "palpate.sources", "palpate.actuators", "palpate.sim_backends"}


def _build_api():
    spec = importlib.util.spec_from_file_location("build_api", DOCS / "build_api.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


MODULES = _build_api().MODULES


def _import(name: str):
    extra = EXTRA_MODULES.get(name)
    if extra is not None:
        pytest.importorskip(extra, reason=f"{name} needs the {extra!r} extra")
    return importlib.import_module(name)


def own_doc(obj) -> str:
    """obj's own docstring: not inherited, and not the signature a dataclass writes when there is none."""
    doc = (obj.__doc__ or "").strip()
    if inspect.isclass(obj) and doc.startswith(f"{obj.__name__}("):
        return ""
    return doc


def undocumented(module) -> list[str]:
    """Public functions, classes and their public methods and properties defined in ``module`` without a docstring."""
    names = getattr(module, "__all__", None) or [n for n in vars(module) if not n.startswith("_")]
    missing = []
    for name in names:
        obj = getattr(module, name)
        if not (inspect.isfunction(obj) or inspect.isclass(obj)) or obj.__module__ != module.__name__:
            continue
        if not own_doc(obj):
            missing.append(name)
        if inspect.isclass(obj):
            for attr, value in vars(obj).items():
                func = value.fget if isinstance(value, property) else getattr(value, "__func__", value)
                if not attr.startswith("_") and inspect.isfunction(func) and not own_doc(func):
                    missing.append(f"{name}.{attr}")
    return missing


def test_undocumented_finds_a_missing_docstring():
    class Holder:
        """A module stand-in."""

    fake = type(inspect)("fake_module")
    exec("def documented():\n    '''Yes.'''\n\ndef bare():\n    pass\n", fake.__dict__)
    assert undocumented(fake) == ["bare"]
    assert own_doc(Holder) == "A module stand-in."


@pytest.mark.parametrize("name", MODULES)
def test_documented_module_imports_with_docstrings(name):
    module = _import(name)
    assert own_doc(module), f"{name} has no module docstring"
    assert undocumented(module) == [], f"{name}: public names without a docstring"


def _resolve(dotted: str):
    """The object a dotted ``palpate.…`` name denotes: the longest importable module, then attributes."""
    parts = dotted.split(".")
    for cut in range(len(parts), 0, -1):
        module_name = ".".join(parts[:cut])
        if module_name in EXTRA_MODULES:
            _import(module_name)
        try:
            obj = importlib.import_module(module_name)
        except ModuleNotFoundError:
            continue
        for attr in parts[cut:]:
            obj = getattr(obj, attr)
        return obj
    raise AssertionError(f"docs/api.md names {dotted}, which does not resolve")


def api_md_names() -> list[str]:
    """Dotted ``palpate.…`` names in docs/api.md (entry-point groups left out) and the top-level names it uses."""
    text = (DOCS / "api.md").read_text()
    dotted = {m.rstrip(".") for m in re.findall(r"\bpalpate(?:\.\w+)+", text)} - ENTRY_POINT_GROUPS
    bare = {f"palpate.{name}" for name in palpate.__all__ if re.search(rf"\b{re.escape(name)}\b", text)}
    return sorted(dotted | bare)


def test_api_md_names_the_public_api():
    names = api_md_names()
    for expected in ("palpate.load_scenario", "palpate.press", "palpate.run", "palpate.HapticMemory",
                     "palpate.register_policy", "palpate.sim.simulate_press"):
        assert expected in names


@pytest.mark.parametrize("dotted", api_md_names())
def test_every_name_in_api_md_resolves_and_has_a_docstring(dotted):
    obj = _resolve(dotted)
    if inspect.isfunction(obj) or inspect.isclass(obj) or inspect.ismodule(obj):
        assert own_doc(obj), f"docs/api.md names {dotted}, which has no docstring"
