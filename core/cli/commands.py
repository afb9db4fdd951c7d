"""Command groups declared without importing them, so that ``palpate --help`` and ``palpate --version`` start fast.

An entry point of the group ``palpate.commands`` names either

- a :class:`CommandGroup`: the top-level commands it adds, each with its one-line help, and where its
  ``register(subparsers)`` function lives; that module is imported only when one of its commands runs (or shows
  its own ``--help``). The groups palpate ships are declared below: this module imports nothing of palpate, so
  loading a declaration costs nothing; or
- a plain ``register(subparsers)`` function (any third-party group): imported whenever the parser is built.

A declaration's help lines are what ``palpate --help`` lists; the register function repeats them on its own parser
(``tests/test_cli_startup.py`` keeps the two equal).
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass


@dataclass(frozen=True)
class CommandGroup:
    """Top-level commands whose parsers are built by one lazily imported function.

    Attributes:
        commands: (command name, one-line help) of every top-level command the group adds.
        register: ``"module:function"``; the function takes argparse's sub-parsers and adds exactly ``commands``.
    """

    commands: tuple[tuple[str, str], ...]
    register: str

    @property
    def names(self) -> tuple[str, ...]:
        """The top-level command names."""
        return tuple(name for name, _ in self.commands)

    def load(self):
        """Import and return the register function (ImportError when an optional extra it needs is missing)."""
        module, _, attr = self.register.partition(":")
        return getattr(importlib.import_module(module), attr)


MEMORY = CommandGroup((("memory", "train, cross-validate and show haptic memories"),),
                      "palpate.core.cli.memory:register")
RUN = CommandGroup((("run", "run a scenario: train the haptic memory, explore each object, write maps, figures and "
                     "summary.json"),), "palpate.core.cli.run:register")
REPLAY = CommandGroup((("replay", "run the perception stack on a recording and write the same maps, figures and "
                        "summary as a run"),),
                      "palpate.core.cli.replay:register")
SWEEP = CommandGroup((("sweep", "run a grid of scenario variants (local processes or Ray) and gather one table"),),
                     "palpate.core.cli.sweep:register")
SCENARIOS = CommandGroup((("scenarios", "list, show or copy the scenarios shipped with palpate"),),
                         "palpate.core.cli.scenarios:register")
HARDWARE = CommandGroup((("import", "import a device's export file into an MCAP recording"),
                         ("record", "record a live device (or its emulator) into an MCAP recording"),
                         ("devices", "find devices on a port")), "palpate.hardware.cli:register")
BENCH = CommandGroup((("bench", "measure simulation speed against accuracy (table, JSON, Pareto plot)"),),
                     "palpate.sim.cli:register")
CALIBRATE = CommandGroup((("calibrate", "fit simulation models to real data (calibrate realism)"),),
                         "palpate.sim.realism.cli:register")
