"""Speed of the haptic memory: posterior throughput (vectorised) against a per-press scipy loop, and the cost of
leave-one-out on the seed's data. Prints a table; run ``.venv/bin/python benchmarks/memory.py [--quick]``."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from bench_timing import best_of
from scipy.special import logsumexp
from scipy.stats import multivariate_normal

from palpate.core.perception.crossval import leave_one_out
from palpate.core.perception.memory import HapticMemory
from palpate.core.perception.params_table import read_params_csv

THESIS_CSV = Path(__file__).resolve().parent.parent / "models" / "realism" / "seed000_tables_6_3_to_6_5.csv"


def _scipy_loop(mem: HapticMemory, x: np.ndarray) -> np.ndarray:
    out = np.empty((len(x), len(mem.materials)))
    for i, row in enumerate(x):
        ll = np.array([
            multivariate_normal.logpdf(row[:2], mem.means_N[k], mem.covs_N[k])
            + multivariate_normal.logpdf(row[2:], mem.means_A[k], mem.covs_A[k])
            for k in range(len(mem.materials))
        ]) + np.log(mem.prior)
        out[i] = np.exp(ll - logsumexp(ll))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--quick", action="store_true", help="smaller sizes, fewer repeats")
    args = ap.parse_args()
    rng = np.random.default_rng(7)
    params, labels, _ = read_params_csv(THESIS_CSV)
    repeats = 3 if args.quick else 7
    print(f"{'materials':>9} {'presses':>8} {'predict_proba s':>16} {'presses/s':>12} {'scipy loop s':>13} "
          f"{'speed-up':>9} {'max |diff|':>11}")
    sizes = [(3, 1_000), (3, 100_000)] + ([] if args.quick else [(20, 100_000)])
    for m, n in sizes:
        centres = rng.normal(0, 500, (m, 4))
        x_train = np.repeat(centres, 10, axis=0) + rng.normal(0, 20, (10 * m, 4))
        mem = HapticMemory().fit(x_train, [f"M{k}" for k in range(m) for _ in range(10)])
        x = rng.normal(0, 800, (n, 4))
        t_vec = best_of(lambda mem=mem, x=x: mem.predict_proba(x), repeats)
        n_loop = min(n, 2_000)
        t_loop = best_of(lambda mem=mem, x=x[:n_loop]: _scipy_loop(mem, x), 1) * n / n_loop
        diff = np.abs(mem.predict_proba(x[:n_loop]) - _scipy_loop(mem, x[:n_loop])).max()
        print(f"{m:>9} {n:>8} {t_vec:>16.4f} {n / t_vec:>12.3g} {t_loop:>13.3f} {t_loop / t_vec:>9.0f} {diff:>11.1e}")
    t_loo = best_of(lambda: leave_one_out(params, labels), repeats)
    print(f"\nleave-one-out on seed 000 Tables 6.3-6.5 (30 presses, 3 materials): {t_loo * 1e3:.1f} ms")
    print("(scipy loop time extrapolated from 2000 presses)")


if __name__ == "__main__":
    main()
