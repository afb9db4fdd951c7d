"""A clairvoyant reference for the exploration benchmarks: how few presses a scene needs when every press's reading
is known in advance.

The worst-scene target (info_gain needs at most 0.7 of raster's presses to 95% of the ceiling) is judged on the
extreme of a tail, and the tail's scenes are those where walls and one-cell features blur under the contact: presses
there read a blend (the *felt* material differs from the truth), and eq. 6.15 spreads that reading to the
neighbours. Whether a scene is hard for the planner or hard for any planner is what this reference tells apart.

The clairvoyant planner is greedy: before each press it tries every unpressed cell with the answer that press will
get (one draw per cell from the memory's predicted posteriors of the cell's felt material, as offline presses are
answered) and takes the one whose post-processed map agrees best with the felt map, i.e. with what pressing
everything would show. It chooses on and is scored on the map a run reports and is scored on
(family_runs.postprocess: the scenario's calibration, wall tempering included). It knows the readings but not the
truth behind a blended reading, so it cannot skip a misleading cell on purpose. Greedy is not optimal (one press
at a time, no lookahead), so it is a reference, not a bound: a scene where it needs more than 0.7 of raster's
presses is one greedy planners find hard. Whether any planner can finish it is benchmarks/clairvoyant_bound.py's
exact answer (on every tail scene measured so far, yes).

Run through benchmarks/exploration_families.py (``--policies ...,clairvoyant``, offline only).
"""

from __future__ import annotations

import copy

import numpy as np
from family_runs import Run, RunTrace, answers_for, felt_cells_cached, postprocess
from scene_families import FamilyScene

from palpate.core.mapping.accuracy import map_accuracy
from palpate.core.mapping.grids import new_map
from palpate.core.world.workspace import ground_truth_map, object_geometry


def cell_readings(fs: FamilyScene, draw_seed: int, *, answers=None, felt=None) -> np.ndarray:
    """(ny, nx, M) one press reading per cell of scene ``fs``, known in advance: a posterior drawn with
    ``draw_seed`` from the memory's predicted answers for the material felt there."""
    felt = felt_cells_cached(fs) if felt is None else felt
    answers = answers_for(fs.references, fs.moduli()) if answers is None else answers
    draw = np.random.default_rng(draw_seed).integers(answers.shape[1], size=np.shape(felt))
    return answers[felt, draw]


def clairvoyant_run(fs: FamilyScene, *, stop_at: float | None = None, answers=None, felt=None) -> Run:
    """The greedy clairvoyant planner on one scene (module docstring): accuracy against the truth after each
    press, stopping once it reaches ``stop_at`` (None: after one press per cell)."""
    sc = fs.scenario("raster")
    entry = sc.objects[0]
    geom = object_geometry(sc, entry)
    truth = ground_truth_map(entry, sc, geom)
    felt = felt_cells_cached(fs) if felt is None else felt
    cal = sc.exploration.calibration
    # one reading per cell, known in advance (the draws differ from offline_run's order, not their distribution)
    reading = cell_readings(fs, fs.seed + 7000, answers=answers, felt=felt)  # (ny, nx, M)
    n = truth.size
    trace = RunTrace(truth)
    grid = new_map(geom)
    post = postprocess(grid, cal)  # the map a run reports and is scored on (wall tempering included)
    for k in range(n + 1):
        got = trace.accuracy(post.probabilities)
        trace.calibration(k, post.probabilities)
        if k == n or (stop_at is not None and got >= stop_at):
            break
        best, best_cell, best_post = -1.0, None, None
        for iy, ix in zip(*np.nonzero(~np.asarray(grid.explored)), strict=True):
            trial = copy.deepcopy(grid)
            trial.update_cell(int(ix), int(iy), cal.evidence(reading[iy, ix]))
            trial_post = postprocess(trial, cal)
            agree = map_accuracy(trial_post.probabilities, felt) or 0.0
            if agree > best:  # first best in row-major order: deterministic
                best, best_cell, best_post = agree, trial, trial_post
        grid, post = best_cell, best_post
    return trace.run()
