"""The layout's rules, checked on the source: core never imports sim or hardware, no import loop anywhere (also not
one hidden in a function), every module importable on its own and no module grown past the size a reader can hold."""

from __future__ import annotations

import ast
import importlib
from pathlib import Path

import pytest

from palpate.core.extras import MissingExtraError

REPO = Path(__file__).resolve().parent.parent
TOPS = ("core", "sim", "hardware")
#: A module past this many lines holds more than one concern; split it.
MAX_LINES = 450


#: The top-level package ``palpate`` (the public API) lives in this folder (setup.py).
API = REPO / "core" / "palpate"


def _modules() -> dict[str, Path]:
    out = {}
    for top in TOPS:
        for path in (REPO / top).rglob("*.py"):
            rel = path.relative_to(API if path.is_relative_to(API) else REPO).with_suffix("")
            parts = ["palpate", *rel.parts]
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join(parts)] = path
    return out


MODULES = _modules()


def _imports(path: Path, name: str) -> set[str]:
    """palpate modules ``path`` imports, at any depth of the file (functions included)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    package = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(parts + ([base] if base else []))
            for alias in node.names:
                for cand in (f"{base}.{alias.name}", base):
                    if cand in MODULES:
                        found.add(cand)
                        break
        elif isinstance(node, ast.Import):
            found.update(a.name for a in node.names if a.name in MODULES)
    found.discard(name)
    return found


GRAPH = {name: _imports(path, name) for name, path in MODULES.items()}


def test_core_never_imports_sim_or_hardware():
    # the public API (the package palpate itself) reaches the simulator only through the source registry, as core does
    bad = sorted((m, d) for m, deps in GRAPH.items() if m.startswith("palpate.core") or MODULES[m].is_relative_to(API)
                 for d in deps if d.startswith(("palpate.sim", "palpate.hardware")))
    assert not bad, f"core imports sim/hardware: {bad}"


def test_sim_never_imports_hardware():
    bad = sorted((m, d) for m, deps in GRAPH.items() if m.startswith("palpate.sim") for d in deps
                 if d.startswith("palpate.hardware"))
    assert not bad, f"sim imports hardware: {bad}"


def test_no_import_loop_even_inside_functions():
    # A package's __init__ may re-export its own modules; an edge into a package means its __init__ only.
    state: dict[str, int] = {}
    stack: list[str] = []
    loops = []

    def visit(m: str) -> None:
        state[m] = 1
        stack.append(m)
        for d in sorted(GRAPH[m]):
            if state.get(d) == 1:
                loops.append(stack[stack.index(d):] + [d])
            elif d not in state:
                visit(d)
        stack.pop()
        state[m] = 2

    for m in sorted(GRAPH):
        if m not in state:
            visit(m)
    assert not loops, "import loops:\n" + "\n".join(" -> ".join(loop) for loop in loops)


@pytest.mark.parametrize("name", sorted(n for n in MODULES if not n.endswith("emulator")))
def test_every_module_imports_on_its_own(name):
    pytest.importorskip("mujoco") if name.startswith("palpate.sim") else None
    try:
        importlib.import_module(name)
    except MissingExtraError as exc:  # a module of an extra that is not installed says so, by name
        assert "pip install" in str(exc)
        pytest.skip(str(exc))


def test_no_module_is_too_long_to_read():
    long = sorted((str(p.relative_to(REPO)), n) for p in MODULES.values()
                  if (n := len(p.read_text(encoding="utf-8").splitlines())) > MAX_LINES)
    assert not long, f"modules over {MAX_LINES} lines (split them by concern): {long}"
