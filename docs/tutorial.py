"""palpate's public API end to end, on the smallest shipped scenario (a few seconds; needs the sim and learn extras).

Run: ``python docs/tutorial.py [OUT_DIR]`` (default: a temporary folder). Every step is one call of ``docs/api.md``:
load a scenario, press one point of it, train its haptic memory and score it with scikit-learn, plug in an
exploration policy and a scikit-learn classifier, run, and read what the run wrote.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np
from sklearn.linear_model import LogisticRegression
from sklearn.model_selection import cross_val_score
from sklearn.pipeline import make_pipeline
from sklearn.preprocessing import StandardScaler

import palpate


def main(out: Path) -> dict:
    print(f"palpate {palpate.__version__}")

    # 1. A scenario: a shipped name or a .toml path. Lengths in the result are m, moduli Pa, forces N.
    scenario = palpate.load_scenario("sweeps/tiny_base")
    block = scenario.objects[0].spec
    print(f"scenario {scenario.name}: materials {scenario.references}, object {block.name} {block.size} m")

    # 2. One press at the centre of map cell (2, 1) (1-based column, row): raw streams and the fitted laws.
    one = palpate.press(scenario, block.name, cell=(2, 1))
    print(f"press at {np.round(one.target, 4)} m: {len(one.frames)} taxel frames, {len(one.poses)} poses, "
          f"peak force {one.truth.force.max():.2f} N, [n1, n2, a1, a2] = {np.round(one.params, 4)}")

    # 3. The haptic memory trained as a run trains it, and scored by scikit-learn on its own training presses.
    training = palpate.train_memory(scenario)
    X, y = training.memory.training_params, training.memory.training_labels
    scores = cross_val_score(palpate.HapticMemory(), X, y, cv=3)
    print(f"leave-one-out accuracy {training.crossval.accuracy:.2f}; 3-fold scikit-learn scores {scores}")

    # 4. Bring your own exploration policy: press the map's cells from the last to the first.
    class Backwards:
        def __init__(self, context: palpate.PolicyContext):
            nx, ny = context.geometry.plane_shape
            self.cells = [(ix, iy) for iy in range(ny) for ix in range(nx)]

        def next_target(self, grid, post=None, last=None):
            return palpate.Target(*self.cells.pop()) if self.cells else None

    palpate.register_policy("backwards", Backwards, replace=True)

    # 5. Run with that policy and a scikit-learn classifier judging each press instead of the haptic memory.
    result = palpate.run(scenario, out, policy="backwards", force=True,
                         classifier=make_pipeline(StandardScaler(), LogisticRegression()))
    summary = result.summary
    obj = summary["objects"][0]
    print(f"run in {result.out}: algorithms {summary['algorithms']}")
    print(f"pressed cells {[p['cell'] for p in obj['per_press']]}, accuracy after post-processing "
          f"{obj['accuracy']['all_cells_after_postprocessing']:.2f}")
    grid = result.map(block.name)
    print(f"most probable material per cell:\n{np.array(scenario.references)[grid.probabilities.argmax(axis=-1)]}")
    palpate.unregister("backwards")
    return summary


if __name__ == "__main__":
    if len(sys.argv) > 1:
        main(Path(sys.argv[1]))
    else:
        with tempfile.TemporaryDirectory() as tmp:
            main(Path(tmp) / "tutorial")
