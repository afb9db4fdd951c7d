"""The ``palpate`` command line.

Each command group lives next to the code it drives and registers itself through the entry-point group
``palpate.commands``, so that core never imports sim or hardware. A group declared as a
:class:`~palpate.core.cli.commands.CommandGroup` is imported only when one of its commands runs: ``palpate --help``
and ``palpate --version`` import no group at all (see :mod:`palpate.core.cli.commands`).
A command's handler returns an exit code. Every error a user can cause (a palpate error, a file that cannot be
read or written) is one line on stderr naming the file, key or line, with exit code 2; anything else is a bug,
reported in one line with exit code 1. ``--debug`` shows the traceback instead. Exit codes: 0 done, 1 failed (a
bug, or a sweep with failed variants), 2 a user error, 130 interrupted, 143 or 129 ended by SIGTERM or SIGHUP (a
sweep ends its workers first), 141 the reader of stdout went away.
"""

from __future__ import annotations

import argparse
import os
import sys
from importlib.metadata import entry_points

from palpate.core import __version__
from palpate.core.cli.commands import CommandGroup
from palpate.core.errors import PalpateError, Terminated
from palpate.core.extras import EXTRA_OF_MODULE, missing_extra
from palpate.core.limits import ENV as LIMITS_ENV
from palpate.core.limits import LIMITS, set_limit

COMMANDS_GROUP = "palpate.commands"


def build_parser(argv: list[str] | None = None) -> argparse.ArgumentParser:
    """Build the top-level parser for ``argv`` (default: every group's real parser).

    With ``argv``, only the group of the command it names is imported; every other declared command gets a
    placeholder parser that carries its help line for ``palpate --help``.
    """
    parser = argparse.ArgumentParser(
        prog="palpate",
        description="Haptic softness perception by press-and-release palpation: simulate, record, perceive, map.",
    )
    parser.add_argument("--version", action="version", version=f"palpate {__version__}")
    parser.add_argument("--debug", action="store_true",
                        help="show the full traceback of an error (also: environment variable PALPATE_DEBUG=1)")
    parser.add_argument("--limit", action="append", default=[], metavar="NAME=VALUE",
                        help="raise (or lower) a limit on what files may make palpate read, for this command and "
                        f"the processes it starts; names: {', '.join(LIMITS)} (docs/limits.md)")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    wanted = None if argv is None else _command_of(argv)
    for ep in sorted(entry_points(group=COMMANDS_GROUP), key=lambda e: e.name):
        try:
            group = ep.load()
        except ImportError as exc:  # an optional extra is missing: say so instead of hiding the command
            _add_unavailable(sub, (ep.name,), exc)
            continue
        if not isinstance(group, CommandGroup):
            group(sub)
        elif argv is not None and wanted not in group.names:
            for name, help_text in group.commands:
                sub.add_parser(name, help=help_text, add_help=False).set_defaults(func=_not_loaded(name))
        else:
            try:
                register = group.load()
            except ImportError as exc:
                _add_unavailable(sub, group.names, exc)
                continue
            register(sub)
    return parser


def _command_of(argv: list[str]) -> str | None:
    """The command ``argv`` names: its first word that is neither a global option nor the value of ``--limit``."""
    words = iter(argv)
    for word in words:
        if word == "--":
            return next(words, None)
        if not word.startswith("-"):
            return word
        if "=" not in word and len(word) > 3 and "--limit".startswith(word):  # argparse takes abbreviations
            next(words, None)
    return None


def _add_unavailable(sub: argparse._SubParsersAction, names, exc: ImportError) -> None:
    for name in names:
        p = sub.add_parser(name, help=f"(unavailable: {missing_extra(exc, 'it')})")
        p.set_defaults(func=_unavailable(name, exc))


def _not_loaded(name: str):
    def handler(args: argparse.Namespace) -> int:  # unreachable: the command's own group is built for its argv
        raise RuntimeError(f"the command group of {name!r} was not loaded")

    return handler


def _unavailable(name: str, exc: ImportError):
    def handler(args: argparse.Namespace) -> int:
        print(f"palpate: error: {missing_extra(exc, f'palpate {name}')}", file=sys.stderr)
        return 2

    return handler


def console() -> int:
    """The ``palpate`` console script: :func:`main` in a process of its own, in which MuJoCo, imported for the
    physics, does not load its OpenGL context (palpate never renders with it; MUJOCO_GL=disable halves
    ``import mujoco``) unless the environment asks for one."""
    os.environ.setdefault("MUJOCO_GL", "disable")
    return main()


def main(argv: list[str] | None = None) -> int:
    """The ``palpate`` command line (what the console script runs; see :func:`console`). Returns the process exit
    code."""
    argv = sys.argv[1:] if argv is None else list(argv)
    args = build_parser(argv).parse_args(argv)
    debug = args.debug or os.environ.get("PALPATE_DEBUG", "") not in ("", "0")
    saved = os.environ.get(LIMITS_ENV)
    try:
        for assignment in args.limit:
            set_limit(assignment)
        return int(args.func(args) or 0)
    except KeyboardInterrupt:
        print("palpate: interrupted", file=sys.stderr)
        return 130
    except Terminated as exc:
        print(f"palpate: terminated by {exc}", file=sys.stderr)
        return 128 + exc.signum
    except BrokenPipeError:
        # the reader of our output (``| head``) has gone: say nothing more, and let no later flush fail
        _silence_stdout()
        return 141
    except Exception as exc:
        if debug:
            raise
        code, line = error_line(exc)
        print(line, file=sys.stderr)
        return code
    finally:  # --limit holds for this command and the processes it started, not for a caller of main()
        if saved is None:
            os.environ.pop(LIMITS_ENV, None)
        else:
            os.environ[LIMITS_ENV] = saved


def error_line(exc: BaseException) -> tuple[int, str]:
    """The exit code and the one line a user sees for an exception (module docstring)."""
    if isinstance(exc, PalpateError):
        return 2, f"palpate: error: {_one_line(str(exc))}"
    if isinstance(exc, ModuleNotFoundError) and (exc.name or "").split(".")[0] in EXTRA_OF_MODULE:
        return 2, f"palpate: error: {missing_extra(exc, 'this command')}"
    if isinstance(exc, OSError) and exc.strerror:
        where = f"{exc.filename}: " if exc.filename else ""
        return 2, f"palpate: error: {where}{exc.strerror}"
    if isinstance(exc, MemoryError):
        return 2, ("palpate: error: out of memory; a file or option asks for more than this machine has "
                   "(see docs/limits.md)")
    return 1, (f"palpate: internal error: {type(exc).__name__}: {_one_line(str(exc))[:300]} (a bug in palpate: "
               "please report it; rerun with --debug for the traceback)")


def _one_line(text: str) -> str:
    return "; ".join(line.strip() for line in text.splitlines() if line.strip())


def _silence_stdout() -> None:
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):
        pass


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
