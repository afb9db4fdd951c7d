"""Make the lump templates the lump depth reading uses (sim/contact/lump_templates.py): the pad's summed pressure
over layers and on-axis spheres and cylinders against the top material alone, over the grid of contrasts, tops,
radii and indentations there.

About 1300 contact-law solves, ten minutes on two cores.

Run: .venv/bin/python benchmarks/lump_templates.py [--write | --out FILE] [--jobs 2]
(--write: replace models/lump_templates.json)
"""

from __future__ import annotations

import argparse
import json
import time
from concurrent.futures import ProcessPoolExecutor
from functools import partial
from pathlib import Path

from tqdm import tqdm

from palpate.core.boundary.lump_templates import LUMP_TEMPLATES_FILE, read_lump_templates
from palpate.core.world.resources import models_dir
from palpate.core.world.scene import FingertipSpec
from palpate.sim.contact import lump_templates as lt


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--write", action="store_true", help="replace models/lump_templates.json")
    parser.add_argument("--out", type=Path, help="write the templates here instead")
    parser.add_argument("--jobs", type=int, default=2, help="worker processes (default 2)")
    args = parser.parse_args()
    out = models_dir() / LUMP_TEMPLATES_FILE if args.write else args.out
    if out is None:
        parser.error("give --write or --out FILE")
    tip = FingertipSpec()
    t0 = time.perf_counter()
    with ProcessPoolExecutor(max_workers=max(1, args.jobs)) as pool:
        blocks = list(tqdm(pool.map(partial(lt.contrast_block, tip), lt.CONTRASTS), total=len(lt.CONTRASTS),
                           desc="contrasts", unit="contrast"))
    doc = lt.make_lump_templates(tip, blocks)
    out.write_text(json.dumps(doc, separators=(",", ":")) + "\n", encoding="utf-8")
    templates = read_lump_templates(out)
    print(f"{out}: {len(templates.shapes)} shapes x {len(templates.contrasts)} contrasts x {len(templates.tops)} tops "
          f"x {len(templates.depths)} depths; {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
