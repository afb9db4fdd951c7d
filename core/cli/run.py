"""``palpate run SCENARIO --out DIR``: the main job (train, explore, map, report)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``run`` command."""
    p = sub.add_parser(
        "run",
        help="run a scenario: train the haptic memory, explore each object, write maps, figures and summary.json",
        description="Run a scenario file end to end. Writes into DIR: summary.json, memory.json, maps/ (NPZ + JSON), "
        "figures/ (PNG) and haptic_materials/ (seed 002 export). Progress goes to stderr.",
    )
    p.add_argument("scenario", type=Path, help="scenario file (TOML), e.g. scenarios/thesis_ch6.toml")
    p.add_argument("--out", type=Path, default=None, help="output folder (default: runs/<scenario name>)")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.add_argument("--json", action="store_true", help="print summary.json to stdout instead of a text report")
    p.add_argument("--source", default="sim", help="registered source to press with (default: sim)")
    p.add_argument("--record", type=Path, default=None,
                   help="also record every press's raw streams to this MCAP file (palpate replay reproduces the maps)")
    p.set_defaults(func=_run)


def _run(args: argparse.Namespace) -> int:
    from palpate.core.progress import Progress
    from palpate.core.run import run_scenario
    from palpate.core.scenario import load_scenario

    scenario = load_scenario(args.scenario)
    out = args.out or Path("runs") / scenario.name
    progress = Progress(enabled=not (args.quiet or args.json))
    progress.message(f"palpate run {scenario.name}: fidelity {scenario.fidelity}, seed {scenario.seed} -> {out}")
    summary = run_scenario(scenario, out, progress=progress, source=args.source, record=args.record)
    if args.json:
        json.dump(summary, sys.stdout, indent=2)
        sys.stdout.write("\n")
    elif not args.quiet:
        print(format_report(summary, out))
    return 0


def format_report(summary: dict, out: Path) -> str:
    """A short human-readable report of a run summary."""
    lines = []
    mats = summary["materials"]
    cv = summary.get("crossval")
    if cv:
        lines.append("Leave-one-out confusion (rows: true material, columns: MAP decision)")
        lines.append(" " * 14 + "".join(f"{m:>12}" for m in mats))
        for m, row in zip(mats, cv["confusion"], strict=True):
            lines.append(f"{m:<14}" + "".join(f"{v:12.2f}" for v in row))
    for obj in summary["objects"]:
        acc = obj["accuracy"]
        lines.append(
            f"{obj['name']}: {obj['presses']} presses, true material(s) {', '.join(obj['true_materials'])}; "
            f"accuracy explored {_pct(acc['explored_before_postprocessing'])}, all cells "
            f"{_pct(acc['all_cells_before_postprocessing'])} -> {_pct(acc['all_cells_after_postprocessing'])} "
            f"after post-processing; mean entropy {obj['mean_entropy_after_each_press'][-1]:.3f} -> "
            f"{obj['mean_entropy_after_postprocessing']:.3f}"
        )
        if obj.get("posterior_per_cycle"):
            final = obj["posterior_per_cycle"][-1]
            for (c, r), p in zip(obj["regions"], final, strict=True):
                probs = "  ".join(f"{m}={v:.2f}" for m, v in zip(mats, p, strict=True))
                lines.append(f"    region ({c},{r}): {probs}")
    t = summary["timing"]
    lines.append("timing: " + ", ".join(f"{k[:-2]} {v:.1f} s" for k, v in t.items()))
    lines.append(f"outputs in {out}/ (summary.json, memory.json, maps/, figures/, haptic_materials/)")
    return "\n".join(lines)


def _pct(v) -> str:
    return "n/a" if v is None else f"{100 * v:.0f}%"
