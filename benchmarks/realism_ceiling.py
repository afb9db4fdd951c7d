"""What a perfect simulator would score on the realism targets: the sampling noise of 10 presses.

Every target is checked on one seed's 10 presses per material, so even a simulator whose presses come from the real
presses' own distribution misses some. This draws many synthetic "seeds" of 10 presses per material from a
*population* of presses and runs the targets' own checks on each
(:func:`palpate.core.perception.realism_targets.check_targets` against the real table, the leave-one-out as a run
computes it). Populations: the real table (a perfect simulator) and, per ``--simulated`` file, the presses a
profile simulated, pooled over their seeds (the profile with its own sampling noise, for comparison with what it held
seed by seed), and each seed's own presses (a synthetic seed resamples one seed's; this regresses: a resample of 10
presses holds fewer targets than the presses themselves). Generators, side by side:

- ``boot-kept``: a bootstrap resample of the population's presses, copies left in the leave-one-out memory (a copy of
  the held-out press trains the memory that reads it, which inflates the self posterior);
- ``boot-out``: the same resamples (the same draws), all copies of the held-out press held out with it (fewer
  distinct presses left);
- ``smooth``: a smoothed bootstrap (Silverman 1986, 6.4.1, shrunk so the variance stays the population's): each
  resampled press plus Gaussian noise of the population's covariance of [n1, n2, a1, a2] times Silverman's
  bandwidth, so no two presses are equal;
- ``gauss``: a Gaussian per material fitted to [n1, n2, log Phi_N, a1, a2, log Phi_A] (covariance n - 1).

Per target it prints the probability of holding it, the expected number of the 6 seeds that hold it and its band
(5-95% of Binomial(6, p)), and per generator the expected count of the 12 targets of a seed and of 72 over 6 seeds,
with the 5-95% band of the 72 (the per-seed counts' distribution convolved 6 times, so targets that miss together
stay together) and the share of synthetic seeds holding all 12 (what one deterministic run is asked to hold). With
``--simulated``, the targets that table's own seeds held are printed too.

    .venv/bin/python benchmarks/realism_ceiling.py [--draws 2000] [--rng 0] [--real TABLE.csv]
        [--simulated benchmarks/data/thesis_ch6_heldout_presses.csv ...] [--generators boot-out,gauss]
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.stats import binom

from palpate.core.errors import ValidationError
from palpate.core.perception.memory import MIN_SAMPLES
from palpate.core.perception.param_stats import PARAM_INDEX, PressTable, table_from_columns, table_from_csv
from palpate.core.perception.params_table import read_params_csv
from palpate.core.perception.realism_targets import TARGETS, check_targets, loo_self

REPO = Path(__file__).resolve().parent.parent
GENERATORS = ("boot-kept", "boot-out", "smooth", "gauss")
PRESSES = 10  # per material and seed, as the scenario's training and seed 000's tables
SEEDS = 6  # the held-out seeds of benchmarks/realism_targets.py (6, 301-305)
MAX_DRAWS = 1_000_000
_PHI = (2, 5)  # Phi_N, Phi_A columns: fitted in log by ``gauss``


@dataclass(frozen=True)
class Draw:
    """One synthetic seed: its table and, for a bootstrap, per material the population press each press copies
    (None: no copies)."""

    table: PressTable
    groups: tuple[np.ndarray, ...] | None


def _silverman(n: int, d: int = len(PARAM_INDEX)) -> float:
    """Silverman's rule-of-thumb bandwidth for a d-dimensional Gaussian kernel on n points (in units of the
    sample's own covariance)."""
    return (4.0 / (n * (d + 2))) ** (1.0 / (d + 4))


def draw_seed(population: PressTable, generator: str, rng: np.random.Generator, presses: int = PRESSES) -> Draw:
    """A synthetic seed of ``presses`` presses per material from ``population`` by ``generator`` (:data:`GENERATORS`).
    """
    tables, groups = [], []
    for rows in population.rows:
        n = len(rows)
        if generator == "gauss":
            x = rows.copy()
            x[:, _PHI] = np.log(np.maximum(x[:, _PHI], 1e-300))
            y = rng.multivariate_normal(x.mean(axis=0), np.cov(x.T, ddof=1), size=presses, method="eigh")
            y[:, _PHI] = np.exp(y[:, _PHI])
            tables.append(y)
            continue
        pick = rng.integers(0, n, size=presses)
        y = rows[pick].copy()
        if generator == "smooth":
            idx = list(PARAM_INDEX)
            h = _silverman(n)
            mean = rows[:, idx].mean(axis=0)
            noise = rng.multivariate_normal(np.zeros(len(idx)), np.cov(rows[:, idx].T, ddof=1), size=presses,
                                            method="eigh")
            y[:, idx] = mean + (y[:, idx] - mean + h * noise) / np.sqrt(1.0 + h * h)
        elif generator not in ("boot-kept", "boot-out"):
            raise ValueError(f"unknown generator {generator!r}; known: {', '.join(GENERATORS)}")
        tables.append(y)
        groups.append(pick)
    table = PressTable(population.materials, tuple(tables))
    return Draw(table, tuple(groups) if generator in ("boot-kept", "boot-out") else None)


