"""``palpate bench``: the speed/accuracy trade of the simulation, and where each fidelity is valid, measured.

Writes tradeoff.txt (the table), tradeoff.json and pareto.png (:mod:`palpate.sim.tradeoff`), and validity.txt /
validity.json (each fidelity's force against the FE reference over thickness, depth, Poisson ratio, skins, lumps
and edges, with each fidelity's cost: :mod:`palpate.sim.validity`) and image_validity.txt (analytic's and bem's taxel
images against the 3-D FE image reference) into --out, and prints them (or the JSON with
--json). ``--quick`` is the CI sweep (a few minutes on two cores): fewer settings, the validity subset; without it
the workstation sweep and every validity case (``--write-table`` then also replaces the validity table ``auto``
reads, models/validity_table.json).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

from palpate.core import files
from palpate.core.errors import RecordingError, ValidationError


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``bench`` command."""
    p = sub.add_parser(
        "bench", help="measure simulation speed against accuracy (table, JSON, Pareto plot)",
        description="Sweep fidelity, timestep, contact resolution and sensor rate; per setting print wall time per "
        "press, real-time factor, peak memory, feature and fit errors against the finest stable reference and "
        "Hertz, and leave-one-out accuracy; name the cheapest settings within 5% and 1%. --quick is the CI sweep.",
    )
    p.add_argument("--quick", action="store_true", help="the CI sweep: fewer settings and presses")
    p.add_argument("--out", type=Path, default=Path("bench"), help="folder for tradeoff.txt/.json, pareto.png")
    p.add_argument("--json", action="store_true", help="print the JSON report instead of the table")
    p.add_argument("--write-table", action="store_true",
                   help="with the full sweep: also replace models/validity_table.json, the table auto reads")
    p.set_defaults(func=run_bench)


def run_bench(args: argparse.Namespace) -> int:
    """Run the sweep, write the outputs, print the table; returns the exit code."""
    # one core, as the table's real-time factors claim
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, "1")
    from palpate.sim import tradeoff, tradeoff_report
    from palpate.sim.validity import cases, measure, reference
    from palpate.sim.validity import report as validity_report
    from palpate.sim.validity import table as validity_table

    try:
        args.out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise RecordingError(f"bench: cannot create the output folder {args.out}: {exc}") from exc
    settings = tradeoff.quick_settings() if args.quick else tradeoff.full_settings()
    seeds = (0, 1, 2, 3) if args.quick else (0, 1, 2, 3, 4, 5)

    # One row per setting, its label printed as the setting starts and its result added when it ends: a long
    # setting (flex) shows what is running instead of nothing.
    count = iter(range(1, len(settings) + 2))
    row_open = []

    def started(setting) -> None:
        print(f"  [{next(count)}/{len(settings) + 1}] {setting.label}: ", end="", file=sys.stderr, flush=True)
        row_open.append(True)

    def progress(r) -> None:
        state = f"failed ({r.failed})" if r.failed else f"{1e3 * r.wall_per_press:.1f} ms/press"
        head = "" if row_open and row_open.pop() else f"  {r.setting.label} (the reference, measured above): "
        print(head + state, file=sys.stderr, flush=True)

    report = tradeoff.run_tradeoff(settings, seeds=seeds, progress=progress, on_start=started)
    doc = tradeoff_report.report_to_dict(report)
    table = tradeoff_report.format_table(report)

    def case_done(case, errs) -> None:
        print(f"  validity {case.name}", file=sys.stderr, flush=True)

    chosen = cases.quick_cases() if args.quick else cases.validity_cases()
    validity = measure.measure_table(chosen, reference.load_reference(), progress=case_done)
    validity_text = validity_report.format_table(validity)
    doc["validity"] = validity.to_dict()
    image_text = _image_columns(args.quick)
    try:
        files.write_text(args.out / "tradeoff.txt", table + "\n")
        files.write_text(args.out / "tradeoff.json", json.dumps(doc, indent=1, allow_nan=False))
        files.write_text(args.out / "validity.txt", validity_text + "\n")
        validity_json = json.dumps(doc["validity"], indent=1, allow_nan=False)
        files.write_text(args.out / "validity.json", validity_json)
        files.write_text(args.out / "image_validity.txt", image_text + "\n")
        tradeoff_report.pareto_plot(report, args.out / "pareto.png")
        if args.write_table and not args.quick:
            files.write_text(validity_table.TABLE_PATH, validity_json + "\n")
    except OSError as exc:
        raise RecordingError(f"bench: cannot write into {args.out}: {exc}") from exc
    print(json.dumps(doc, indent=1) if args.json else table + "\n\n" + validity_text + "\n\n" + image_text)
    return 0


def _image_columns(quick: bool) -> str:
    """The image columns measured now: each image rung on the image reference's cases of the families it is scored
    on (held-out ones only with ``quick``)."""
    from palpate.sim.validity.image_cases import image_cases
    from palpate.sim.validity.image_measure import IMAGE_RUNGS, score, scored
    from palpate.sim.validity.image_reference import load_image_reference
    from palpate.sim.validity.image_table import format_summary, rows_from_scores

    ref = load_image_reference()
    scores = []
    for case in image_cases():
        if case.name not in ref.cases or (quick and ref.cases[case.name].split != "report"):
            continue
        for rung in IMAGE_RUNGS:
            if not scored(rung, case.family):
                continue
            try:
                scores.append(score(case, ref.cases[case.name].image, rung, ref.cases[case.name].split, ref.tip))
            except ValidationError:
                continue  # a rung that refuses the case (flex under a skin thinner than it resolves) is not scored
    return format_summary(rows_from_scores(scores))
