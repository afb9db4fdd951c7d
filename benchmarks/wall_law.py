"""The contact law beside a wall: the surface solve's (``sim/bem/law.py``, what the analytic and rigid rungs press
with) against the axisymmetric average it replaced there, both against the 3-D FE reference
(models/image_reference.json) and both timed in one run.

Every wall case of the image reference, tuning and report apart: the worst |force error| at depths from 1 mm, and
the CPU time of a law at a new press point (no cache; one BLAS thread; rounds interleaved, median).

Run: .venv/bin/python benchmarks/wall_law.py [--rounds 3]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from palpate.sim.bem.law import press_law
from palpate.sim.blas import one_blas_thread
from palpate.sim.contact.stack import object_law
from palpate.sim.validity.image_cases import image_cases
from palpate.sim.validity.image_reference import load_image_reference


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    ref = load_image_reference()
    tip = ref.tip
    cases = [c for c in image_cases() if c.family == "wall" and c.name in ref.cases]
    laws = {"surface": lambda obj, x, y, d: press_law(obj, x, y, obj.height, tip, d),
            "axisymmetric": lambda obj, x, y, d: object_law(obj, x, y, obj.height, tip.radius, d)}
    cpu = {name: [] for name in laws}
    worst = {(name, split): 0.0 for name in laws for split in ("tuning", "report")}
    for k in range(args.rounds):
        for name, law_of in laws.items():
            t0 = time.process_time()
            with one_blas_thread():
                made = [law_of(c.object_spec(), *c.press_point, 1.05 * float(ref.cases[c.name].image.depth[-1]))
                        for c in cases]
            cpu[name].append((time.process_time() - t0) / len(cases))
            if k:
                continue
            for case, law in zip(cases, made, strict=True):
                image = ref.cases[case.name].image
                keep = image.depth >= 1e-3 - 1e-12
                err = float(np.max(np.abs(law.force_at(image.depth[keep]) / image.force[keep] - 1.0)))
                worst[name, case.split] = max(worst[name, case.split], err)
    n_t = sum(c.split == "tuning" for c in cases)
    print(f"{len(cases)} wall cases ({n_t} tuning, {len(cases) - n_t} report), depths 1-4 mm, median of {args.rounds}")
    print(f"{'law':<14} {'worst |force error| tuning / report':>36} {'ms a new point':>15}")
    for name in laws:
        print(f"{name:<14} {100 * worst[name, 'tuning']:>17.1f}% / {100 * worst[name, 'report']:.1f}% "
              f"{1e3 * float(np.median(cpu[name])):>15.1f}")
    ratio = float(np.median(cpu["axisymmetric"])) / float(np.median(cpu["surface"]))
    print(f"axisymmetric / surface CPU: {ratio:.1f}x")


if __name__ == "__main__":
    main()