def _loo_ready(groups: tuple[np.ndarray, ...] | None) -> bool:
    """Whether holding out each group still leaves the memory MIN_SAMPLES presses of that material (asked of both
    bootstraps, so that boot-kept and boot-out given one stream draw the same seeds)."""
    return groups is None or all(len(g) - np.bincount(g).max() >= MIN_SAMPLES for g in groups)


@dataclass(frozen=True)
class Ceiling:
    """The targets over many synthetic seeds of one population and generator.

    Attributes:
        held: (draws, M, 4) whether each target of :data:`TARGETS` held on each synthetic seed.
        redrawn: synthetic seeds drawn again because holding out a group of copies left fewer than MIN_SAMPLES.
    """

    held: np.ndarray
    redrawn: int

    @property
    def probability(self) -> np.ndarray:
        """(M, 4) share of synthetic seeds holding each target."""
        return self.held.mean(axis=0)

    @property
    def counts(self) -> np.ndarray:
        """(draws,) targets held per synthetic seed."""
        return self.held.reshape(len(self.held), -1).sum(axis=1)


def ceiling(population: PressTable | Sequence[PressTable], real: PressTable, generator: str, draws: int,
            rng: np.random.Generator) -> Ceiling:
    """Check the targets against ``real`` on ``draws`` synthetic seeds drawn from ``population`` (several tables:
    each synthetic seed from one of them, chosen at random)."""
    tables = [population] if isinstance(population, PressTable) else list(population)
    if not isinstance(draws, (int, np.integer)) or isinstance(draws, bool) or not 1 <= draws <= MAX_DRAWS:
        raise ValidationError(f"draws must be an integer in 1..{MAX_DRAWS}, got {draws!r}")
    materials = list(real.materials)
    held, redrawn = np.empty((draws, len(materials), len(TARGETS)), dtype=bool), 0
    for k in range(draws):
        d = draw_seed(tables[rng.integers(len(tables))], generator, rng)
        while not _loo_ready(d.groups):
            redrawn += 1
            d = draw_seed(tables[rng.integers(len(tables))], generator, rng)
        loo = loo_self(d.table, materials, d.groups if generator == "boot-out" else None)
        held[k] = check_targets(d.table, real, loo, materials).held
    return Ceiling(held, redrawn)


def seeds_band(counts: np.ndarray, seeds: int = SEEDS, size: int = 12) -> tuple[np.ndarray, float, float]:
    """The distribution of the targets held over ``seeds`` independent seeds, from per-seed ``counts`` (0..size):
    (pmf over 0..seeds * size, its 5% and 95% quantiles)."""
    pmf1 = np.bincount(counts, minlength=size + 1).astype(float) / len(counts)
    pmf = np.array([1.0])
    for _ in range(seeds):
        pmf = np.convolve(pmf, pmf1)
    cdf = np.cumsum(pmf)
    return pmf, float(np.searchsorted(cdf, 0.05 - 1e-12)), float(np.searchsorted(cdf, 0.95 - 1e-12))


@dataclass(frozen=True)
class Simulated:
    """Presses a profile simulated (realism_targets.py --write-presses): per seed, its table and which targets it
    held (S, M, 4)."""

    seeds: tuple[int, ...]
    tables: tuple[PressTable, ...]
    seed_held: np.ndarray

    @property
    def held(self) -> np.ndarray:
        """(M, 4) how many of the seeds held each target."""
        return self.seed_held.sum(axis=0)


def read_simulated(simulated_csv: Path, real: PressTable) -> Simulated:
    """The CSV's presses by seed, checked against ``real`` seed by seed (as realism_targets.py printed them).

    Read once as a per-press table (:func:`~palpate.core.perception.param_stats.table_from_columns`) with an
    integer ``seed`` column; ValidationError naming the file when it lacks one."""
    params, labels, extra = read_params_csv(simulated_csv)
    table = table_from_columns(simulated_csv, params, labels, extra)
    seed_col = extra.get("seed")
    if seed_col is None or seed_col.dtype.kind != "f" or np.any(seed_col != np.round(seed_col)):
        raise ValidationError(f"{simulated_csv}: needs an integer 'seed' column (realism_targets.py --write-presses)")
    seeds = sorted({int(v) for v in seed_col})
    materials = list(real.materials)
    held, tables = [], []
    lab = np.asarray(labels)
    for seed in seeds:
        # table_from_csv keeps each material's rows in file order, as its seed column's are
        rows = tuple(table.of(m)[seed_col[lab == m] == seed] for m in materials)
        tables.append(PressTable(tuple(materials), rows))
        held.append(check_targets(tables[-1], real, loo_self(tables[-1], materials), materials).held)
    return Simulated(tuple(seeds), tuple(tables), np.array(held, dtype=int))


