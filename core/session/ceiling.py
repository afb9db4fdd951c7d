"""Attainable accuracy: what a full raster reaches with the scene's own physics, and how fast a run got near it.

A press is ~11 mm across at palpation depth, so it blurs walls and one-cell features: on cells of about that size
even a press on every cell leaves some cells wrong, and "95% right" may be out of reach for any policy. The ceiling
is measured, not modelled: every column of the map is pressed once, in raster order, by a fresh simulated source
(its own seed), and the post-processed map is scored like the run's. A run that itself pressed every column in
raster order is its own ceiling (reported whatever ``outputs.attainable_accuracy`` says: it costs nothing); any other
run measures it only when the scenario opts in, as it costs a press on every cell.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from palpate.core.session.explore import ObjectResult, explore_object
from palpate.core.session.progress import Progress

#: A run counts presses to this accuracy, absolute and as a fraction of the ceiling.
LEVEL = 0.95


@dataclass(frozen=True)
class Ceiling:
    """The attainable accuracy of one object's map.

    Attributes:
        accuracy: of the post-processed map after one press on every column (None without ground truth).
        presses: presses the ceiling took (the map's column count).
        reused_run: True when the run itself was that raster (no extra presses).
    """

    accuracy: float | None
    presses: int
    reused_run: bool


def presses_to(accuracies: list[float | None], level: float) -> int | None:
    """1-based press count at which the accuracy first reaches ``level`` (None if it never does)."""
    for k, a in enumerate(accuracies):
        if a is not None and a >= level - 1e-12:
            return k + 1
    return None


def is_full_raster(obj: ObjectResult) -> bool:
    """True when the run pressed every column of the map in raster order (then it is its own ceiling, free)."""
    nx, ny = obj.geometry.plane_shape
    return obj.policy == "raster" and len({s.cell for s in obj.steps}) == nx * ny


def attainable_accuracy(scenario, entry, memory, make_source, seed: int, progress: Progress, obj: ObjectResult,
                        layers=None) -> Ceiling:
    """The ceiling of one explored object (module docstring): ``obj`` is the run's result, reused when it was a
    full raster; otherwise every column is pressed once through ``make_source`` with ``seed``."""
    if not (np.asarray(obj.truth) >= 0).any():
        return Ceiling(None, 0, False)
    nx, ny = obj.geometry.plane_shape
    if is_full_raster(obj):
        return Ceiling(obj.steps[-1].accuracy_postprocessed, len(obj.steps), True)
    ex = replace(scenario.exploration, policy="raster", budget=nx * ny, stop_mean_entropy=None,
                 stop_max_entropy=None, stop_min_gain=None)
    progress.message(f"attainable accuracy of {obj.name}: one press on each of its {nx * ny} columns")
    full = explore_object(replace(scenario, exploration=ex), entry, memory, make_source, seed, progress, None, layers)
    acc = full.steps[-1].accuracy_postprocessed if full.steps else None
    return Ceiling(acc, len(full.steps), False)


def ceiling_summary(obj: ObjectResult, ceiling: Ceiling | None) -> dict:
    """summary.json's ``attainable_accuracy`` of an object: the ceiling and the presses the run needed to reach
    LEVEL absolute and LEVEL of the ceiling (None where not reached or not known)."""
    acc = [s.accuracy_postprocessed for s in obj.steps]
    out = {"level": LEVEL, "presses_to_level": presses_to(acc, LEVEL)}
    if ceiling is None or ceiling.accuracy is None:
        out.update({"ceiling": None, "presses_to_level_of_ceiling": None, "ceiling_presses": 0,
                    "note": "not measured: needs ground truth, the simulated actuator and "
                            "outputs.attainable_accuracy = true"})
        return out
    out.update({"ceiling": ceiling.accuracy, "presses_to_level_of_ceiling": presses_to(acc, LEVEL * ceiling.accuracy),
                "ceiling_presses": ceiling.presses, "ceiling_is_this_run": ceiling.reused_run})
    return out
