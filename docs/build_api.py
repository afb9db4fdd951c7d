"""Build the API reference (HTML) from the docstrings of palpate's public API with pdoc; any warning fails it.

    .venv/bin/python docs/build_api.py OUT_DIR

Needs the ``docs`` extra (pdoc) and the ``sim`` and ``gym`` extras (the reference imports palpate.sim and
palpate.gym). Documented: the modules of :data:`MODULES` (the names docs/api.md gives, the plugin protocols, the
estimators, the simulated press and the Gymnasium environment), not every internal module. A warning from pdoc
(an unresolved annotation, a docstring it cannot parse, a module it cannot import) or from an import it triggers
is printed and the build exits 1, so CI keeps the reference clean.
"""

from __future__ import annotations

import argparse
import importlib
import sys
import warnings
from pathlib import Path

#: modules of the reference; a package's submodules are left out unless listed
MODULES = (
    "palpate",
    "palpate.api",
    "palpate.gym",
    "palpate.sim",
    "palpate.core.errors",
    "palpate.core.world.scenario",
    "palpate.core.session.training",
    "palpate.core.session.explore_env",
    "palpate.core.perception.streams",
    "palpate.core.perception.press",
    "palpate.core.perception.memory",
    "palpate.core.perception.classifier_memory",
    "palpate.core.perception.memory_loading",
    "palpate.core.perception.layered_estimator",
    "palpate.core.perception.crossval",
    "palpate.core.perception.feature_extractors",
    "palpate.core.planning.registry",
    "palpate.core.planning.policies",
)


def specs() -> list[str]:
    """pdoc's module specs: each module, then a pattern that drops its submodules (pdoc walks a package's)."""
    out: list[str] = []
    for name in MODULES:
        out += [name, f"!{name.replace('.', '[.]')}[.].*"]
    return out


def resolve_exports() -> None:
    """Import every name of ``palpate.__all__``: the package imports them on first use, and pdoc documents a
    module's ``__all__`` from what its namespace holds."""
    import palpate

    for name in palpate.__all__:
        getattr(palpate, name)


def build(out: Path) -> list[str]:
    """Write the reference into ``out``; returns the warnings raised meanwhile (formatted, one per entry)."""
    import pdoc
    import pdoc.render

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for name in MODULES:
            importlib.import_module(name)
        resolve_exports()
        pdoc.render.configure(docformat="google", show_source=False, footer_text="palpate")
        pdoc.pdoc(*specs(), output_directory=out)
    return [f"{w.filename}:{w.lineno}: {w.category.__name__}: {w.message}" for w in caught]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path, help="folder to write the HTML into (created if missing)")
    args = parser.parse_args(argv)
    problems = build(args.out)
    for line in problems:
        print(line, file=sys.stderr)
    if problems:
        print(f"API reference: {len(problems)} warning(s); fix the docstrings or annotations named above",
              file=sys.stderr)
        return 1
    print(f"API reference: {len(MODULES)} modules written to {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
