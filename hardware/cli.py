"""Hardware command groups: ``palpate import``, ``palpate record``, ``palpate devices``.

Each device subpackage exposes ``register_cli(groups)`` and adds its own sub-commands to the shared groups
(``groups["import"]``, ``groups["record"]``, ``groups["devices"]`` are argparse sub-parser collections).
Device libraries (pyserial, dynamixel-sdk) are imported only when a command runs.
"""

from __future__ import annotations

import argparse
import importlib

DEVICE_MODULES = ("palpate.hardware.tekscan", "palpate.hardware.polhemus", "palpate.hardware.dynamixel",
                  "palpate.hardware.rig")


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``import``, ``record`` and ``devices`` command groups with every device's sub-commands."""
    groups = {}
    for name, help_text in (
        ("import", "import a device's export file into an MCAP recording"),
        ("record", "record a live device (or its emulator) into an MCAP recording"),
        ("devices", "find devices on a port"),
    ):
        parser = sub.add_parser(name, help=help_text)
        parser.set_defaults(func=lambda a, p=parser: p.print_help() or 2)
        groups[name] = parser.add_subparsers(dest=f"{name}_kind", metavar="KIND")
    for module_name in DEVICE_MODULES:
        module = importlib.import_module(module_name)
        register_cli = getattr(module, "register_cli", None)
        if register_cli is not None:
            register_cli(groups)
