"""``palpate run SCENARIO --out DIR``: the main job (train, explore, map, report)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from palpate.core.cli.live import add_live_options, hold_live, open_live
from palpate.core.names import file_stem
from palpate.core.world.actuator_kinds import actuator_names


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``run`` command."""
    p = sub.add_parser(
        "run",
        help="run a scenario: train the haptic memory, explore each object, write maps, figures and summary.json",
        description="Run a scenario file end to end. Writes into DIR: summary.json, memory.json, maps/ (NPZ + JSON), "
        "figures/ (PNG) and haptic_materials/ (seed 002 export). Progress goes to stderr.",
    )
    p.add_argument("scenario", help="scenario file (TOML), or the name of a shipped one (palpate scenarios list), "
                   "e.g. thesis_ch6")
    p.add_argument("--out", type=Path, default=None,
                   help="output folder, new or empty, or an earlier run's with --force (default: runs/<scenario name>)")
    p.add_argument("--force", action="store_true",
                   help="replace an earlier run in --out (its summary, maps, figures, exports) and an existing "
                   "--record file; inputs are never overwritten")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.add_argument("--json", action="store_true", help="print summary.json to stdout instead of a text report")
    p.add_argument("--source", default=None,
                   help="registered simulated source that trains the memory and, with actuator sim, explores "
                   "(default: the scenario's training.source, 'sim')")
    a = p.add_argument_group("actuator (who presses during exploration; overrides the scenario's [actuator])")
    a.add_argument("--actuator", choices=actuator_names(), default=None,
                   help="sim: the simulated finger; operator: a person shown each cell (terminal + PNG), presses "
                   "read from --recordings; dynamixel: the finger of --finger on --port, or --emulate")
    a.add_argument("--recordings", type=Path, default=None, metavar="DIR",
                   help="operator: folder of MCAP recordings, one per press, in name order")
    a.add_argument("--port", default=None, help="dynamixel: serial port of the servo bus, e.g. /dev/ttyUSB0")
    a.add_argument("--emulate", action="store_true",
                   help="dynamixel: press through the servo emulator on a pty, backed by MuJoCo physics of the object")
    a.add_argument("--finger", type=Path, default=None, help="dynamixel: finger description (models/fingers/*.toml)")
    a.add_argument("--taxels", default=None, metavar="PORT",
                   help="dynamixel: serial port of the tactile array on the fingertip (docs/tactile_array.md)")
    p.add_argument("--record", type=Path, default=None,
                   help="also record every press's raw streams to this MCAP file (palpate replay reproduces the maps)")
    add_live_options(p)
    p.set_defaults(func=_run)


def _run(args: argparse.Namespace) -> int:
    from palpate.core.session.progress import Progress
    from palpate.core.session.run import run_scenario
    from palpate.core.world.resources import find_scenario
    from palpate.core.world.scenario_file import load_scenario

    scenario = with_actuator_options(load_scenario(find_scenario(args.scenario)), args)
    out = args.out or Path("runs") / file_stem(scenario.name)
    progress = Progress(enabled=not (args.quiet or args.json))
    progress.message(f"palpate run {scenario.name}: fidelity {scenario.fidelity}, seed {scenario.seed}, "
                     f"actuator {scenario.actuator.kind} -> {out}")
    live = open_live(args)
    try:
        summary = run_scenario(scenario, out, progress=progress, source=args.source, record=args.record,
                               force=args.force, live=live)
    except BaseException:
        if live is not None:
            live.close()
        raise
    if args.json:
        json.dump(summary, sys.stdout, indent=2)
        sys.stdout.write("\n")
    elif not args.quiet:
        print(format_report(summary, out))
    sys.stdout.flush()
    hold_live(live, args.live_hold)
    return 0