def _report(name: str, results: dict[str, Ceiling], real: PressTable, seen: np.ndarray | None,
            total: int | None) -> None:
    gens = list(results)
    print(f"\npopulation: {name}")
    head = "".join(f"{g:>19}" for g in gens)
    print(f"  {'target':<22}{head}" + ("   held" if seen is not None else ""))
    print(f"  {'':<22}" + "".join(f"{'P  of 6 [5-95%]':>19}" for _ in gens))
    for i, m in enumerate(real.materials):
        for j, t in enumerate(TARGETS):
            cells = []
            for g in gens:
                p = float(results[g].probability[i, j])
                lo, hi = binom.ppf(0.05, SEEDS, p), binom.ppf(0.95, SEEDS, p)
                cells.append(f"{p:5.2f} {SEEDS * p:4.1f} [{lo:.0f}-{hi:.0f}]")
            line = f"  {m + ' ' + t:<22}" + "".join(f"{c:>19}" for c in cells)
            print(line + (f"   {seen[i, j]}" if seen is not None else ""))
    size = len(real.materials) * len(TARGETS)
    for g in gens:
        c = results[g].counts
        pmf, lo, hi = seeds_band(c, SEEDS, size)
        se = SEEDS * c.std(ddof=1) / np.sqrt(len(c))
        extra = "" if total is None else f"; P(<= {total}) {pmf[:total + 1].sum():.3f}"
        print(f"  {g}: expected {c.mean():.2f} of {size} a seed, {SEEDS * c.mean():.1f} of {SEEDS * size} over "
              f"{SEEDS} seeds (Monte Carlo s.e. {se:.1f}; 5-95% of 6 seeds {lo:.0f}-{hi:.0f}{extra}); "
              f"all {size} held on {np.mean(c == size):.3f} of seeds; redrawn {results[g].redrawn}")


def _draws(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--draws takes a whole number, got {text!r}") from None
    if not 1 <= value <= MAX_DRAWS:
        raise argparse.ArgumentTypeError(f"--draws must be within 1..{MAX_DRAWS}, got {value}")
    return value


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=_draws, default=2000, help="synthetic seeds per population and generator")
    ap.add_argument("--rng", type=int, default=0, help="seed of the draws")
    ap.add_argument("--real", type=Path, default=REPO / "models" / "realism" / "seed000_tables_6_3_to_6_5.csv")
    ap.add_argument("--simulated", type=Path, action="append", default=[],
                    help="a CSV of realism_targets.py --write-presses, pooled over its seeds (repeatable)")
    ap.add_argument("--generators", default=",".join(GENERATORS))
    args = ap.parse_args(argv)
    gens = args.generators.split(",")
    if not gens or any(g not in GENERATORS for g in gens):
        print(f"realism_ceiling: --generators takes some of {','.join(GENERATORS)}", file=sys.stderr)
        return 2
    try:
        real = table_from_csv(args.real)
        populations = [(f"real table {args.real.name}", real, None)]
        for path in args.simulated:
            sim = read_simulated(path, real)
            pooled = PressTable(real.materials, tuple(np.vstack([t.of(m) for t in sim.tables])
                                                      for m in real.materials))
            about = (f"seeds {','.join(map(str, sim.seeds))}; they held {sim.held.sum()} of "
                     f"{sim.held.size * len(sim.seeds)}: the column 'held'")
            populations += [(f"{path.name} pooled over its seeds ({about})", pooled, sim),
                            (f"{path.name}, each seed's own presses ({about})", sim.tables, sim)]
    except (ValidationError, ValueError, OSError) as err:
        print(f"realism_ceiling: {err}", file=sys.stderr)
        return 2
    print(f"{args.draws} synthetic seeds of {PRESSES} presses per material per generator, rng {args.rng}; "
          f"targets against {args.real.name}")
    # every population's band is compared with what the first simulated table's seeds held
    # (per SEEDS seeds, rounded down, so that a file of 24 seeds is compared with the band of 6)
    total = next((int(sim.held.sum()) * SEEDS // len(sim.seeds) for _, _, sim in populations if sim is not None),
                 None)
    streams = np.random.SeedSequence(args.rng).spawn(len(populations) * len(GENERATORS))
    # boot-out draws boot-kept's seeds: only the leave-one-out differs, so the copies' effect is seen alone
    stream = {g: GENERATORS.index("boot-kept" if g == "boot-out" else g) for g in GENERATORS}
    for p, (name, pop, sim) in enumerate(populations):
        results = {g: ceiling(pop, real, g, args.draws, np.random.default_rng(streams[p * len(GENERATORS) + stream[g]]))
                   for g in gens}
        _report(name, results, real, None if sim is None else sim.held, total)
    return 0


if __name__ == "__main__":
    sys.exit(main())
