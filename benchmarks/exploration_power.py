"""How often the exploration targets pass by chance: the size and power of the per-scene statistics that
`exploration_fine.py` prints, from its rows (``--json``), by resampling the scenes.

Each scene gives, per policy, the presses to 95% of the area right as a share of the raster's (a run that never
gets there counts as cells + 1). For a policy against a baseline (default ``boundary`` against ``max_entropy``) it
prints, over the report scenes:

- the paired differences (policy - baseline): median, how many scenes each way, a one-sided Wilcoxon signed-rank
  p-value (does the policy need fewer presses?);
- the bootstrap pass probability (scenes drawn with replacement into families of the rows' sizes) of "no family's median
  worse than the baseline's", of the Wilcoxon test at 5%, of the median <= 0.25 and of the 95th percentile <= 0.6,
  for the policy as measured and shifted by a constant share of presses (a policy that much better on every
  scene), and for a policy exchangeable with the baseline (each scene's pair swapped at random: no difference).

``--reading stays`` judges the press from which the fine map stays at 95% to the end of the run instead of the first
press that reaches it (rows of ``exploration_fine.py --stays``); ``--reading to_ceiling`` the first press at 95% or
the raster's final area right less 2 points, whichever is lower (rows of runs with ``raster`` among the policies).

Run: .venv/bin/python benchmarks/exploration_power.py ROWS.json [ROWS.json ...] [--policy boundary]
     [--baseline max_entropy] [--reading to_target|stays|to_ceiling] [--split report|tuning] [--draws 4000] [--seed 0]
(rows from `exploration_fine.py --first 100000 --scenes 24 --policies raster,max_entropy,info_gain,boundary
--json ROWS.json`)
"""

from __future__ import annotations

import argparse
import json
from collections import Counter

import numpy as np
from scipy.stats import wilcoxon

SHIFTS = (0.0, -0.05, -0.1, -0.2)


def shares(rows: list[dict], policy: str, reading: str = "to_target",
           split: str = "report") -> dict[int, tuple[str, float]]:
    """Seed -> (family, presses to target over the raster's) for ``policy`` on the ``split``'s scenes; ``reading``:
    ``to_target`` (the first press at the target), ``stays`` (the press from which the map stays there) or
    ``to_ceiling`` (the first press at the target or the raster's final area right less 2 points if lower)."""
    out = {}
    for r in rows:
        if r["policy"] == policy and r["split"] == split:
            if reading not in r:
                raise SystemExit(f"the rows have no {reading!r} reading (exploration_fine.py writes stays with "
                                 "--stays, to_ceiling with raster among the policies)")
            presses = r[reading] if r[reading] is not None else r["cells"] + 1
            out[r["seed"]] = (r["family"], presses / r["cells"])
    return out


def no_family_worse(x: np.ndarray, y: np.ndarray, groups: list[np.ndarray]) -> bool:
    """Whether every group's median of x is at most its median of y."""
    return all(np.median(x[g]) <= np.median(y[g]) + 1e-12 for g in groups)


def one_sided_wilcoxon(d: np.ndarray) -> float:
    """p-value that the differences sit below 0 (1.0 when every difference is 0)."""
    nonzero = d[d != 0]
    return float(wilcoxon(nonzero, alternative="less").pvalue) if nonzero.size else 1.0


