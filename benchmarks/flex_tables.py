"""What reading the `flex` calibration tables once per run saves a press: one stiff-skin press (block and plate
tables read) repeated in one window, each press given the run's tables (sim/flex/tables.py, as a SimSource passes
them) or reading them from disk itself (``tables=None``, as every press did before), interleaved.

    .venv/bin/python benchmarks/flex_tables.py              # 5 rounds of 15 presses each way
    .venv/bin/python benchmarks/flex_tables.py --rounds 3 --presses 5

Prints the median CPU time per press each way (median over presses in a round, then over rounds) and their ratio;
the forces of the two ways are compared bit for bit.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from palpate.core.session.sources import PressTarget
from palpate.core.world.scene import FingertipSpec, Layer, Material, ObjectSpec, Scene
from palpate.sim.controller import press_profile
from palpate.sim.flex.press import run_flex_press
from palpate.sim.flex.tables import load_flex_tables

RADIUS = 0.008
#: 2 mm of 2 MPa on 100 kPa, 30 mm: wide enough for the plate window, so the press reads the plate table too.
SKIN = ObjectSpec("skin", "box", (0.2, 0.2, 0.03), (0.0, 0.0), Material("base", 1e5, 0.45),
                  layers=(Layer(Material("skin", 2e6, 0.4), 0.002),))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--presses", type=int, default=15, help="presses each way per round")
    args = ap.parse_args()
    scene = Scene((SKIN,), fingertip=FingertipSpec(radius=RADIUS))
    target = PressTarget(0.0, 0.0, depth=0.003, speed=0.01)
    profile = press_profile(target, SKIN.height, radius=RADIUS, timestep=0.002)
    models: dict = {}
    tables = load_flex_tables()

    def press(given):
        return run_flex_press(scene, SKIN, target, profile, models=models, tables=given)

    first = press(None)  # builds the window both ways share
    if not first.meta["plate_corrected"] or not np.array_equal(first.force, press(tables).force):
        raise SystemExit("the two ways differ (or the press read no plate table): nothing to compare")
    medians = {"read per press": [], "given once": []}
    for _ in range(args.rounds):
        for label, given in (("read per press", None), ("given once", tables)):
            cpu = []
            for _ in range(args.presses):
                t0 = time.process_time()
                press(given)
                cpu.append(time.process_time() - t0)
            medians[label].append(float(np.median(cpu)))
    print(f"stiff-skin press (2 mm of 20x on 30 mm, 3 mm deep), CPU per press, {args.rounds} interleaved rounds of "
          f"{args.presses}: forces equal bit for bit")
    for label, values in medians.items():
        print(f"  {label:15} median {1e3 * np.median(values):6.1f} ms  (rounds: "
              + " ".join(f"{1e3 * v:.1f}" for v in values) + ")")
    ratio = np.median(medians["given once"]) / np.median(medians["read per press"])
    print(f"  given once / read per press: {ratio:.3f}")


if __name__ == "__main__":
    main()
