"""Exploring one object: the closed loop policy -> actuator -> perception -> map update -> post-processing -> stop.

The loop presses through whatever ``make_source((object,), seed, variability)`` returns: anything with
``press(PressTarget) -> PressRecording`` (the simulated finger, a Dynamixel finger, a human operator, a replay); one
with ``show_map(grid, post)`` is shown the map before each press.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from palpate.core.alignment.merge import perception_of, pipeline_for
from palpate.core.boundary.moduli import MaterialModuli
from palpate.core.boundary.reading import BoundaryReading
from palpate.core.errors import ValidationError
from palpate.core.mapping.accuracy import map_accuracy
from palpate.core.mapping.calibration import SEED_CALIBRATION, MapCalibration
from palpate.core.mapping.geometry import MapGeometry
from palpate.core.mapping.grids import Grid2D, VoxelGrid, new_map
from palpate.core.mapping.snapshot import MapSnapshot
from palpate.core.perception.layered_memory import LayeredMemory
from palpate.core.perception.memory import HapticMemory
from palpate.core.perception.press import PressResult, perceive_press
from palpate.core.planning.policies import Target
from palpate.core.planning.registry import PolicyContext, build_policy, stop_reason
from palpate.core.session.press_log import PressLog
from palpate.core.session.progress import Progress
from palpate.core.session.sources import PressTarget
from palpate.core.world.scenario import ObjectEntry, Scenario
from palpate.core.world.workspace import clear_of_walls, contact_radius, ground_truth_map, object_geometry


@dataclass(frozen=True)
class PressStep:
    """One press of an exploration and the map right after it.

    Attributes:
        k: 1-based press number.
        cell: (ix, iy), 0-based, of the planned column.
        target: planned (x, y), m; planned_depth: m.
        score: the policy's score for the target (None for list-driven policies).
        result: what the press was perceived as.
        posterior: the memory's posterior for the press (the deepest layer's on a voxel map), or None; the map
            fused it tempered by the scenario's map calibration.
        mean_entropy, mean_entropy_postprocessed: of the map after the press (map's entropy base).
        accuracy_explored: of the explored cells before post-processing (None without truth).
        accuracy_postprocessed: of all cells after post-processing (None without truth).
        boundary: the press's boundary reading (world frame), when the exploration was given a reader.
    """

    k: int
    cell: tuple[int, int]
    target: tuple[float, float]
    planned_depth: float
    score: float | None
    result: PressResult
    posterior: np.ndarray | None
    mean_entropy: float
    mean_entropy_postprocessed: float
    accuracy_explored: float | None
    accuracy_postprocessed: float | None
    boundary: BoundaryReading | None = None


@dataclass(frozen=True)
class ObjectResult:
    """Everything an exploration of one object produced.

    Attributes:
        name: the object's name; geometry: its map's geometry.
        policy, stop_reason: which policy explored and why it stopped.
        steps: every press, in order.
        regions: the scenario's predefined cells, 0-based (ix, iy).
        cycle_posteriors: predefined policy: each region's distribution after each cycle (seed 000 Tables 6.9-6.11).
        snapshots: the map at k = 0, mid-way, at the end, and post-processed.
        grid, post: the measured and the post-processed map.
        truth: the true reference-material index per cell (-1 = none).
        true_materials: the reference materials the object is made of.
        clear_of_walls: 2-D maps, per cell: no second material within a press's contact radius at exploration
            depth (:func:`~palpate.core.world.workspace.clear_of_walls`); None for voxel maps.
    """

    name: str
    geometry: MapGeometry
    policy: str
    stop_reason: str
    steps: tuple[PressStep, ...]
    regions: tuple[tuple[int, int], ...]
    cycle_posteriors: tuple[tuple[tuple[float, ...], ...], ...]
    snapshots: tuple[MapSnapshot, ...]
    grid: Grid2D | VoxelGrid
    post: Grid2D | VoxelGrid
    truth: np.ndarray
    true_materials: tuple[str, ...]
    clear_of_walls: np.ndarray | None = None

    @property
    def results(self) -> list[PressResult]:
        """The perceived presses, in order."""
        return [s.result for s in self.steps]


@dataclass(frozen=True)
class MapPostprocessing:
    """How a run post-processes its maps besides the calibration (recordings carry it, so replay rebuilds the same
    maps): eq. 6.15 ``passes`` on 2-D maps (None = until every cell is filled) and, on voxel maps, whether layers
    are also filled laterally."""

    passes: int | None = 1
    voxel_lateral: bool = False

    @classmethod
    def of(cls, ex) -> MapPostprocessing:
        return cls(ex.extrapolation_passes, ex.voxel_lateral)

    def to_dict(self) -> dict:
        return {"extrapolation_passes": "all" if self.passes is None else self.passes,
                "voxel_lateral": self.voxel_lateral}

    @classmethod
    def from_dict(cls, doc, source: str) -> MapPostprocessing:
        """Read :meth:`to_dict`'s document (missing keys: the seeds' one pass, no lateral filling); anything else
        wrong is a ValidationError naming ``source`` and the key."""
        if not isinstance(doc, dict):
            raise ValidationError(f"{source}: expected an object, got {type(doc).__name__}")
        unknown = sorted(set(doc) - {"extrapolation_passes", "voxel_lateral"})
        if unknown:
            raise ValidationError(f"{source}: unknown key(s) {unknown}")
        passes = doc.get("extrapolation_passes", 1)
        if passes != "all" and (isinstance(passes, bool) or not isinstance(passes, int) or passes < 1):
            raise ValidationError(f"{source}: extrapolation_passes must be an integer >= 1 or \"all\", got "
                                  f"{passes!r}")
        lateral = doc.get("voxel_lateral", False)
        if not isinstance(lateral, bool):
            raise ValidationError(f"{source}: voxel_lateral must be true or false, got {lateral!r}")
        return cls(None if passes == "all" else passes, lateral)

    def apply(self, grid, calibration: MapCalibration, walls: bool = True):
        """The post-processed copy of ``grid`` (2-D or voxel) with these settings and ``calibration``'s
        extrapolation certainty and, on 2-D maps with ``walls``, its wall reliability."""
        c = calibration.extrapolation_certainty
        if isinstance(grid, VoxelGrid):
            return grid.postprocessed(lateral=self.voxel_lateral, certainty=c)
        wall = calibration.wall_reliability if walls else 1.0
        return grid.postprocessed(passes=self.passes, certainty=c, wall_reliability=wall)

    def planned_on(self, grid, calibration: MapCalibration, post):
        """The map the policies plan on and the stop rules read: ``post`` (:meth:`apply`'s) without the wall
        tempering. A tempered wall cell stays unsure however often it is pressed, so planning on it sends the
        policies back to walls (measured in docs/results.md, "Maps beside walls"); the tempering says how far
        the reported map can be trusted, not where to press."""
        if calibration.wall_reliability == 1.0 or isinstance(grid, VoxelGrid):
            return post
        return self.apply(grid, calibration, walls=False)


def apply_press(grid: Grid2D | VoxelGrid, res: PressResult, memory: HapticMemory,
                layers: LayeredMemory | None, fallback_xy: tuple[float, float],
                calibration: MapCalibration = SEED_CALIBRATION) -> np.ndarray | None:
    """Update a map with one perceived press (seed 001 eq. 2), in place, and return the memory's posterior for it.

    The map fuses that posterior tempered by ``calibration`` (:func:`palpate.core.mapping.calibration.press_evidence`;
    the default, the seeds' setting, fuses it as it is).

    2-D: the press's posterior updates the cell under the measured press location (the planned cell if the
    finger slipped off the grid). Voxels: every layer the press reached gets the posterior of ``layers`` for a fit
    to the press samples down to that layer (deeper layers see more of the press, as seed 001 observes); the
    deepest layer's posterior is returned. A press with no fit changes nothing and returns None. A classifier
    memory (:class:`~palpate.core.perception.classifier_memory.ClassifierMemory`) judges the features its extractor
    takes from the press (2-D maps only); a press it gives no features changes nothing either.
    """
    if res.fit is None:
        return None
    if isinstance(grid, VoxelGrid):
        if layers is None:
            raise ValidationError("a voxel map needs a layered memory (LayeredMemory.whole_press(memory, ...) judges "
                                  "every layer with the whole-press memory)")
        pr = res.press
        posts = layers.layer_posteriors(pr.t, pr.c_P, pr.c_A, pr.c_D)
        try:
            ix, iy = grid.column_of(*res.location)
        except ValidationError:
            ix, iy = grid.column_of(*fallback_xy)
        for iz, p in enumerate(posts):
            if p is not None:
                grid.update_voxel(ix, iy, iz, calibration.evidence(p))
        done = [p for p in posts if p is not None]
        return done[-1] if done else None
    features_of = getattr(memory, "press_features", None)  # a classifier memory: its own feature extractor
    if features_of is None:
        p = memory.predict_proba(res.fit.params[None, :], features=res.fit.features)[0]
    elif (x := features_of(res)) is None:
        return None
    else:
        p = memory.predict_proba(x[None, :])[0]
    try:
        grid.update(*res.location, calibration.evidence(p))
    except ValidationError:
        grid.update(*fallback_xy, calibration.evidence(p))
    return p


def _region_row(grid, cell: tuple[int, int]) -> tuple[float, ...]:
    ix, iy = cell
    if isinstance(grid, VoxelGrid):
        col = grid.probabilities[ix, iy]
        expl = grid.explored[ix, iy]
        p = col[expl][-1] if expl.any() else col[0]
    else:
        p = grid.probabilities[iy, ix]
    return tuple(round(float(v), 4) for v in p)


def _press_point(target: Target, cells_xy: np.ndarray, geometry: MapGeometry, policy: str,
                 name: str) -> tuple[float, float]:
    """Where a target is pressed, m: its own (x, y) when it names one (it must lie in its cell), else the cell's
    centre."""
    ix, iy = int(target.ix), int(target.iy)
    if target.xy is None:
        return float(cells_xy[iy, ix, 0]), float(cells_xy[iy, ix, 1])
    x, y = (float(v) for v in target.xy)
    half = geometry.cell_size / 2 * (1 + 1e-9)
    if not (np.isfinite(x) and np.isfinite(y) and abs(x - cells_xy[iy, ix, 0]) <= half
            and abs(y - cells_xy[iy, ix, 1]) <= half):
        raise ValidationError(f"exploration policy {policy!r} chose the point ({x * 1e3:.2f}, {y * 1e3:.2f}) mm, "
                              f"outside its cell {ix + 1},{iy + 1} (1-based) of {name!r}")
    return x, y


def explore_object(scenario: Scenario, entry: ObjectEntry, memory: HapticMemory, make_source, seed: int,
                   progress: Progress, log: PressLog | None = None,
                   layers: LayeredMemory | None = None, boundary_reader=None,
                   moduli: MaterialModuli | None = None) -> ObjectResult:
    """Explore one object with the scenario's policy.

    Per press: policy (next target from the map) -> actuator -> perception -> map update -> post-processing ->
    stop rules (press budget, no expected gain above ``stop_min_gain``, mean or max entropy of the post-processed
    map under ``stop_mean_entropy`` / ``stop_max_entropy``). The policy and the stop rules read the map
    post-processed without the calibration's wall tempering (:meth:`MapPostprocessing.planned_on`); the result
    holds, and its steps score, the tempered one.

    Args:
        scenario, entry: the scenario and the object to explore.
        memory: the whole-press haptic memory (judges 2-D presses; info_gain predicts outcomes from it).
        make_source: ``make(objects, seed, variability)`` returning the actuator.
        seed: seed of the policy and the source.
        progress: progress display.
        log: when given, every press is laid on the run's timeline (and recorded).
        layers: voxel maps: the per-layer judges (default: every layer judged by ``memory``).
        boundary_reader: ``read(recording, result)`` returning the press's boundary reading or None (e.g.
            :func:`palpate.core.boundary.press.read_press` with templates and a noise model bound); each step holds
            it. The cell map itself does not use it; a policy with an ``observe(location, reading)`` method is
            told each press's measured (x, y), m, and reading (None when there is none).
        moduli: the reference materials' moduli as the readings read them (from the training presses), for a
            policy that plans on the fine map (:class:`~palpate.core.planning.registry.PolicyContext`).
    """
    ex = scenario.exploration
    geometry = object_geometry(scenario, entry)
    grid = new_map(geometry)
    voxel = geometry.voxel
    if voxel and layers is None:
        layers = LayeredMemory.whole_press(memory, geometry.cell_size, geometry.shape[2])
    cells_xy = geometry.cell_centres()  # (ny, nx, 2)
    truth = ground_truth_map(entry, scenario, geometry)

    regions0 = tuple((c - 1, r - 1) for c, r in entry.regions)
    budget = len(regions0) * ex.presses_per_region if ex.policy == "predefined" else ex.budget
    context = PolicyContext(ex.policy, geometry, seed, memory, regions0, budget, ex.depth, moduli)
    policy, _ = build_policy(context, cells=list(regions0), repeats=ex.presses_per_region, seed=seed, memory=memory,
                             travel_cost_per_mm=ex.travel_cost_per_mm, max_depth=ex.depth if voxel else None,
                             passes=ex.extrapolation_passes, objective=ex.objective, feature_size=ex.feature_size,
                             certainty=ex.calibration.extrapolation_certainty, lateral=ex.voxel_lateral,
                             geometry=geometry, moduli=moduli)
    observe = getattr(policy, "observe", None)
    # The one post-processing the policies plan on, the run reports and the map files hold.
    post_settings = MapPostprocessing.of(ex)

    def postprocess():
        return post_settings.apply(grid, ex.calibration)

    def planned_on(post):
        return post_settings.planned_on(grid, ex.calibration, post)
    source = make_source((entry.spec,), seed, ex.variability)
    if not callable(getattr(source, "press", None)):
        raise ValidationError(f"exploring {entry.spec.name}: the source/actuator {type(source).__name__} has no "
                              "press(target) method")
    show_map = getattr(source, "show_map", None)

    snapshots = [MapSnapshot.of(grid, "k = 0")]
    steps: list[PressStep] = []
    cycles = []
    post = postprocess()
    plan = planned_on(post)
    last, stop = None, "budget"
    progress.start(f"exploring {entry.spec.name}", budget)
    for k in range(budget):
        target = policy.next_target(grid, plan, last)
        if target is None:
            stop = "policy_exhausted"
            break
        if ex.stop_min_gain is not None and target.score is not None and target.score < ex.stop_min_gain:
            stop = "min_gain"
            break
        cell = (int(target.ix), int(target.iy))
        if not (0 <= cell[0] < cells_xy.shape[1] and 0 <= cell[1] < cells_xy.shape[0]):
            raise ValidationError(f"exploration policy {ex.policy!r} chose cell {cell} (0-based ix, iy) outside the "
                                  f"{cells_xy.shape[1]} x {cells_xy.shape[0]} map of {entry.spec.name!r}")
        depth = ex.depth if target.depth is None else target.depth
        x, y = _press_point(target, cells_xy, geometry, ex.policy, entry.spec.name)
        if callable(show_map):
            show_map(grid, post)
        try:
            rec = source.press(PressTarget(x, y, depth=depth, force=ex.max_force, speed=ex.speed,
                                           label=f"{entry.spec.name} cell {cell[0] + 1},{cell[1] + 1}"))
        except ValidationError as exc:  # e.g. a map reaching past its object: name the scenario, object and cell
            raise ValidationError(f"{scenario.path or 'scenario'}: object {entry.spec.name!r}, cell "
                                  f"[{cell[0] + 1}, {cell[1] + 1}] at ({x * 1e3:.1f}, {y * 1e3:.1f}) mm: {exc} "
                                  "(check the object's size_mm, grid_origin_mm, grid_cells and exploration.cell_mm)"
                                  ) from None
        # a press from a session file says how it is perceived; the recording keeps that for replay
        perception = perception_of(rec.meta)
        if log is not None:
            info = {"phase": "exploration", "object": entry.spec.name, "k": k + 1, "cell": [cell[0] + 1, cell[1] + 1],
                    "target_m": [x, y]}
            rec = log.add(rec, {**info, "perception": perception} if perception else info)
        res = perceive_press(rec, pipeline_for(perception) if perception else None).at_target((x, y))
        boundary = boundary_reader(rec, res) if boundary_reader is not None else None
        posterior = apply_press(grid, res, memory, layers, fallback_xy=(x, y), calibration=ex.calibration)
        if callable(observe):
            observe(res.location, boundary)
        post = postprocess()
        plan = planned_on(post)
        if log is not None:
            log.show_map(entry.spec.name, grid, geometry, entry.spec.height, scene=(entry.spec,) if k == 0 else ())
        last = cell
        steps.append(PressStep(k + 1, cell, (x, y), depth, target.score, res, posterior, float(grid.mean_entropy()),
                               float(post.mean_entropy()), map_accuracy(grid.probabilities, truth, grid.explored),
                               map_accuracy(post.probabilities, truth), boundary))
        if ex.policy == "predefined" and (k + 1) % len(regions0) == 0:
            cycles.append(tuple(_region_row(grid, c) for c in regions0))
        if (k + 1) == budget // 2:
            snapshots.append(MapSnapshot.of(grid, f"k = {k + 1}"))
        progress.update(k + 1)
        reason = stop_reason(plan, mean_entropy=ex.stop_mean_entropy, max_entropy=ex.stop_max_entropy)
        if reason is not None:
            stop = reason
            break
    snapshots.append(MapSnapshot.of(grid, f"k = {len(steps)}"))
    snapshots.append(MapSnapshot.of(post, "post-processed"))
    return ObjectResult(
        name=entry.spec.name, geometry=geometry, policy=ex.policy, stop_reason=stop, steps=tuple(steps),
        regions=regions0, cycle_posteriors=tuple(cycles), snapshots=tuple(snapshots), grid=grid, post=post,
        truth=truth, true_materials=tuple(sorted({scenario.materials[m.name].like for m in entry.spec.materials()})),
        clear_of_walls=clear_of_walls(entry, scenario, geometry, contact_radius(scenario)))
