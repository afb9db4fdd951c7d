"""Speed against accuracy of the simulation settings (fidelity, timestep, quadrature, flex cells, taxel rate).

Thin wrapper of ``palpate bench`` (code in palpate.sim.tradeoff): prints the table, writes tradeoff.txt,
tradeoff.json and pareto.png into --out (default /tmp/palpate-bench).

    .venv/bin/python benchmarks/tradeoff.py --quick     # CI sweep, a few minutes on 2 cores
    .venv/bin/python benchmarks/tradeoff.py             # workstation sweep (every flex cell size: ~15 min)
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from palpate.sim.cli import register


def main() -> int:
    parser = argparse.ArgumentParser(prog="benchmarks/tradeoff.py")
    sub = parser.add_subparsers()
    register(sub)
    argv = ["bench", *sys.argv[1:]]
    if "--out" not in argv:
        argv += ["--out", str(Path("/tmp/palpate-bench"))]
    args = parser.parse_args(argv)
    return args.func(args)


if __name__ == "__main__":
    sys.exit(main())
