"""``palpate sweep --workers 2`` against ``--workers 1``: wall time of the whole command, as a ratio in one run.

Each repetition runs the same sweep into a fresh folder once with one worker and once with two (in alternating
order, so a drift of the machine's load touches both), and the ratio is taken pair by pair; the median of the
pairs is printed. The target is a ratio of at least 1.6 on ``scenarios/sweeps/thesis_policies.toml``
(six analytic variants).

The wall ratio can only show a speed-up where the second worker gets a core of its own. So the script also
measures where the CPU time goes (Linux: each worker's CPU seconds read from /proc while the sweep runs; the
sweep process's own from the total) and prints the ratio two free cores would give: the one-worker sweep's CPU
time over the two-worker sweep's critical path (the sweep process's CPU plus its busiest worker's). Before the
pairs it runs a control: one busy loop, then two at once, which shows how much CPU this machine gives the
benchmark's processes together (on a shared machine capped at a third of a core, two processes run no faster
than one, whatever palpate does).

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
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
TICK = os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100
SPIN = "n = 0\nwhile n < 5_000_000:\n    n += 1\n"


@dataclass(frozen=True)
class SweepTiming:
    """One ``palpate sweep``: wall seconds, total CPU seconds (sweep + workers), each worker's CPU seconds."""

    wall: float
    cpu: float
    workers: tuple[float, ...]

    @property
    def critical_path(self) -> float:
        """CPU seconds on the longest chain: the sweep process's own plus its busiest worker's."""
        own = self.cpu - sum(self.workers)
        return own + (max(self.workers) if self.workers else 0.0)


def _cpu_of(pid: int) -> float | None:
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return None
    return (int(fields[11]) + int(fields[12])) / TICK  # utime, stime


def _children(pid: int) -> set[int]:
    out: set[int] = set()
    for task in Path(f"/proc/{pid}/task").glob("*/children"):
        try:
            out.update(int(p) for p in task.read_text().split())
        except OSError:
            pass
    return out


def run_sweep(sweep: Path, workers: int, out: Path) -> SweepTiming:
    if out.exists():
        shutil.rmtree(out)
    cmd = [sys.executable, "-c", "import sys; from palpate.core.cli import main; sys.exit(main())",
           "sweep", str(sweep), "--out", str(out), "--workers", str(workers)]
    before = os.times()
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            env=dict(os.environ, MPLBACKEND="Agg"))
    seen: dict[int, float] = {}
    while proc.poll() is None:
        for child in _children(proc.pid):
            cpu = _cpu_of(child)
            if cpu is not None:
                seen[child] = cpu
        time.sleep(0.05)
    wall = time.perf_counter() - t0
    after = os.times()
    err = proc.stderr.read()
    if proc.returncode != 0:
        raise SystemExit(f"palpate sweep --workers {workers} failed ({proc.returncode}): {err[-2000:]}")
    cpu = (after.children_user - before.children_user) + (after.children_system - before.children_system)
    return SweepTiming(wall, cpu, tuple(sorted(seen.values(), reverse=True)))


def spin_control() -> tuple[float, float]:
    """Wall seconds of one busy loop, and of two run at once."""
    cmd = [sys.executable, "-c", SPIN]
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True)
    one = time.perf_counter() - t0
    t0 = time.perf_counter()
    procs = [subprocess.Popen(cmd) for _ in range(2)]
    for p in procs:
        p.wait()
    return one, time.perf_counter() - t0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sweep", type=Path, default=REPO / "scenarios" / "sweeps" / "thesis_policies.toml")
    parser.add_argument("--repeats", type=int, default=3, help="pairs of runs (default 3)")
    parser.add_argument("--quick", action="store_true", help="scenarios/sweeps/tiny.toml, 2 pairs")
    args = parser.parse_args(argv)
    sweep = REPO / "scenarios" / "sweeps" / "tiny.toml" if args.quick else args.sweep
    repeats = 2 if args.quick else args.repeats
    one, two = spin_control()
    print(f"control: one busy loop {one:.2f} s, two at once {two:.2f} s: two processes run "
          f"{2 * one / two:.2f}x as fast as one here (2.0 with two free cores)")
    name = sweep.relative_to(REPO) if sweep.is_relative_to(REPO) else sweep
    print(f"sweep {name}: {repeats} pairs, {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f}")
    wall_ratios, cpu_ratios = [], []
    with tempfile.TemporaryDirectory(prefix="palpate_speed_sweep_") as tmp:
        for r in range(repeats):
            pair: dict[int, SweepTiming] = {}
            for w in ((1, 2) if r % 2 == 0 else (2, 1)):
                pair[w] = t = run_sweep(sweep, w, Path(tmp) / f"w{w}")
                print(f"  pair {r + 1}: --workers {w}: {t.wall:6.2f} s wall, {t.cpu:6.2f} s CPU (workers "
                      f"{', '.join(f'{c:.2f}' for c in t.workers)} s; critical path {t.critical_path:.2f} s)")
            wall_ratios.append(pair[1].wall / pair[2].wall)
            cpu_ratios.append(pair[1].cpu / pair[2].critical_path)
    print(f"speed-up --workers 2 over --workers 1, median of {repeats} pairs:")
    print(f"  measured wall time: {statistics.median(wall_ratios):.2f}x (min {min(wall_ratios):.2f}, max "
          f"{max(wall_ratios):.2f}); this machine ran two busy loops {2 * one / two:.2f}x as fast as one")
    print(f"  on two free cores (one-worker CPU / two-worker critical path): {statistics.median(cpu_ratios):.2f}x "
          f"(min {min(cpu_ratios):.2f}, max {max(cpu_ratios):.2f}); target >= 1.6x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
