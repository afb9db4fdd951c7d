"""Share of the main job's run time spent on figures (target: at most a third of ``summary.json``'s timing).

Run: ``.venv/bin/python benchmarks/speed_figures.py [--scenario thesis_ch6] [--repeat 3]``. Each repeat runs the
scenario end to end in a fresh process (matplotlib's import and first-use costs count, as in a real run), twice:

- ``background`` (what ``palpate run`` does): figures are drawn in a second process as their data become ready,
  and ``figures_s`` is the wait for the last ones after exploration;
- ``inline``: every figure drawn in the run's own process after exploration (the reference: what the figures cost
  when nothing overlaps).

Printed per run: wall seconds per stage from the summary's ``timing``, the figures' share, and the CPU seconds
spent drawing (the background process's, or the run's own figure stage). Wall times on a shared machine vary with
its load; the medians over the repeats are printed at the end.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

CHILD = """
import json, resource, sys, time
from palpate.core.session import figure_jobs, run as run_module
from palpate.core.world.resources import find_scenario
from palpate.core.world.scenario_file import load_scenario
if sys.argv[3] == "inline":
    run_module.FigureDrawer = lambda folder, **kw: figure_jobs.FigureDrawer(folder, background=False)
cpu = {}
finish = figure_jobs.FigureDrawer.finish
def timed_finish(self, progress=None):
    t = time.process_time()
    try:
        return finish(self, progress)
    finally:
        cpu["figures_inline"] = time.process_time() - t
figure_jobs.FigureDrawer.finish = timed_finish
summary = run_module.run_scenario(load_scenario(find_scenario(sys.argv[1])), sys.argv[2])
children = resource.getrusage(resource.RUSAGE_CHILDREN)
print(json.dumps({"timing": summary["timing"], "background_cpu": children.ru_utime + children.ru_stime,
                  "inline_cpu": cpu.get("figures_inline", 0.0)}))
"""


def run_once(scenario: str, mode: str) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        out = subprocess.run([sys.executable, "-c", CHILD, scenario, str(Path(tmp) / "run"), mode], check=True,
                             capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="thesis_ch6")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    shares: dict[str, list[float]] = {"background": [], "inline": []}
    print(f"{args.scenario}: wall seconds per stage (summary.json timing), figures' share of the run, CPU drawing")
    for i in range(args.repeat):
        for mode in ("background", "inline"):
            r = run_once(args.scenario, mode)
            t = r["timing"]
            share = t["figures_s"] / sum(t.values())
            shares[mode].append(share)
            drawing = r["background_cpu"] if mode == "background" else r["inline_cpu"]
            stages = "  ".join(f"{k[:-2]} {v:5.2f}" for k, v in t.items())
            print(f"  run {i + 1} {mode:10}: {stages}   figures {100 * share:4.1f}% of the run; "
                  f"{drawing:.2f} s CPU drawing")
    for mode, vals in shares.items():
        print(f"median figures share, {mode}: {100 * statistics.median(vals):.1f}% (target <= 33.3%)")


if __name__ == "__main__":
    main()
