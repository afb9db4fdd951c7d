"""``palpate memory``: train, cross-validate and show haptic memories."""

from __future__ import annotations

import argparse


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``memory`` command group."""
    p = sub.add_parser("memory", help="train, cross-validate and show haptic memories")
    p.set_defaults(func=lambda a: p.print_help() or 2)
