"""``palpate calibrate realism PARAMS.csv``: fit a realism profile to a per-press parameter table and write it.

The fit is the method of simulated moments of :mod:`palpate.sim.realism.calibrate`: the scenario's training
protocol is simulated on the tuning seeds for every candidate, and the fitted profile is then reported on seeds it
was not tuned on. Progress (one line per candidate) goes to stderr; the comparison table to stdout.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np

from palpate.core import files
from palpate.core.errors import RecordingError, ValidationError
from palpate.sim.realism.moments import MOMENTS
from palpate.sim.realism.search import SEARCHES

DEFAULT_TUNE_SEEDS = "101,102,103,104"
DEFAULT_REPORT_SEEDS = "201,202,203,204,205,206"


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``calibrate`` command group (``calibrate realism``)."""
    p = sub.add_parser("calibrate", help="fit simulation models to real data (calibrate realism)",
                       description="Fit simulation models to real data.")
    groups = p.add_subparsers(dest="what", metavar="WHAT")
    groups.required = True
    r = groups.add_parser(
        "realism", help="fit a realism profile to a per-press parameter table (method of simulated moments)",
        description="Fit the free parameters of a realism profile so that the scenario's simulated training presses "
        "match the table's per-material statistics (log mean of n1 and a1, log CV of n1 and a1, negative share of "
        "n2, leave-one-out self posterior; a2's sign is reported only), averaged over the tuning seeds; "
        "then report the fitted profile on the report seeds. Deterministic for given arguments. Writes a profile "
        "file a scenario names in [realism] profile.")
    r.add_argument("table", type=Path, help="per-press parameter CSV (material,n1,n2,a1,a2,phi_n,phi_a), e.g. "
                   "models/realism/seed000_tables_6_3_to_6_5.csv")
    r.add_argument("--scenario", type=Path, required=True,
                   help="scenario whose reference materials, training protocol, fingertip and sensors are simulated")
    r.add_argument("--out", type=Path, required=True, help="profile file to write (TOML)")
    r.add_argument("--start", default="lab", help="profile the fit starts from and takes fixed values from: a "
                   "preset, a shipped profile's name or a .toml file (default: lab)")
    r.add_argument("--free", default=None, help="comma-separated parameters to fit, as section.key of the profile "
                   "file (default: the pulp's stiffness, stiffening and stiffness CV, the press's depth CV, the pad's "
                   "sensitivity, non-linearity and gain drift, the tracker's clock wander, the material's relaxation); "
                   "pad.pitch_mm and pad.fill (sensel side over pitch) fit the scenario's pad, printed for its "
                   "[fingertip]")
    r.add_argument("--fit-moduli", default="", metavar="MATERIALS",
                   help="comma-separated reference materials whose Young's modulus is fitted too (a factor on the "
                   "scenario's); the fitted moduli are printed and recorded in the profile's provenance, for the "
                   "scenario's young_kpa")
    r.add_argument("--tune-seeds", default=DEFAULT_TUNE_SEEDS, help=f"seeds tuned on (default {DEFAULT_TUNE_SEEDS})")
    r.add_argument("--report-seeds", default=DEFAULT_REPORT_SEEDS,
                   help=f"seeds reported on, never tuned on (default {DEFAULT_REPORT_SEEDS})")
    r.add_argument("--budget", type=int, default=150, help="candidates simulated (default 150)")
    r.add_argument("--design", type=int, default=None,
                   help="candidates of the Latin hypercube before the search (default: a third of the budget; 0: "
                   "refine the start profile with the search only)")
    r.add_argument("--search", default="trust-region", choices=SEARCHES,
                   help="the search after the design: trust-region (default; Gauss-Newton on a linear model of the "
                   "moments' residuals fitted to candidates around the current point) or nelder-mead (the simplex; "
                   "stalls with five or more free parameters)")
    r.add_argument("--fidelity", default=None, choices=("analytic", "bem", "rigid", "flex", "auto"),
                   help="fidelity of the simulated presses (default: the scenario's)")
    r.add_argument("--fit-a2-sign", action="store_true",
                   help="fit the share of presses with a2 < 0 too (default: reported only, as the shipped fits)")
    r.add_argument("--tolerance", action="append", default=[], metavar="STATISTIC=VALUE",
                   help=f"replace a statistic's tolerance in the objective (repeatable; statistics: "
                   f"{', '.join(MOMENTS)}; inf: reported only), e.g. log_mean_a1=0.1 to weigh a1's location three "
                   "times the default")
    r.add_argument("--name", default=None, help="the profile's name (default: the output file's stem)")
    r.add_argument("--quick", action="store_true",
                   help="a smoke run: budget 6, two tuning and two report seeds, analytic fidelity")
    r.add_argument("--force", action="store_true", help="overwrite --out if it exists")
    r.set_defaults(func=run_calibrate_realism)


