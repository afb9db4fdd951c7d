"""Wall-clock helpers shared by the benchmark scripts (they run as `python benchmarks/NAME.py`, so this module is
importable as `bench_timing`)."""

from __future__ import annotations

import statistics
import time


def best_of(fn, repeats: int) -> float:
    """Shortest wall time of ``repeats`` calls of ``fn()``, s (the least disturbed run on a shared machine)."""
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def median_of(fn, repeats: int) -> tuple[float, object]:
    """Median wall time of ``repeats`` calls of ``fn()``, s, and the last call's result."""
    times, out = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), out
