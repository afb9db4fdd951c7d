"""``palpate sweep SWEEP.toml --out DIR [--ray auto|ADDRESS] [--workers N]``: run a grid of scenario variants."""

from __future__ import annotations

import argparse
import os
from pathlib import Path


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``sweep`` command."""
    p = sub.add_parser(
        "sweep", help="run a grid of scenario variants (local processes or Ray) and gather one table",
        description="Run every variant of a sweep file into DIR/runs/<variant>/ and gather DIR/sweep.csv and "
        "DIR/sweep.json. Finished runs are kept: re-running an interrupted sweep only runs what is missing.",
    )
    p.add_argument("sweep", type=Path, help="sweep file (TOML), e.g. scenarios/sweeps/thesis_fidelity.toml")
    p.add_argument("--out", type=Path, required=True, help="output folder")
    p.add_argument("--workers", type=int, default=min(2, os.cpu_count() or 1),
                   help="local processes (default: up to 2)")
    p.add_argument("--ray", default=None, metavar="auto|ADDRESS",
                   help="run on Ray: 'auto' (a running cluster, else a local instance) or a cluster address")
    p.set_defaults(func=_sweep)


def _sweep(args: argparse.Namespace) -> int:
    from palpate.core.session.sweep import load_sweep, run_sweep

    sweep = load_sweep(args.sweep)
    rows = run_sweep(sweep, args.out, workers=args.workers, ray=args.ray)
    failed = [r for r in rows if not str(r.get("status", "")).startswith("done")]
    print(f"{len(rows) - len(failed)}/{len(rows)} variants finished; table: {args.out / 'sweep.csv'}")
    for r in failed:
        print(f"  {r['variant']}: {r['status']}")
    return 1 if failed else 0
