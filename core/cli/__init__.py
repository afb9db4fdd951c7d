"""The ``palpate`` command line.

Each command group lives next to the code it drives and registers itself through the entry-point group
``palpate.commands`` (a function ``register(subparsers)``), so that core never imports sim or hardware.
A command's handler returns an exit code; palpate errors become a one-line message and exit code 2.
"""

from __future__ import annotations

import argparse
import sys
from importlib.metadata import entry_points

from palpate.core import __version__
from palpate.core.errors import PalpateError
from palpate.core.extras import EXTRA_OF_MODULE, missing_extra

COMMANDS_GROUP = "palpate.commands"


def build_parser() -> argparse.ArgumentParser:
    """Build the top-level parser with every registered command group."""
    parser = argparse.ArgumentParser(
        prog="palpate",
        description="Haptic softness perception by press-and-release palpation: simulate, record, perceive, map.",
    )
    parser.add_argument("--version", action="version", version=f"palpate {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for ep in sorted(entry_points(group=COMMANDS_GROUP), key=lambda e: e.name):
        try:
            register = ep.load()
        except ImportError as exc:  # an optional extra is missing: say so instead of hiding the command
            p = sub.add_parser(ep.name, help=f"(unavailable: {missing_extra(exc, 'it')})")
            p.set_defaults(func=_unavailable(ep.name, exc))
            continue
        register(sub)
    return parser


def _unavailable(name: str, exc: ImportError):
    def handler(args: argparse.Namespace) -> int:
        print(f"palpate: error: {missing_extra(exc, f'palpate {name}')}", file=sys.stderr)
        return 2

    return handler


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``palpate`` console script. Returns the process exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except PalpateError as exc:
        print(f"palpate: error: {exc}", file=sys.stderr)
        return 2
    except ModuleNotFoundError as exc:
        if (exc.name or "").split(".")[0] not in EXTRA_OF_MODULE:
            raise
        print(f"palpate: error: {missing_extra(exc, f'palpate {args.command}')}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("palpate: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
