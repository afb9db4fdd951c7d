"""Make the boundary templates the per-press boundary reading uses (sim/bem/templates.py): the bem rung's image
of the default fingertip beside a wall, over the grid of depths, angles 0-45 deg, offsets and contrasts there.

About 700 bem solves, a few minutes on one core.

Run: .venv/bin/python benchmarks/boundary_templates.py [--write | --out FILE]
(--write: replace models/boundary_templates.json)
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from tqdm import tqdm

from palpate.core.boundary.templates import TEMPLATES_FILE, read_templates
from palpate.core.world.resources import models_dir
from palpate.core.world.scene import FingertipSpec
from palpate.sim.bem import templates as bt
from palpate.sim.bem.wall import load_wall_table


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--write", action="store_true", help="replace models/boundary_templates.json")
    parser.add_argument("--out", type=Path, help="write the templates here instead")
    args = parser.parse_args()
    out = models_dir() / TEMPLATES_FILE if args.write else args.out
    if out is None:
        parser.error("give --write or --out FILE")
    tip = FingertipSpec()
    n = len(bt.ANGLES_DEG) * len(bt.OFFSETS) * len(bt.CONTRASTS)
    t0 = time.process_time()
    with tqdm(total=n, desc="wall cases", unit="case") as bar:
        doc = bt.make_templates(tip, load_wall_table(), progress=bar.update)
    out.write_text(json.dumps(doc, separators=(",", ":")) + "\n", encoding="utf-8")
    templates = read_templates(out)
    print(f"{out}: {len(templates.angles)} angles x {len(templates.offsets)} offsets x {len(templates.contrasts)} "
          f"contrasts x {len(templates.depths)} depths; {time.process_time() - t0:.0f} s CPU")


if __name__ == "__main__":
    main()
