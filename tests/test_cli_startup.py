"""Start-up: ``palpate --help`` and ``--version`` import no command group (nor numpy, nor the simulator), a command
imports only its own group, and every declared help line is the one its group registers."""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from importlib.metadata import entry_points

import pytest

from palpate.core.cli import COMMANDS_GROUP, _command_of, main
from palpate.core.cli.commands import CommandGroup

#: Runs the command line in a fresh interpreter and prints the modules it imported, as JSON, on stderr.
PROBE = ("import json, sys\nfrom palpate.core.cli import main\ntry:\n    code = main(sys.argv[1:])\n"
         "except SystemExit as exc:\n    code = exc.code\n"
         "print(json.dumps(sorted(sys.modules)), file=sys.stderr)\nsys.exit(code or 0)")


def _imported(*argv: str) -> tuple[str, set[str]]:
    proc = subprocess.run([sys.executable, "-c", PROBE, *argv], capture_output=True, text=True, timeout=120)
    return proc.stdout, set(json.loads(proc.stderr.strip().splitlines()[-1]))


def _declared() -> dict[str, CommandGroup]:
    return {ep.name: ep.load() for ep in entry_points(group=COMMANDS_GROUP)}


@pytest.mark.parametrize("flag", ["--help", "--version"])
def test_help_and_version_import_no_command_group(flag):
    out, modules = _imported(flag)
    heavy = sorted(m for m in modules if m.split(".")[0] in ("numpy", "scipy", "mujoco")
                   or m.startswith(("palpate.sim", "palpate.hardware", "palpate.core.cli.")) and
                   m != "palpate.core.cli.commands")
    assert not heavy, f"palpate {flag} imported {heavy[:10]}"
    if flag == "--version":
        from palpate.core import __version__

        assert out.strip() == f"palpate {__version__}"
    else:
        for group in _declared().values():
            for name, _ in group.commands:
                assert name in out


def test_a_command_imports_only_its_own_group():
    out, modules = _imported("scenarios", "list")
    assert "thesis_ch6" in out
    assert "palpate.core.cli.scenarios" in modules
    assert not {"palpate.core.cli.memory", "palpate.core.cli.run", "palpate.hardware.cli", "palpate.sim.cli"} & modules


def test_declared_help_lines_are_the_registered_ones():
    for ep_name, group in _declared().items():
        assert isinstance(group, CommandGroup), ep_name
        try:
            register = group.load()
        except ImportError as exc:  # an optional extra of that group is not installed here
            pytest.skip(f"{ep_name}: {exc}")
        parser = argparse.ArgumentParser()
        sub = parser.add_subparsers()
        register(sub)
        registered = {a.dest: a.help for a in sub._choices_actions}
        assert registered == dict(group.commands), ep_name


def test_the_command_word_is_found_after_global_options():
    assert _command_of(["--debug", "--limit", "map_cells=10", "run", "x"]) == "run"
    assert _command_of(["--lim", "map_cells=10", "memory"]) == "memory"  # an abbreviation takes its value too
    assert _command_of(["--limit=map_cells=10", "replay"]) == "replay"
    assert _command_of(["--", "sweep"]) == "sweep"
    assert _command_of(["--help"]) is None


def test_unknown_command_still_lists_every_command(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["spiral"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "invalid choice: 'spiral'" in err and "'memory'" in err and "'bench'" in err


@pytest.mark.parametrize(("preset", "expected"), [(None, "disable"), ("egl", "egl")])
def test_the_console_script_loads_no_opengl_context_unless_asked(preset, expected):
    import os

    # the installed console script is the entry point pyproject names; its process imports MuJoCo without GLFW
    (script,) = [ep for ep in entry_points(group="console_scripts") if ep.name == "palpate"]
    assert script.value == "palpate.core.cli:console"
    probe = ("import json, os, sys\nfrom palpate.core.cli import console\nsys.argv = ['palpate', '--version']\n"
             "try:\n    console()\nexcept SystemExit:\n    pass\nimport mujoco\n"
             "print(json.dumps([os.environ['MUJOCO_GL'], 'glfw' in sys.modules]), file=sys.stderr)")
    env = {k: v for k, v in os.environ.items() if k != "MUJOCO_GL"} | ({} if preset is None else {"MUJOCO_GL": preset})
    proc = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120, env=env)
    gl, glfw = json.loads(proc.stderr.strip().splitlines()[-1])
    assert gl == expected and not glfw
