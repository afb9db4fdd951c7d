"""Start-up cost of the ``palpate`` command and of ``import palpate``, against a bare interpreter.

Run: ``.venv/bin/python benchmarks/startup.py [--repeat N]``. Each command runs ``--repeat`` times as a child process;
the table prints the median CPU time (user + system, the operating system's accounting of the finished child) and
its ratio to the plain reference measured in the same run: ``python -c "import argparse"`` (what any command-line
tool pays before it does anything). ``palpate --help`` and ``--version`` import no command group (their parsers are
declared, see ``core/cli/commands.py``); ``palpate scenarios list`` imports one group; ``import palpate`` imports
nothing of the API until a name is used.
"""

from __future__ import annotations

import argparse
import resource
import statistics
import subprocess
import sys

CLI = "import sys; from palpate.core.cli import main; sys.exit(main())"
COMMANDS = {
    "python -c 'import argparse' (reference)": [sys.executable, "-c", "import argparse"],
    "palpate --help": [sys.executable, "-c", CLI, "--help"],
    "palpate --version": [sys.executable, "-c", CLI, "--version"],
    "palpate scenarios list": [sys.executable, "-c", CLI, "scenarios", "list"],
    "import palpate; palpate.__version__": [sys.executable, "-c", "import palpate; palpate.__version__"],
    "import palpate.sim (the simulator a run loads)": [sys.executable, "-c", "import palpate.sim"],
    "import numpy (for scale)": [sys.executable, "-c", "import numpy"],
}


def child_cpu(cmd: list[str]) -> float:
    """CPU seconds (user + system) of one run of ``cmd``."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=7, help="runs per command (median reported)")
    args = ap.parse_args()
    medians = {}
    for name, cmd in COMMANDS.items():
        child_cpu(cmd)  # warm the file cache
        medians[name] = statistics.median(child_cpu(cmd) for _ in range(args.repeat))
    ref = medians[next(iter(COMMANDS))]
    print(f"{'command':<42} {'cpu s (median)':>14} {'x reference':>12}")
    for name, t in medians.items():
        print(f"{name:<42} {t:14.3f} {t / ref:12.1f}")


if __name__ == "__main__":
    main()
