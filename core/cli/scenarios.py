"""``palpate scenarios list|show|copy``: the scenario files shipped with palpate, to run by name or start from."""

from __future__ import annotations

import argparse
import json
import re
import shutil
import sys
from pathlib import Path

from palpate.core import files


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``scenarios`` command group."""
    p = sub.add_parser("scenarios", help="list, show or copy the scenarios shipped with palpate",
                       description="The scenario files shipped inside the package. Run one by name from any folder "
                       "(palpate run thesis_ch6), or copy it to start your own (relative paths in a copy are "
                       "rewritten to the shipped models).")
    cmds = p.add_subparsers(dest="scenarios_command", metavar="SUBCOMMAND")
    p.set_defaults(func=lambda a: p.print_help() or 2)
    ls = cmds.add_parser("list", help="names and descriptions of the shipped scenarios")
    ls.add_argument("--json", action="store_true", help="print a JSON list of {name, path, description}")
    ls.set_defaults(func=_list)
    show = cmds.add_parser("show", help="print a shipped scenario file")
    show.add_argument("name", help="scenario name, e.g. thesis_ch6 or sweeps/tiny")
    show.set_defaults(func=_show)
    cp = cmds.add_parser("copy", help="copy a shipped scenario file to edit it")
    cp.add_argument("name", help="scenario name, e.g. heterogeneous")
    cp.add_argument("dest", type=Path, help="file or folder to copy it to")
    cp.set_defaults(func=_copy)


def _list(args: argparse.Namespace) -> int:
    from palpate.core.world.resources import scenarios_dir, shipped_scenarios

    infos = shipped_scenarios()
    if args.json:
        json.dump([{"name": i.name, "path": str(i.path), "description": i.description, "kind": i.kind}
                   for i in infos], sys.stdout, indent=1)
        sys.stdout.write("\n")
        return 0
    width = max(len(i.name) for i in infos)
    # sweep files are not scenarios (palpate run refuses them): listed apart, with the command that runs them
    for i in (i for i in infos if i.kind == "scenario"):
        print(f"{i.name:<{width}}  {i.description}")
    sweeps = [i for i in infos if i.kind == "sweep"]
    if sweeps:
        print("\nsweep files (palpate run refuses them; run one with the command shown):")
        for i in sweeps:
            note = f"  ({i.description})" if i.description else ""
            print(f"{i.name:<{width}}  palpate sweep {i.path} --out DIR{note}")
    print(f"\n(files in {scenarios_dir()}; run a scenario with: palpate run NAME)")
    return 0


def _shipped(name: str) -> Path:
    from palpate.core.errors import ValidationError
    from palpate.core.world.resources import shipped_scenarios

    wanted = name.removesuffix(".toml")
    for info in shipped_scenarios():
        if info.name == wanted:
            return info.path
    raise ValidationError(f"no shipped scenario {name!r}; see palpate scenarios list")


def _show(args: argparse.Namespace) -> int:
    sys.stdout.write(_shipped(args.name).read_text(encoding="utf-8"))
    return 0


def renamed(text: str, name: str) -> str:
    """A scenario file's text with its ``[scenario]`` name set to ``name`` (a sweep file's text as it is)."""
    head = re.search(r"^\[scenario\][ \t]*$", text, flags=re.M)
    if head is None:
        return text
    tail = text[head.end():]
    nxt = re.search(r"^\[", tail, flags=re.M)
    body = tail[:nxt.start()] if nxt else tail
    new_body, n = re.subn(r'^(name[ \t]*=[ \t]*)"[^"\n]*"', lambda m: f"{m.group(1)}{json.dumps(name)}", body,
                          count=1, flags=re.M)
    if n == 0:
        new_body = f"\nname = {json.dumps(name)}" + body
    return text[:head.end()] + new_body + tail[len(body):]


def _copy(args: argparse.Namespace) -> int:
    from palpate.core.errors import ValidationError
    from palpate.core.names import check_name
    from palpate.core.world.resources import models_dir

    src = _shipped(args.name)
    dest = args.dest / src.name if args.dest.is_dir() else args.dest
    if dest.exists():
        raise ValidationError(f"{dest}: exists; not overwriting it")
    text = src.read_text(encoding="utf-8")
    # The shipped files reach the shipped models through paths relative to the scenarios folder; a copy elsewhere
    # points at the installed models instead.
    for rel in ("../models/", "models/"):
        text = text.replace(f'"{rel}', f'"{models_dir().as_posix()}/')
    # the copy is a scenario of its own: named after its file, so its default output folder is not the shipped one's
    text = renamed(text, check_name(dest.stem, f"{dest}: the copy's scenario name (its file stem)"))
    files.write_text(dest, text)
    shutil.copymode(src, dest)
    print(f"copied {args.name} to {dest}")
    return 0