def with_actuator_options(scenario, args: argparse.Namespace):
    """The scenario with its ``[actuator]`` changed by ``--actuator``, ``--recordings``, ``--port``, ``--emulate``,
    ``--finger`` and ``--taxels``, validated like the file (an error names the option's key).

    The scenario's own keys stay when the kind does not change; paths given on the command line are relative to
    the working directory; ``--port`` replaces ``emulate`` and ``--emulate`` replaces ``port``.
    """
    import dataclasses

    from palpate.core.world.scenario_file import parse_actuator

    options = {"recordings_dir": args.recordings, "port": args.port, "finger": args.finger,
               "emulate": True if args.emulate else None, "taxels": getattr(args, "taxels", None)}
    given = {k: v for k, v in options.items() if v is not None}
    if args.actuator is None and not given:
        return scenario
    raw = scenario.raw.get("actuator", {}) if isinstance(scenario.raw.get("actuator", {}), dict) else {}
    kind = args.actuator or raw.get("kind", "sim")
    table = dict(raw) if raw.get("kind", "sim") == kind else {}
    table["kind"] = kind
    base = scenario.path.parent if scenario.path else Path.cwd()
    # command-line paths are the user's, relative to where they typed them
    table.update({k: str(Path(v).resolve()) if isinstance(v, Path) else v for k, v in given.items()})
    if "port" in given:
        table.pop("emulate", None)
    if "emulate" in given:
        table.pop("port", None)
        if "taxels" not in given:
            table.pop("taxels", None)
    where = f"{scenario.path or 'scenario'} with the command line's actuator options"
    return dataclasses.replace(scenario, actuator=parse_actuator(table, where, base))


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
        ceiling = obj.get("attainable_accuracy") or {}
        if ceiling.get("ceiling") is not None:
            lines.append(f"    attainable accuracy (every column pressed once, same physics) "
                         f"{_pct(ceiling['ceiling'])}; presses to 95%: {ceiling['presses_to_level'] or 'not reached'}, "
                         f"to 95% of the attainable: {ceiling['presses_to_level_of_ceiling'] or 'not reached'}")
        walls = acc.get("by_walls_after_postprocessing")
        if walls:
            clear, near = walls["clear"], walls["near"]
            lines.append(f"    after post-processing: {_pct(clear['accuracy'])} of the {clear['cells']} cells with one "
                         f"material within a press's contact radius, {_pct(near['accuracy'])} of the {near['cells']} "
                         "with a wall within it")
        cal = obj.get("calibration")
        if cal:
            lines.append(f"    calibration error (ECE) of the post-processed map {cal['ece']:.3f} over {cal['cells']} "
                         "cells")
        lines += _fine_map_lines(obj.get("fine_map") or {})
        if obj.get("posterior_per_cycle"):
            final = obj["posterior_per_cycle"][-1]
            for (c, r), p in zip(obj["regions"], final, strict=True):
                probs = "  ".join(f"{m}={v:.2f}" for m, v in zip(mats, p, strict=True))
                lines.append(f"    region ({c},{r}): {probs}")
    if summary.get("sim_to_real"):
        from palpate.core.session.sim_to_real import format_sim_to_real

        lines.append(format_sim_to_real(summary["sim_to_real"]))
    t = summary["timing"]
    lines.append("timing: " + ", ".join(f"{k[:-2]} {v:.1f} s" for k, v in t.items()))
    lines.append(f"outputs in {out}/ (summary.json, memory.json, maps/, figures/, haptic_materials/)")
    return "\n".join(lines)


def _fine_map_lines(fine: dict, most: int = 4) -> list[str]:
    """The fine map's lines of the report: its area right beside the cell map's, and where presses read harder or
    softer than the map names (the ``most`` strongest spots)."""
    lines = []
    area = fine.get("area_accuracy")
    if area:
        lines.append(f"    fine map ({fine['resolution_m'] * 1e3:g} mm): {_pct(area['fine_map'])} of the area right "
                     f"(cell map {_pct(area['cell_map'])}), {fine['walls_read']} walls read")
    spots = fine.get("stiffness_anomalies") or []
    if spots:
        where = ", ".join(f"{a['sign']} at ({a['centroid_m'][0] * 100:.1f}, {a['centroid_m'][1] * 100:.1f}) cm"
                          + _lump_words(a.get("lump")) for a in spots[:most])
        more = f" and {len(spots) - most} more" if len(spots) > most else ""
        lines.append(f"    {len(spots)} spot(s) reading harder or softer than the map names (a lump under the "
                     f"surface?): {where}{more}")
    return lines


def _lump_words(lump: dict | None) -> str:
    """How a spot's lump reads, in a few words ("" when none was read)."""
    return "" if not lump else f" ({lump['material']} from {lump['top_m'] * 1e3:.1f} mm down)"


def _pct(v) -> str:
    return "n/a" if v is None else f"{100 * v:.0f}%"