def pass_rates(x: np.ndarray, y: np.ndarray, sizes: list[int], draws: int, rng,
               exchange: bool = False) -> dict[str, float]:
    """Bootstrap pass rates of the four criteria for the policy ``x`` against the baseline ``y`` (per scene):
    scenes drawn with replacement from all of them into groups of ``sizes`` (pooled: a family's own two or three
    scenes are too few to resample); ``exchange``: each drawn pair swapped at random (no difference)."""
    bounds = np.cumsum([0] + sizes)
    groups = [np.arange(a, b) for a, b in zip(bounds[:-1], bounds[1:], strict=True)]
    hits = Counter()
    for _ in range(draws):
        i = rng.integers(0, len(x), len(x))
        xs, ys = x[i], y[i]
        if exchange:
            swap = rng.random(len(x)) < 0.5
            xs, ys = np.where(swap, ys, xs), np.where(swap, xs, ys)
        hits["no family worse"] += no_family_worse(xs, ys, groups)
        hits["Wilcoxon p < 0.05"] += one_sided_wilcoxon(xs - ys) < 0.05
        hits["median <= 0.25"] += np.median(xs) <= 0.25
        hits["p95 <= 0.6"] += np.percentile(xs, 95) <= 0.6
    return {k: hits[k] / draws for k in ("no family worse", "Wilcoxon p < 0.05", "median <= 0.25", "p95 <= 0.6")}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("rows", nargs="+")
    parser.add_argument("--policy", default="boundary")
    parser.add_argument("--baseline", default="max_entropy")
    parser.add_argument("--draws", type=int, default=4000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--reading", choices=("to_target", "stays", "to_ceiling"), default="to_target",
                        help="the first press at 95%% (default), the press from which the map stays at 95%%, or the "
                        "first press at 95%% or the raster's final less 2 points if lower")
    parser.add_argument("--split", choices=("report", "tuning"), default="report",
                        help="the scenes judged (default report; tuning to see a protocol on the scenes it was set on)")
    args = parser.parse_args()
    rows = [r for path in args.rows for r in json.load(open(path))]
    pol, base = (shares(rows, p, args.reading, args.split) for p in (args.policy, args.baseline))
    seeds = sorted(set(pol) & set(base), key=lambda s: (pol[s][0], s))
    if len(seeds) < 4:
        raise SystemExit(f"need at least 4 {args.split} scenes with both {args.policy} and {args.baseline}")
    families = [pol[s][0] for s in seeds]
    sizes = list(Counter(families).values())
    x = np.array([pol[s][1] for s in seeds])
    y = np.array([base[s][1] for s in seeds])
    d = x - y
    bounds = np.cumsum([0] + sizes)
    groups = [np.arange(a, b) for a, b in zip(bounds[:-1], bounds[1:], strict=True)]
    worse = [families[g[0]] for g in groups if np.median(x[g]) > np.median(y[g]) + 1e-12]
    print(f"{len(seeds)} {args.split} scenes, {len(sizes)} families of {min(sizes)}-{max(sizes)}; {args.policy} "
          f"against {args.baseline} (presses to 95% over the raster's, {args.reading} reading)")
    print(f"measured: median {np.median(x):.3f}, p95 {np.percentile(x, 95):.3f}; paired difference median "
          f"{np.median(d):+.3f}, fewer presses on {int(np.sum(d < 0))}, more on {int(np.sum(d > 0))}; one-sided "
          f"Wilcoxon p {one_sided_wilcoxon(d):.4f}; families with a worse median: {', '.join(worse) or 'none'}")
    rng = np.random.default_rng(args.seed)
    names = ("no family worse", "Wilcoxon p < 0.05", "median <= 0.25", "p95 <= 0.6")
    print(f"\nbootstrap pass rate ({args.draws} draws of the scenes)")
    print(f"{'policy':34} " + " ".join(f"{n:>17}" for n in names))
    for shift in SHIFTS:
        rates = pass_rates(np.maximum(x + shift, 0.0), y, sizes, args.draws, rng)
        label = f"{args.policy} as measured" if shift == 0 else f"{args.policy} {shift:+.2f} on every scene"
        print(f"{label:34} " + " ".join(f"{rates[n]:17.3f}" for n in names))
    rates = pass_rates(x, y, sizes, args.draws, rng, exchange=True)
    print(f"{'exchangeable with ' + args.baseline:34} " + " ".join(f"{rates[n]:17.3f}" for n in names))


if __name__ == "__main__":
    main()
