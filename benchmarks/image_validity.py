"""Each rung's taxel image against the 3-D FE image reference (models/image_reference.json): force error, rms sensel
error as a share of the reference's peak, x-asymmetry against the reference's, active sensels, per case and depth;
tuning and report (held-out) cases printed apart, with a summary per rung and family.

Run: .venv/bin/python benchmarks/image_validity.py [--rungs analytic,bem,flex] [--family wall] [--wall-table PATH]
[--write]  (--write: replace models/image_validity.json, the image columns ``auto`` reads)
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from palpate.core.errors import ValidationError
from palpate.sim.bem.wall import load_wall_table
from palpate.sim.validity.image_cases import image_cases
from palpate.sim.validity.image_measure import score, scored
from palpate.sim.validity.image_reference import load_image_reference
from palpate.sim.validity.image_table import IMAGE_TABLE_PATH, format_summary, rows_from_scores, table_document


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rungs", default="analytic,bem,flex")
    parser.add_argument("--family", default=None)
    parser.add_argument("--wall-table", type=Path, default=None)
    parser.add_argument("--write", action="store_true", help="replace models/image_validity.json")
    args = parser.parse_args()
    ref = load_image_reference()
    walls = load_wall_table(args.wall_table) if args.wall_table else None
    cases = [c for c in image_cases() if c.name in ref.cases and (args.family is None or c.family == args.family)]
    rows = []
    print(f"{'case':<44} {'split':<6} {'rung':<8} {'mix':<7} {'force err %':>24} {'rms % of peak':>24} "
          f"{'asym x (ref)':>30} {'cpu s':>6}")
    for case in cases:
        entry = ref.cases[case.name]
        for rung in args.rungs.split(","):
            if not scored(rung, case.family):
                continue
            try:
                s = score(case, entry.image, rung, entry.split, ref.tip, walls)
            except ValidationError as exc:  # a rung that refuses the case (flex under 1 mm skins) is not scored
                print(f"{case.name:<44} {entry.split:<6} {rung:<8} refused: {exc}")
                continue
            e = s.errors
            rows.append(s)
            asym = " ".join(f"{a:+.2f}({r:+.2f})" for a, r in zip(e.asymmetry[1:], e.reference_asymmetry[1:],
                                                                   strict=True))
            print(f"{case.name:<44} {entry.split:<6} {rung:<8} {s.mixing:<7} "
                  f"{' '.join(f'{100 * v:+4.1f}' for v in e.force_error):>24} "
                  f"{' '.join(f'{100 * v:4.1f}' for v in e.rms_share):>24} {asym:>30} {s.cpu:6.2f}", flush=True)
    print()
    print(format_summary(rows_from_scores(rows)))
    if args.write:
        if args.family is not None or args.wall_table is not None:
            raise SystemExit("--write needs every family and the shipped wall table")
        doc = table_document(rows_from_scores(rows), {
            "how": "benchmarks/image_validity.py --write (palpate.sim.validity.image_measure)",
            "reference": "models/image_reference.json (3-D FE)", "rungs": args.rungs})
        IMAGE_TABLE_PATH.write_text(json.dumps(doc))
        print(f"wrote {IMAGE_TABLE_PATH}")


if __name__ == "__main__":
    main()