def _seeds(text: str, option: str) -> list[int]:
    try:
        seeds = [int(s) for s in text.split(",") if s.strip()]
    except ValueError:
        raise ValidationError(f"{option}: expected comma-separated integers, got {text!r}") from None
    if not seeds or any(s < 0 for s in seeds) or len(set(seeds)) != len(seeds):
        raise ValidationError(f"{option}: expected distinct seeds >= 0, got {text!r}")
    return seeds


def _tolerances(items: list[str]) -> dict[str, float]:
    out = {}
    for item in items:
        name, sep, value = item.partition("=")
        try:
            if not sep:
                raise ValueError
            out[name.strip()] = float(value)
        except ValueError:
            raise ValidationError(f"--tolerance: expected STATISTIC=VALUE, got {item!r}") from None
    return out


def run_calibrate_realism(args: argparse.Namespace) -> int:
    """Run the fit, write the profile, print the comparison; returns the exit code."""
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, "1")
    from palpate.core.perception.param_stats import table_from_csv
    from palpate.core.world.scenario_file import load_scenario
    from palpate.sim.realism.calibrate import calibrate
    from palpate.sim.realism.parameters import DEFAULT_FREE, free_parameters
    from palpate.sim.realism.profile_file import profile_to_toml, resolve_profile

    if args.out.exists() and not args.force:
        raise ValidationError(f"{args.out} exists; pass --force to overwrite it")
    table = table_from_csv(args.table)
    scenario = load_scenario(args.scenario)
    start = resolve_profile(args.start)
    moduli = [f"young.{m.strip()}" for m in args.fit_moduli.split(",") if m.strip()]
    free = free_parameters([*(args.free.split(",") if args.free else DEFAULT_FREE), *moduli], scenario.references)
    tune, report = _seeds(args.tune_seeds, "--tune-seeds"), _seeds(args.report_seeds, "--report-seeds")
    tolerances = _tolerances(args.tolerance)
    budget, fidelity = args.budget, args.fidelity
    if args.quick:
        budget, tune, report, fidelity = 6, tune[:2], report[:2], "analytic"
    print(f"palpate calibrate realism: {args.table.name} on scenario {scenario.name} "
          f"({fidelity or scenario.fidelity}), "
          f"{len(free)} free parameters, budget {budget}, tuning seeds {tune}, report seeds {report}", file=sys.stderr)
    result = calibrate(table, scenario, start, free, tune_seeds=tune, report_seeds=report, budget=budget,
                       fidelity=fidelity, name=args.name or args.out.stem, table_name=args.table.name,
                       design=args.design, fit_a2_sign=args.fit_a2_sign, search=args.search, tolerances=tolerances,
                       log=lambda s: print(s, file=sys.stderr, flush=True))
    try:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        files.write_text(args.out, profile_to_toml(result.profile))  # a killed write keeps an older profile whole
    except OSError as exc:
        raise RecordingError(f"calibrate realism: cannot write {args.out}: {exc}") from exc
    print(format_calibration(result))
    print(f"wrote {args.out}")
    return 0


def format_calibration(result) -> str:
    """The table printed after a fit: per material, each statistic real / tuned / report."""
    from palpate.sim.realism.calibrate import MOMENTS

    prov = result.profile.provenance
    lines = [f"objective {result.objective:.3f} after {result.evaluations} candidates; fitted: " + ", ".join(
        f"{k}={v:.4g}" for k, v in prov["free"].items())]
    if any(k.startswith("young.") for k in prov["free"]):
        lines.append("moduli for the scenario's young_kpa: " + ", ".join(
            f"{m} {v:.4g}" for m, v in prov["moduli_kpa"].items()))
    if any(k.startswith("pad.") for k in prov["free"]):
        lines.append(f"pad for the scenario's [fingertip]: pitch_mm {prov['pad_mm']['pitch']:.4g}, "
                     f"sensel_mm {prov['pad_mm']['sensel']:.4g}")
    lines.append(f"{'material':<14}{'statistic':<14}{'real':>10}{'tuned':>10}{'report':>10}")
    for i, m in enumerate(result.materials):
        for k, name in enumerate(MOMENTS):
            show = np.exp if name.startswith("log_") else (lambda v: v)
            label = name[4:] if name.startswith("log_") else name
            lines.append(f"{m if k == 0 else '':<14}{label:<14}{show(result.real[i, k]):>10.4g}"
                         f"{show(result.tuned[i, k]):>10.4g}{show(result.report[i, k]):>10.4g}")
    return "\n".join(lines)
