"""Reading the shipped model tables: the wall table and the boundary templates as shipped (packed fixed-point
arrays, ``palpate.core.files.pack_decimals``) against the same numbers written as JSON lists (the plain reference),
each read by the project's own reader, which checks both alike.

Run: ``.venv/bin/python benchmarks/speed_tables.py [--repeat N]``: median CPU seconds per read and the ratio, and
whether both forms give the same arrays bit for bit.
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from palpate.core.boundary.templates import TEMPLATES_FILE, read_templates
from palpate.core.world.resources import models_dir
from palpate.sim.bem.wall import TABLE_PATH, _read_wall_table


def _listed(doc: dict, arrays: dict) -> dict:
    return dict(doc, **{k: np.asarray(v).tolist() for k, v in arrays.items()})


def _cpu(read, path: Path, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t = time.process_time()
        read(path)
        times.append(time.process_time() - t)
    return statistics.median(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5, help="reads per form (median reported)")
    args = ap.parse_args()
    wall, templates = TABLE_PATH, models_dir() / TEMPLATES_FILE
    table, tpl = _read_wall_table(wall), read_templates(templates)
    with tempfile.TemporaryDirectory() as tmp:
        wall_list, tpl_list = Path(tmp) / "wall.json", Path(tmp) / "templates.json"
        wall_list.write_text(json.dumps(_listed(json.loads(wall.read_text()), {"share": table.share})))
        doc = json.loads(templates.read_text())
        # the file holds angles 0-45 deg; the reader spreads them round the circle
        n = len(doc["angles_deg"])
        tpl_list.write_text(json.dumps(_listed(doc, {"wall": tpl.wall[:, :n], "plain": tpl.plain})))
        same = (np.array_equal(_read_wall_table(wall_list).share, table.share)
                and np.array_equal(read_templates(tpl_list).wall, tpl.wall))
        print(f"{'table':<20} {'packed s':>9} {'list s':>8} {'ratio':>7} {'packed MB':>10} {'list MB':>8}")
        for name, read, shipped, listed in (("wall table", _read_wall_table, wall, wall_list),
                                            ("boundary templates", read_templates, templates, tpl_list)):
            packed, plain = _cpu(read, shipped, args.repeat), _cpu(read, listed, args.repeat)
            print(f"{name:<20} {packed:9.4f} {plain:8.4f} {packed / plain:7.3f} {shipped.stat().st_size / 1e6:10.2f} "
                  f"{listed.stat().st_size / 1e6:8.2f}")
    print(f"same arrays bit for bit: {same}")


if __name__ == "__main__":
    main()
