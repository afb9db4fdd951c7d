"""``palpate replay REC.mcap --memory memory.json --out DIR``: the perception stack on a recording."""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from palpate.core.cli.live import add_live_options, hold_live, open_live


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``replay`` command."""
    p = sub.add_parser(
        "replay",
        help="run the perception stack on a recording and write the same maps, figures and summary as a run",
        description="Replay an MCAP recording (from palpate run --record, palpate import, palpate record) through "
        "sync, features, segmentation, fits, the run's memory (the haptic memory, or the classifier plugin that "
        "judged the run, fitted again to its training rows) and the map. A recording made by palpate run is "
        "cut into the same presses and rebuilds the run's maps exactly.",
    )
    p.add_argument("recording", type=Path, help="MCAP recording")
    p.add_argument("--memory", type=Path, required=True,
                   help="the run's memory.json: a haptic memory, or a classifier plugin's (the plugin must be "
                   "installed or registered)")
    p.add_argument("--out", type=Path, required=True,
                   help="output folder: new or empty, or an earlier replay's with --force")
    p.add_argument("--force", action="store_true", help="replace an earlier replay in --out")
    p.add_argument("--no-audit", action="store_true",
                   help="accept a haptic memory whose stored parameters do not match a re-fit of its training "
                   "data (or a classifier plugin that describes itself differently from the run's)")
    p.add_argument("--memory-layers", type=Path, default=None,
                   help="per-voxel-layer memories (default: memory_layers.json beside --memory, if present)")
    p.add_argument("--cell-mm", type=float, default=10.0,
                   help="grid cell for recordings without map geometry (default 10 mm)")
    p.add_argument("--no-figures", action="store_true", help="skip PNG figures")
    p.add_argument("--salvage", action="store_true",
                   help="replay a truncated or damaged recording (e.g. of a killed run) from its complete chunks")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    add_live_options(p)
    p.add_argument("--live-speed", type=float, default=1.0, metavar="X",
                   help="with --live: play the presses at X times real time (0: as fast as possible; default 1)")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.set_defaults(func=_replay)


def _replay(args: argparse.Namespace) -> int:
    from palpate.core.errors import ValidationError
    from palpate.core.perception.layered_memory import LayeredMemory
    from palpate.core.perception.memory import HapticMemory
    from palpate.core.perception.memory_loading import load_memory
    from palpate.core.session.progress import Progress
    from palpate.core.session.replay import replay_recording

    if not (math.isfinite(args.cell_mm) and args.cell_mm > 0):
        raise ValidationError(f"--cell-mm must be a finite number > 0, got {args.cell_mm}")
    memory = load_memory(args.memory, audit=not args.no_audit)
    layers_file = args.memory_layers or args.memory.with_name("memory_layers.json")
    layers = None
    if args.memory_layers is not None and not isinstance(memory, HapticMemory):
        raise ValidationError(f"--memory-layers: {args.memory} is classifier {memory.label!r}, not a haptic memory; "
                              "per-layer memories judge voxel maps with palpate's haptic memory only")
    # a classifier run maps in 2-D and writes no layers: a layers file lying beside its memory is not its own
    if isinstance(memory, HapticMemory) and (args.memory_layers is not None or layers_file.is_file()):
        layers = LayeredMemory.load(memory, layers_file)
    if not args.live_speed >= 0:
        raise ValidationError(f"--live-speed must be >= 0, got {args.live_speed}")
    live = open_live(args)
    try:
        summary = replay_recording(args.recording, memory, args.out, layers=layers, cell_size=args.cell_mm * 1e-3,
                                   progress=Progress(enabled=not (args.quiet or args.json)),
                                   figures=not args.no_figures, force=args.force,
                                   inputs=[args.memory, layers_file if layers is not None else None],
                                   salvage=args.salvage, live=live, live_speed=args.live_speed)
    except BaseException:
        if live is not None:
            live.close()
        raise
    if args.json:
        json.dump(summary, sys.stdout, indent=2)
        sys.stdout.write("\n")
    elif not args.quiet:
        if summary["salvaged"]:
            print(f"{args.recording}: damaged or truncated; replayed what its complete chunks hold")
        for obj in summary["objects"]:
            print(f"{obj['name']}: {obj['presses']} presses replayed, mean entropy "
                  f"{obj['mean_entropy_after_postprocessing']:.3f} after post-processing")
        print(f"outputs in {args.out}/")
    sys.stdout.flush()
    hold_live(live, args.live_hold)
    return 0
