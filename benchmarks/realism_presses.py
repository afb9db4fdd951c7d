"""Per-press anatomy of scenarios/thesis_ch6.toml's training presses: what sets each material's cutaneous a1 and a2.

For each seed and reference material, every training press with its peak force (N), the object's indentation d and
the pulp's compression delta at their deepest (mm), the press's factor on the pulp's stiffness, the perceived
indentation c_D (mm) and contact area c_A (mm^2), the peak intensity c_P (counts), the active and saturated sensels
of the peak frame, the fit's n1, n2 (counts: its sign is the realism targets' n2 < 0), a1 and a2, the perceived
indentation at which the contact area stopped growing ("filled", mm), and ``a1 / (n1 (c_D / c_A)^1.5)``.

When the patch covers the pad before the press ends, both fits end at the same c_P, so a1 / n1 is
(c_D / c_A)^1.5 at the deepest point whatever the pad's gain, non-linearity or saturation and the material's
modulus: the last column stays near 1 and a1 follows n1 and where the press stops (docs/results.md, "Realism").
a2 says how early the pad filled: an area that stops growing well before the press ends while c_P keeps rising
makes the cutaneous fit steep and a2 negative; seed 000's small a2 on the sponge and the rubber (13, 4) say their
area grew to the end. The last lines give per material the means over the seeds.

    .venv/bin/python benchmarks/realism_presses.py [--seeds 101,102,103,104] [--scenario S.toml]
        [--profile NAME_OR_PATH] [--set KEY=VALUE ...] [--scenario-set training.depth_mm=1.8 ...] [--quiet]
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from palpate.core.session.progress import Progress
from palpate.core.session.training import train_memory, training_seeds
from palpate.core.world.scenario_file import load_scenario
from palpate.sim.realism.calibrate import realism_source_maker
from palpate.sim.realism.parameters import free_parameters, with_values
from palpate.sim.realism.profile_file import resolve_profile

sys.path.insert(0, str(Path(__file__).resolve().parent))
from realism_targets import REPO, _pairs, with_scenario_values  # noqa: E402

#: columns of one press's row (units in the module docstring)
COLUMNS = ("force", "d", "delta", "pulp", "c_D", "c_A", "c_P", "active", "saturated", "n1", "n2", "a1", "a2",
           "filled", "a1/identity")


@dataclass(frozen=True)
class _Keeping:
    """A source that also keeps every recording it returns (the perceived press keeps no frames)."""

    source: object
    kept: list

    def press(self, target):
        rec = self.source.press(target)
        self.kept.append(rec)
        return rec


def press_rows(scenario, profile, seed: int) -> dict[str, np.ndarray]:
    """Per reference material, one row of :data:`COLUMNS` per fitted training press, the presses being those of
    the run's own training loop (:func:`palpate.core.session.training.train_memory`) with ``seed`` as scenario
    seed."""
    sc = replace(scenario, seed=int(seed))
    kept: list = []
    make = realism_source_maker(sc, profile, sc.fidelity)
    result = train_memory(sc, lambda objects, s, variability: _Keeping(make(objects, s, variability), kept),
                          training_seeds(sc), Progress(enabled=False))
    recs = iter(kept)  # in press order: the references in order, each material's presses in order
    out = {}
    for name in sc.references:
        rows = []
        for res in result.presses[name]:
            rec = next(recs)
            if res.fit is None:
                continue
            counts = np.array([f.counts for f in rec.frames], dtype=float)
            peak = counts[int(np.argmax(counts.sum(axis=(1, 2))))]
            area = np.asarray(res.press.c_A, dtype=float)
            c_d, c_a = res.press.depth * 1e3, float(area.max()) * 1e6
            filled = float(np.asarray(res.press.c_D, dtype=float)[int(np.argmax(area))]) * 1e3
            finger = rec.meta["physics"].get("finger", {})
            rows.append([float(np.max(rec.truth.force)), float(np.max(rec.truth.indentation)) * 1e3,
                         finger.get("max_compression_m", 0.0) * 1e3, finger.get("stiffness_scale", 1.0), c_d,
                         c_a, peak.sum(), (peak > 0).sum(), (peak >= 255).sum(), res.fit.n1, res.fit.n2, res.fit.a1,
                         res.fit.a2, filled, res.fit.a1 / (res.fit.n1 * (c_d / c_a) ** 1.5)])
        out[name] = np.array(rows)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", type=Path, default=REPO / "scenarios" / "thesis_ch6.toml")
    ap.add_argument("--seeds", default="101,102,103,104")
    ap.add_argument("--profile", help="realism profile instead of the scenario's (name or .toml)")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    ap.add_argument("--scenario-set", action="append", default=[], metavar="KEY=VALUE")
    ap.add_argument("--quiet", action="store_true", help="only the means")
    args = ap.parse_args()
    sets = _pairs(args.set, "--set")
    scenario = with_scenario_values(load_scenario(args.scenario), _pairs(args.scenario_set, "--scenario-set"))
    profile = resolve_profile(args.profile or scenario.realism.profile)
    if sets:
        profile = with_values(profile, free_parameters([k for k, _ in sets]), [v for _, v in sets])
    rows: dict[str, list[np.ndarray]] = {name: [] for name in scenario.references}
    for seed in (int(s) for s in args.seeds.split(",")):
        for name, r in press_rows(scenario, profile, seed).items():
            rows[name].append(r)
            if not args.quiet:
                print(f"{name} seed {seed}: " + " ".join(f"{c:>8}" for c in COLUMNS))
                for row in r:
                    print(" " * (len(name) + len(str(seed)) + 7) + " ".join(f"{v:8.3g}" for v in row))
    means = {name: np.mean(np.vstack(r), axis=0) for name, r in rows.items()}
    print("means over the seeds' presses: " + " ".join(f"{c:>8}" for c in COLUMNS))
    for name, m in means.items():
        print(f"  {name:<28}" + " ".join(f"{v:8.3g}" for v in m))
    return 0


if __name__ == "__main__":
    sys.exit(main())
