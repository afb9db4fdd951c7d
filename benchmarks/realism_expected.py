"""The realism decision statistic: a profile's expected targets held per 6 seeds, with a standard error over seeds.

A seed's count of the 12 targets is a statistic of its 10 presses per material, so counts on 24 seeds have a
standard error of ~2 per 6 seeds. The quantity a user cares about is the simulator's *expected* count per seed,
which depends only on its press distribution: this estimates it from the presses of a ``--write-presses`` CSV
pooled over its seeds (boot-out draws of 10 presses per material, as ``realism_ceiling.py`` draws them; copies of one
press held out together), and its uncertainty by a bootstrap **over seeds**: each resample redraws the seeds (their
press groups) with replacement, pools them and recomputes the expectation. Several CSVs on the same seeds are
resampled on the same seed indices and drawn with the same uniforms (common random numbers), so their differences
are paired. The Monte Carlo variance of each resample's finite draws is subtracted from the resamples' spread.

Validation printed alongside (docs/results.md, "Realism"): each population's mean per-seed
count with its seed-bootstrap s.e. and the difference per-seed - pooled with its own; ``--perfect N`` adds N
synthetic seeds drawn from the real table (a perfect simulator, whose expectation realism_ceiling.py gives) as a
population.

A simulated seed's presses share session-level draws (the same pad and finger for a material's 10 presses), so
pooling presses over seeds widens their spread beyond a seed's. ``--session-levels`` keeps that structure: each
synthetic seed takes one seed's level of n1 and a1 (its mean logs, per material) and draws its 10 presses from every
seed's presses moved to that level (their residuals from their own seed's level, inflated by sqrt(k / (k - 1)) for a
level estimated from k presses), so only the within-seed spread is pooled.

    .venv/bin/python benchmarks/realism_expected.py --simulated SHIPPED.csv [--simulated OTHER.csv]
        [--perfect 24] [--session-levels] [--draws 1000] [--resamples 100] [--resample-draws 150] [--rng 0]
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.perception.memory import MIN_SAMPLES
from palpate.core.perception.param_stats import PressTable, table_from_csv
from palpate.core.perception.realism_targets import TARGETS, check_targets, loo_self

sys.path.insert(0, str(Path(__file__).resolve().parent))
from realism_ceiling import MAX_DRAWS, PRESSES, SEEDS, draw_seed, read_simulated  # noqa: E402

REPO = Path(__file__).resolve().parent.parent


@dataclass(frozen=True)
class SeedPresses:
    """One seed's presses: per material its rows (k, 6), per row the id of the press it is (copies share one), and
    which targets the seed's own presses held (M, 4)."""

    rows: tuple[np.ndarray, ...]
    ids: tuple[np.ndarray, ...]
    held: np.ndarray


def simulated_seeds(path: Path, real: PressTable) -> tuple[tuple[int, ...], tuple[SeedPresses, ...]]:
    """The seeds of a ``--write-presses`` CSV (every press its own id) and what each held, in seed order."""
    sim = read_simulated(path, real)
    out = []
    for s, table in enumerate(sim.tables):
        ids = tuple(s * 10_000 + np.arange(len(r)) for r in table.rows)
        out.append(SeedPresses(table.rows, ids, sim.seed_held[s]))
    return sim.seeds, tuple(out)


def perfect_seeds(real: PressTable, seeds: int, rng: np.random.Generator) -> tuple[SeedPresses, ...]:
    """``seeds`` synthetic seeds of a perfect simulator: boot-out draws from the real table, each press's id the
    real press it copies, each seed's targets checked as realism_ceiling.py checks them."""
    out = []
    materials = list(real.materials)
    while len(out) < seeds:
        d = draw_seed(real, "boot-kept", rng)
        if any(len(g) - np.bincount(g).max() < MIN_SAMPLES for g in d.groups):
            continue
        held = check_targets(d.table, real, loo_self(d.table, materials, d.groups), materials).held
        out.append(SeedPresses(d.table.rows, tuple(np.asarray(g) for g in d.groups), held))
    return tuple(out)


