"""``palpate sweep --workers 2`` against ``--workers 1``: wall time of the whole command, as a ratio in one run.

Each repetition runs the same sweep into a fresh folder once with one worker and once with two (in alternating
order, so a drift of the machine's load touches both), and the ratio is taken pair by pair; the median of the
pairs is printed. The target (issue 11) is a ratio of at least 1.6 on ``scenarios/sweeps/thesis_policies.toml``
(six analytic variants). Run on an idle machine with two free cores: a machine whose cores are busy with other
work cannot give the second worker a core of its own, and the ratio then measures the load, not palpate.

    python benchmarks/speed_sweep.py [--sweep scenarios/sweeps/thesis_policies.toml] [--repeats 3] [--quick]
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent


def run_sweep(sweep: Path, workers: int, out: Path) -> tuple[float, float]:
    """Wall and CPU seconds (this process's children: the sweep and its workers) of one ``palpate sweep``."""
    if out.exists():
        shutil.rmtree(out)
    cmd = [sys.executable, "-c", "import sys; from palpate.core.cli import main; sys.exit(main())",
           "sweep", str(sweep), "--out", str(out), "--workers", str(workers)]
    before = os.times()
    t0 = time.perf_counter()
    done = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                          env=dict(os.environ, MPLBACKEND="Agg"))
    wall = time.perf_counter() - t0
    after = os.times()
    if done.returncode != 0:
        raise SystemExit(f"palpate sweep --workers {workers} failed ({done.returncode}): {done.stderr[-2000:]}")
    cpu = (after.children_user - before.children_user) + (after.children_system - before.children_system)
    return wall, cpu


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sweep", type=Path, default=REPO / "scenarios" / "sweeps" / "thesis_policies.toml")
    parser.add_argument("--repeats", type=int, default=3, help="pairs of runs (default 3)")
    parser.add_argument("--quick", action="store_true", help="scenarios/sweeps/tiny.toml, 2 pairs")
    args = parser.parse_args(argv)
    sweep = REPO / "scenarios" / "sweeps" / "tiny.toml" if args.quick else args.sweep
    repeats = 2 if args.quick else args.repeats
    print(f"sweep {sweep.relative_to(REPO) if sweep.is_relative_to(REPO) else sweep}: {repeats} pairs, "
          f"{os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f} at start")
    ratios, walls = [], {1: [], 2: []}
    with tempfile.TemporaryDirectory(prefix="palpate_speed_sweep_") as tmp:
        for r in range(repeats):
            order = (1, 2) if r % 2 == 0 else (2, 1)
            pair = {}
            for w in order:
                wall, cpu = run_sweep(sweep, w, Path(tmp) / f"w{w}")
                pair[w] = wall
                walls[w].append(wall)
                print(f"  pair {r + 1}: --workers {w}: {wall:6.2f} s wall, {cpu:6.2f} s CPU")
            ratios.append(pair[1] / pair[2])
    print(f"median wall: --workers 1 {statistics.median(walls[1]):.2f} s, --workers 2 "
          f"{statistics.median(walls[2]):.2f} s")
    print(f"speed-up --workers 2 / --workers 1: median {statistics.median(ratios):.2f}x over {repeats} pairs "
          f"(min {min(ratios):.2f}, max {max(ratios):.2f}); target >= 1.6x; load average "
          f"{os.getloadavg()[0]:.1f} at end")
    return 0


if __name__ == "__main__":
    sys.exit(main())