def _session_logs(seeds: Sequence[SeedPresses], i: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Material ``i``'s pooled presses split into session levels and residuals, in log n1 and log a1: (S, 2) each
    seed's mean logs, (n, 2) each press's logs, (n, 2) its residual from its own seed's level, inflated by
    sqrt(k / (k - 1)) so that residuals from a mean of k presses keep the within-seed variance."""
    logs, levels, resid = [], [], []
    for s in seeds:
        x = s.rows[i][:, [0, 3]]
        if len(x) < 2 or not np.all(x > 0):
            raise ValidationError("session levels need at least 2 presses per material and seed, n1 and a1 > 0")
        lx = np.log(x)
        logs.append(lx)
        levels.append(lx.mean(axis=0))
        resid.append((lx - levels[-1]) * np.sqrt(len(x) / (len(x) - 1.0)))
    return np.array(levels), np.vstack(logs), np.vstack(resid)


def _at_level(rows: np.ndarray, logs: np.ndarray, resid: np.ndarray, level: np.ndarray) -> np.ndarray:
    """Presses moved to one session's level: n1 and a1 to exp(level + residual), n2 / a2 with them (a gain scales a
    law's offset as its slope) and the residual sums Phi by the square."""
    f = np.exp(level + resid - logs)
    return rows * np.column_stack([f[:, 0], f[:, 0], f[:, 0] ** 2, f[:, 1], f[:, 1], f[:, 1] ** 2])


def pooled_held(seeds: Sequence[SeedPresses], real: PressTable, uniforms: np.ndarray, rng: np.random.Generator,
                sessions: np.ndarray | None = None) -> np.ndarray:
    """(D, M, 4) the targets held on D synthetic seeds drawn from ``seeds``' presses pooled.

    ``uniforms`` (D, M, PRESSES) in [0, 1) pick the presses (floor(u n) of a material's n pooled presses), so two
    pools of equal size given the same uniforms draw the same positions; a draw whose held-out groups would leave
    fewer than MIN_SAMPLES presses is replaced by one from ``rng`` (never needed with distinct presses).

    ``sessions`` (D,) in [0, 1), optional: each synthetic seed takes one seed's session (floor(v S) of the S seeds)
    and every drawn press is moved to that seed's level of n1 and a1 (:func:`_session_logs`), so a synthetic seed
    keeps a seed's between-material levels and only the within-seed spread is pooled."""
    materials = list(real.materials)
    rows = [np.vstack([s.rows[i] for s in seeds]) for i in range(len(materials))]
    ids = [np.concatenate([s.ids[i] for s in seeds]) for i in range(len(materials))]
    logs = None if sessions is None else [_session_logs(seeds, i) for i in range(len(materials))]
    held = np.empty((len(uniforms), len(materials), len(TARGETS)), dtype=bool)
    for k, u in enumerate(uniforms):
        while True:
            picks = [np.minimum((u[i] * len(r)).astype(np.int64), len(r) - 1) for i, r in enumerate(rows)]
            groups = [ids[i][p] for i, p in enumerate(picks)]
            if all(len(g) - np.unique(g, return_counts=True)[1].max() >= MIN_SAMPLES for g in groups):
                break
            u = rng.random(u.shape)
        drawn = [r[p] for r, p in zip(rows, picks, strict=True)]
        if logs is not None:
            s = min(int(sessions[k] * len(seeds)), len(seeds) - 1)
            drawn = [_at_level(d, lg[1][p], lg[2][p], lg[0][s]) for d, lg, p in zip(drawn, logs, picks, strict=True)]
        table = PressTable(real.materials, tuple(drawn))
        # ids as small integers per material: loo_self offsets them so that no group spans two materials
        small = [np.unique(g, return_inverse=True)[1] for g in groups]
        held[k] = check_targets(table, real, loo_self(table, materials, small), materials).held
    return held


@dataclass(frozen=True)
class Expected:
    """Expected targets of P populations on the same number of seeds (per seed; multiply by SEEDS for 6 seeds).

    Attributes:
        probability: (P, M, 4) share of pooled draws holding each target (the point estimate).
        all_held: (P,) share of pooled draws holding every target.
        observed: (P,) mean of the populations' own per-seed counts.
        counts: (B, P, D) targets held by each draw of each seed resample (common uniforms across populations).
        per_seed: (B, P) mean per-seed count of each resample's seeds.
    """

    probability: np.ndarray
    all_held: np.ndarray
    observed: np.ndarray
    counts: np.ndarray
    per_seed: np.ndarray

    @property
    def expected(self) -> np.ndarray:
        """(P,) expected targets held per seed."""
        return self.probability.reshape(len(self.probability), -1).sum(axis=1)

    def se(self, p: int, q: int | None = None) -> float:
        """Seed-bootstrap s.e. per seed of population ``p``'s expectation (or of ``p`` - ``q``, paired), with the
        resamples' Monte Carlo variance subtracted (0 when that leaves nothing)."""
        x = self.counts[:, p].astype(float) - (0.0 if q is None else self.counts[:, q])
        return _corrected_se(x.mean(axis=1), x.var(axis=1, ddof=1) / x.shape[1])

    def se_validation(self, p: int) -> float:
        """Seed-bootstrap s.e. per seed of population ``p``'s per-seed mean less its pooled expectation."""
        x = self.counts[:, p].astype(float)
        return _corrected_se(self.per_seed[:, p] - x.mean(axis=1), x.var(axis=1, ddof=1) / x.shape[1])

    def se_per_seed(self, p: int) -> float:
        """Seed-bootstrap s.e. per seed of population ``p``'s mean per-seed count."""
        return float(self.per_seed[:, p].std(ddof=1))


def _corrected_se(values: np.ndarray, mc_var: np.ndarray) -> float:
    return float(np.sqrt(max(np.var(values, ddof=1) - np.mean(mc_var), 0.0)))


def expected_targets(populations: Sequence[Sequence[SeedPresses]], real: PressTable, draws: int, resamples: int,
                     resample_draws: int, rng: np.random.Generator, session_levels: bool = False) -> Expected:
    """The pooled expectation of each population (``draws`` draws) and ``resamples`` seed resamples of
    ``resample_draws`` draws each; every population is resampled on the same seed indices with the same uniforms.
    ``session_levels``: each synthetic seed at one seed's level (:func:`pooled_held`'s ``sessions``)."""
    n = {len(p) for p in populations}
    if len(n) != 1 or min(n) < 2:
        raise ValidationError(f"populations must have the same number of seeds (at least 2), got {sorted(n)}")
    for value, what in ((draws, "draws"), (resamples, "resamples"), (resample_draws, "resample draws")):
        if not 2 <= value <= MAX_DRAWS:
            raise ValidationError(f"{what} must be within 2..{MAX_DRAWS}, got {value}")
    seeds, m = n.pop(), len(real.materials)
    streams = rng.spawn(3)
    u0 = streams[0].random((draws, m, PRESSES))
    v0 = streams[0].random(draws) if session_levels else None
    point = [pooled_held(pop, real, u0, streams[2], v0) for pop in populations]
    probability = np.array([h.mean(axis=0) for h in point])
    all_held = np.array([h.reshape(draws, -1).all(axis=1).mean() for h in point])
    observed = np.array([np.mean([s.held.sum() for s in pop]) for pop in populations])
    counts = np.empty((resamples, len(populations), resample_draws), dtype=np.int64)
    per_seed = np.empty((resamples, len(populations)))
    for b in range(resamples):
        pick = streams[1].integers(0, seeds, size=seeds)
        u = streams[1].random((resample_draws, m, PRESSES))
        v = streams[1].random(resample_draws) if session_levels else None
        for p, pop in enumerate(populations):
            chosen = [pop[i] for i in pick]
            counts[b, p] = pooled_held(chosen, real, u, streams[2], v).reshape(resample_draws, -1).sum(axis=1)
            per_seed[b, p] = np.mean([s.held.sum() for s in chosen])
    return Expected(probability, all_held, observed, counts, per_seed)


def _report(names: Sequence[str], e: Expected, real: PressTable) -> None:
    print(f"  {'target (per 6 seeds)':<24}" + "".join(f"{n[:18]:>20}" for n in names)
          + ("".join(f"{'- ' + names[0][:14]:>20}" for _ in names[1:])))
    for i, mat in enumerate(real.materials):
        for j, t in enumerate(TARGETS):
            cells = [f"{SEEDS * e.probability[p, i, j]:20.2f}" for p in range(len(names))]
            diffs = [f"{SEEDS * (e.probability[p, i, j] - e.probability[0, i, j]):+20.2f}"
                     for p in range(1, len(names))]
            print(f"  {mat + ' ' + t:<24}" + "".join(cells + diffs))
    for p, name in enumerate(names):
        v = SEEDS * (e.observed[p] - e.expected[p])
        print(f"  {name}: expected {SEEDS * e.expected[p]:.2f} per {SEEDS} seeds (seed-bootstrap s.e. "
              f"{SEEDS * e.se(p):.2f}); all {e.probability.shape[1] * len(TARGETS)} targets on "
              f"{e.all_held[p]:.3f} of draws; per-seed counts {SEEDS * e.observed[p]:.2f} (s.e. "
              f"{SEEDS * e.se_per_seed(p):.2f}); per-seed - pooled {v:+.2f} (s.e. {SEEDS * e.se_validation(p):.2f})")
    for p in range(1, len(names)):
        d = SEEDS * (e.expected[p] - e.expected[0])
        s = SEEDS * e.se(p, 0)
        ratio = d / s if s else np.inf
        print(f"  {names[p]} - {names[0]}: {d:+.2f} per {SEEDS} seeds, paired s.e. {s:.2f} ({ratio:+.2f} s.e.); "
              f"per-seed counts {SEEDS * (e.observed[p] - e.observed[0]):+.2f}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--simulated", type=Path, action="append", default=[],
                    help="a realism_targets.py --write-presses CSV (repeatable; all on the same seeds; the first is "
                         "the baseline of the differences)")
    ap.add_argument("--perfect", type=int, default=0, metavar="N",
                    help="also a population of N synthetic seeds drawn from the real table (alone: N seeds)")
    ap.add_argument("--draws", type=int, default=1000, help="pooled draws of the point estimate")
    ap.add_argument("--resamples", type=int, default=100, help="seed resamples of the bootstrap")
    ap.add_argument("--resample-draws", type=int, default=150, help="pooled draws per seed resample")
    ap.add_argument("--session-levels", action="store_true",
                    help="each synthetic seed at one seed's level of n1 and a1; only the within-seed spread pooled")
    ap.add_argument("--rng", type=int, default=0)
    ap.add_argument("--real", type=Path, default=REPO / "models" / "realism" / "seed000_tables_6_3_to_6_5.csv")
    args = ap.parse_args(argv)
    try:
        real = table_from_csv(args.real)
        names, pops, seed_lists = [], [], []
        for path in args.simulated:
            seeds, pop = simulated_seeds(path, real)
            names.append(path.stem)
            pops.append(pop)
            seed_lists.append(seeds)
        if len(set(seed_lists)) > 1:
            raise ValidationError("the --simulated files must hold the same seeds (their differences are paired)")
        rng = np.random.default_rng(args.rng)
        if args.perfect:
            if pops and args.perfect != len(pops[0]):
                raise ValidationError(f"--perfect {args.perfect}: the --simulated files hold {len(pops[0])} seeds")
            names.append(f"perfect x{args.perfect}")
            pops.append(perfect_seeds(real, args.perfect, np.random.default_rng([args.rng, 1])))
        if not pops:
            raise ValidationError("give --simulated CSV and/or --perfect N")
        e = expected_targets(pops, real, args.draws, args.resamples, args.resample_draws, rng, args.session_levels)
    except (ValidationError, ValueError, OSError) as err:
        print(f"realism_expected: {err}", file=sys.stderr)
        return 2
    how = "at one seed's session level each" if args.session_levels else "pooled"
    print(f"expected targets per {SEEDS} seeds from presses {how} (boot-out), {args.draws} draws; s.e. over "
          f"{args.resamples} seed resamples of {args.resample_draws} draws each; rng {args.rng}; "
          f"seeds {','.join(map(str, seed_lists[0])) if seed_lists else '-'}")
    _report(names, e, real)
    return 0


if __name__ == "__main__":
    sys.exit(main())
