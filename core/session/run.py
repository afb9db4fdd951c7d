"""The run loop: train a haptic memory, explore each object, keep its map, and write every output.

The loop only talks to a *source* (``palpate.core.session.sources``): it asks for a press at a target and gets raw taxel
and pose streams back. The simulation, a replayed recording or a robot finger are interchangeable, so what this
module computes on a simulation is what it computes on hardware.

Stages (each timed in ``summary["timing"]``):

1. training: press each reference material ``presses_per_material`` times, segment, fit the 3/2-power laws, fit
   the haptic memory, leave-one-out cross-validation (skipped when the scenario names a trained memory);
2. exploration, per object: a policy picks cells, each press's fit gives a posterior over the reference materials
   that updates the map (seed 001 eq. 2); entropy and accuracy against ground truth are kept after every press;
3. post-processing: entropy-weighted extrapolation (2-D: eq. 6.15; voxels: vertical extrapolation then
   continuity verification);
4. outputs: summary.json, maps (NPZ + JSON), memory.json, figures, a haptic-material export per object.
"""

from __future__ import annotations

import json
import platform
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from palpate.core import __version__
from palpate.core.errors import FitError, PalpateError, ValidationError
from palpate.core.planning.policies import make_policy
from palpate.core.session.progress import Progress
from palpate.core.session.sources import PressTarget, load_source
from palpate.core.world.scenario import ObjectEntry, Scenario
from palpate.core.world.scene import ObjectSpec, Scene, material_index_at

SUMMARY_FORMAT = "palpate-run-summary"
SUMMARY_VERSION = 1
TRAINING_BLOCK = (0.08, 0.08, 0.04)  # m: a thick sample of each reference material, as in seed 000 Fig. 6.7


@dataclass
class PressResult:
    """One press's perception: where it was, its features (press phase) and fit, and its posterior."""

    target: tuple[float, float]
    location: tuple[float, float]
    depth: float
    t: np.ndarray
    c_P: np.ndarray
    c_A: np.ndarray
    c_D: np.ndarray
    params: np.ndarray | None
    fit: dict | None
    posterior: np.ndarray | None = None
    rejected: list[str] = field(default_factory=list)
    truth_force: np.ndarray | None = None
    truth_indentation: np.ndarray | None = None


def fit_summary(fit) -> dict:
    """The per-press fit as reported in summaries: n1, n2, phi_n, a1, a2, phi_a (c_D in mm, c_A in mm^2)."""
    return {k: float(getattr(fit, k)) for k in ("n1", "n2", "phi_n", "a1", "a2", "phi_a")}


def perceive_press(recording, pipeline_config=None) -> PressResult:
    """Turn one press's raw streams into features and a 3/2-power fit (no memory involved).

    Returns a PressResult whose ``params`` is None (with reasons in ``rejected``) when no usable press was found.
    """
    from palpate.core.perception.fit import fit_press
    from palpate.core.perception.pipeline import PipelineConfig, presses_from_recording

    cfg = pipeline_config or PipelineConfig()
    seg = presses_from_recording(recording, cfg)
    meta = recording.meta or {}
    # The planned target, when the source says it (SimSource does); callers that know it overwrite it anyway.
    planned = meta.get("target") if isinstance(meta.get("target"), dict) else {}
    target = (float(planned.get("x", np.nan)), float(planned.get("y", np.nan)))
    reasons = [f"{r.reason}" for r in seg.rejected]
    truth = recording.truth
    tf = None if truth is None else np.asarray(truth.force)
    ti = None if truth is None else np.asarray(truth.indentation)
    if not seg.presses:
        return PressResult(target, target, 0.0, np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(0), None, None,
                           rejected=reasons or ["no press found in the streams"], truth_force=tf, truth_indentation=ti)
    # One press was asked for; if noise split it, the deepest part is the press.
    press = max(seg.presses, key=lambda p: p.depth)
    if len(seg.presses) > 1:
        reasons.append(f"{len(seg.presses)} presses found where one was made; kept the deepest")
    try:
        fit = fit_press(press)
        params = np.asarray(fit.params, dtype=float)
        fit_dict = fit_summary(fit)
    except FitError as exc:
        params, fit_dict = None, None
        reasons.append(f"fit failed: {exc}")
    return PressResult(target, (float(press.location[0]), float(press.location[1])), float(press.depth),
                       np.asarray(press.t), np.asarray(press.c_P), np.asarray(press.c_A), np.asarray(press.c_D),
                       params, fit_dict, rejected=reasons, truth_force=tf, truth_indentation=ti)


class PressLog:
    """Lays every press on one timeline (so a run is one continuous stream) and optionally records it to MCAP.

    The run perceives the *shifted* streams, exactly what the recording holds, so ``palpate replay`` of the
    recording reproduces the run's maps bit for bit.
    """

    GAP = 1.0  # s of silence between presses

    def __init__(self, path: Path | None = None, metadata: dict | None = None):
        self.clock = 0.0
        self.writer = None
        if path is not None:
            from palpate.core.io.recording import RecordingWriter

            self.writer = RecordingWriter(path, metadata or {})

    def add(self, rec, info: dict):
        """Shift ``rec`` to start at the current clock, record it with a ``press`` annotation, return it."""
        shifted = shift_recording(rec, self.clock - _start_time(rec))
        t_end = max(shifted.frames[-1].t if shifted.frames else self.clock,
                    shifted.poses[-1].t if shifted.poses else self.clock)
        if self.writer is not None:
            self.writer.write_annotation(self.clock, "press", {**info, "t_start": self.clock, "t_end": t_end})
            for f in shifted.frames:
                self.writer.write_taxel(f)
            for p in shifted.poses:
                self.writer.write_pose(p)
            if shifted.truth is not None:
                for t, f, d in zip(shifted.truth.t, shifted.truth.force, shifted.truth.indentation, strict=True):
                    self.writer.write_truth(float(t), float(f), float(d), shifted.truth.material)
        self.clock = float(np.ceil(t_end + self.GAP))
        return shifted

    def close(self) -> None:
        if self.writer is not None:
            self.writer.close()


def _start_time(rec) -> float:
    times = [rec.frames[0].t] if rec.frames else []
    times += [rec.poses[0].t] if rec.poses else []
    return min(times) if times else 0.0


def shift_recording(rec, dt: float):
    """A copy of a PressRecording with every timestamp moved by ``dt`` seconds."""
    from dataclasses import replace

    from palpate.core.perception.streams import GroundTruth, PressRecording

    if dt == 0.0:
        return rec
    frames = [replace(f, t=f.t + dt) for f in rec.frames]
    poses = [replace(p, t=p.t + dt) for p in rec.poses]
    truth = None
    if rec.truth is not None:
        truth = GroundTruth(np.asarray(rec.truth.t) + dt, rec.truth.force, rec.truth.indentation, rec.truth.material)
    return PressRecording(frames, poses, truth, dict(rec.meta))


def apply_press(grid, res: PressResult, memory, *, voxel: bool, fallback_xy: tuple[float, float]) -> None:
    """Update a map with one perceived press (seed 001 eq. 2), in place; sets ``res.posterior``.

    2-D: the press's posterior updates the cell under the measured press location (the planned cell if the
    finger slipped off the grid). Voxels: every layer the press reached gets the posterior of a fit to the press
    samples down to that layer (deeper layers see more of the press, as seed 001 observes).
    """
    if res.params is None:
        return
    if voxel:
        if hasattr(memory, "layer_posteriors"):
            posts = memory.layer_posteriors(res.t, res.c_P, res.c_A, res.c_D)
        else:  # a whole-press memory only: judge every cut of the press by it
            from palpate.core.perception.layered_memory import layer_fits

            posts = [None if f is None else memory.predict_proba(f[None, :])[0]
                     for f in layer_fits(res.t, res.c_P, res.c_A, res.c_D, grid.cell_size, grid.shape[2])]
        try:
            ix, iy = grid.column_of(*res.location)
        except ValidationError:
            ix, iy = grid.column_of(*fallback_xy)
        for iz, p in enumerate(posts):
            if p is not None:
                grid.update_voxel(ix, iy, iz, p)
        done = [p for p in posts if p is not None]
        res.posterior = done[-1] if done else None
        return
    p = memory.predict_proba(res.params[None, :])[0]
    try:
        grid.update(*res.location, p)
    except ValidationError:
        grid.update(*fallback_xy, p)
    res.posterior = p


def _source_factory(scenario: Scenario, name: str = "sim"):
    factory = load_source(name)

    def make(objects: tuple[ObjectSpec, ...], seed: int, variability: str):
        scene = Scene(objects, scenario.fingertip, scenario.taxels, scenario.pose)
        return factory(scene, fidelity=scenario.fidelity, seed=seed, variability=variability)

    return make


def train_memory(scenario: Scenario, make_source, seeds, progress: Progress, log: PressLog | None = None):
    """Press every reference material and fit the haptic memory; returns (memory, crossval, presses by material)."""
    from palpate.core.perception.memory import HapticMemory, leave_one_out

    tr = scenario.training
    params, labels, by_material = [], [], {}
    for m, name in enumerate(scenario.references):
        mat = scenario.materials[name].material
        block = ObjectSpec(f"sample_{name}", "box", TRAINING_BLOCK, (0.0, 0.0), mat)
        source = make_source((block,), int(seeds[m]), tr.variability)
        results = []
        progress.start(f"training {name}", tr.presses_per_material)
        for k in range(tr.presses_per_material):
            rec = source.press(PressTarget(0.0, 0.0, depth=tr.depth, force=tr.max_force, speed=tr.speed,
                                           label=f"{name}#{k + 1}"))
            if log is not None:
                rec = log.add(rec, {"phase": "training", "material": name, "k": k + 1})
            res = perceive_press(rec)
            results.append(res)
            if res.params is not None:
                params.append(res.params)
                labels.append(name)
            progress.update(k + 1)
        by_material[name] = results
        usable = sum(r.params is not None for r in results)
        if usable < 3:
            raise PalpateError(f"training: only {usable} of {tr.presses_per_material} presses on {name} could be "
                               "fitted; press deeper (training.depth_mm) or lower the taxel threshold")
    P = np.vstack(params)
    memory = HapticMemory(materials=list(scenario.references)).fit(P, labels)
    crossval = leave_one_out(P, labels, materials=list(scenario.references))
    return memory, crossval, by_material


def _grid_geometry(entry: ObjectEntry, cell: float) -> tuple[tuple[float, float], tuple[int, int]]:
    spec = entry.spec
    if entry.grid_origin is not None:
        origin = entry.grid_origin
    else:
        half = np.array(spec.size[:2] if spec.shape != "cylinder" else (2 * spec.size[0],) * 2) / 2.0
        origin = (spec.position[0] - half[0], spec.position[1] - half[1])
    if entry.grid_shape is not None:
        shape = entry.grid_shape
    else:
        extent = spec.size[:2] if spec.shape != "cylinder" else (2 * spec.size[0],) * 2
        shape = (max(1, int(round(extent[0] / cell))), max(1, int(round(extent[1] / cell))))
    return (float(origin[0]), float(origin[1])), (int(shape[0]), int(shape[1]))


def ground_truth_cells(entry: ObjectEntry, scenario: Scenario, centres_xy: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Reference-material index (or -1) at each point: the object's material mapped through ``like``."""
    spec = entry.spec
    names = [m.name for m in spec.materials()]
    idx = material_index_at(spec, np.column_stack([centres_xy, z]), names)
    refs = scenario.references
    like = scenario.truth_names()
    lut = np.array([refs.index(like[n]) if n in like else -1 for n in names] + [-1])
    return lut[idx]


def ground_truth_map(entry: ObjectEntry, scenario: Scenario, geom: dict) -> np.ndarray:
    """Reference-material index (or -1) of every cell of an object's map (``geom`` from :func:`map_geometry`):
    (ny, nx) for a 2-D map, the material half-way down the planned press (what a press there mostly feels);
    (nx, ny, nz) like the voxel grid, at each voxel's centre."""
    origin, cell = tuple(geom["origin_m"]), geom["cell_size_m"]
    nx, ny = geom["shape"][:2]
    top = entry.spec.height
    flat = _cell_centres(origin, cell, nx, ny).reshape(-1, 2)
    if geom["map"] != "voxel":
        return ground_truth_cells(entry, scenario, flat,
                                  np.full(nx * ny, top - scenario.exploration.depth / 2)).reshape(ny, nx)
    nz = geom["shape"][2]
    zc = top - (np.arange(nz) + 0.5) * cell
    pts = np.concatenate([np.column_stack([flat, np.full(nx * ny, z)]) for z in zc])
    truth = ground_truth_cells(entry, scenario, pts[:, :2], pts[:, 2]).reshape(nz, ny, nx)
    return np.transpose(truth, (2, 1, 0))


def explore_object(scenario: Scenario, entry: ObjectEntry, memory, make_source, seed: int, progress: Progress,
                   log: PressLog | None = None):
    """Explore one object with the scenario's policy; returns (object summary dict, map snapshots, results).

    The closed loop, per press: policy (next target from the map) -> actuator (``make_source(...)`` returns
    anything with ``press(PressTarget) -> PressRecording``: the simulated finger, a Dynamixel finger, a human
    operator; one with ``show_map(grid, post)`` is shown the map first) -> perception -> map update ->
    post-processing -> stop rules (press budget, no expected gain above ``stop_min_gain``, mean or max entropy of
    the post-processed map under ``stop_mean_entropy`` / ``stop_max_entropy``).
    """
    from palpate.core.planning.policies import stop_reason

    ex = scenario.exploration
    geom = map_geometry(scenario)[entry.spec.name]
    grid = build_map(geom)
    origin, cell = tuple(geom["origin_m"]), geom["cell_size_m"]
    nx, ny = geom["shape"][:2]
    voxel = ex.map == "voxel"
    cells_xy = _cell_centres(origin, cell, nx, ny)  # (ny, nx, 2)
    truth = ground_truth_map(entry, scenario, geom)

    regions0 = [(c - 1, r - 1) for c, r in entry.regions]
    if ex.policy == "predefined":
        budget = len(regions0) * ex.presses_per_region
    else:
        budget = ex.budget
    policy = make_policy(ex.policy, cells=regions0, repeats=ex.presses_per_region, seed=seed, memory=memory,
                         travel_cost_per_mm=ex.travel_cost_per_mm, max_depth=ex.depth if voxel else None,
                         passes=ex.extrapolation_passes, objective=ex.objective, feature_size=ex.feature_size)
    # The one post-processing the policies plan on, the run reports and the map files hold.
    postprocess = grid.postprocessed if voxel else (lambda: grid.postprocessed(passes=ex.extrapolation_passes))
    # Any actuator will do: the simulated finger, a Dynamixel finger, a human operator, a replay.
    source = make_source((entry.spec,), seed, ex.variability)
    if not callable(getattr(source, "press", None)):
        raise ValidationError(f"exploring {entry.spec.name}: the source/actuator {type(source).__name__} has no "
                              "press(target) method")
    show_map = getattr(source, "show_map", None)

    def snapshot(label: str) -> dict:
        probs = grid.probabilities
        return {"label": label, "probabilities": np.array(probs), "explored": np.array(grid.explored)}

    snapshots = [snapshot("k = 0")]
    per_press, results = [], []
    cycle_posteriors = []
    post = postprocess()
    last, stop = None, "budget"
    progress.start(f"exploring {entry.spec.name}", budget)
    for k in range(budget):
        target = policy.next_target(grid, post, last)
        if target is None:
            stop = "policy_exhausted"
            break
        if ex.stop_min_gain is not None and target.score is not None and target.score < ex.stop_min_gain:
            stop = "min_gain"
            break
        cell = (target.ix, target.iy)
        depth = ex.depth if target.depth is None else target.depth
        x, y = (float(v) for v in cells_xy[cell[1], cell[0]])
        if callable(show_map):
            show_map(grid, post)
        rec = source.press(PressTarget(x, y, depth=depth, force=ex.max_force, speed=ex.speed,
                                       label=f"{entry.spec.name} cell {cell[0] + 1},{cell[1] + 1}"))
        if log is not None:
            rec = log.add(rec, {"phase": "exploration", "object": entry.spec.name, "k": k + 1,
                                "cell": [cell[0] + 1, cell[1] + 1], "target_m": [x, y]})
        res = perceive_press(rec)
        res.target = (x, y)
        row = {"k": k + 1, "cell": [cell[0] + 1, cell[1] + 1], "target_m": [x, y], "planned_depth_m": depth,
               "score": target.score, "location_m": list(res.location), "depth_m": res.depth, "fit": res.fit,
               "rejected": res.rejected}
        apply_press(grid, res, memory, voxel=voxel, fallback_xy=(x, y))
        post = postprocess()
        last = cell
        row["posterior"] = None if res.posterior is None else [float(v) for v in res.posterior]
        row["mean_entropy"] = float(grid.mean_entropy())
        row["mean_entropy_postprocessed"] = float(post.mean_entropy())
        row["accuracy_explored"] = map_accuracy(grid, truth, explored_only=True)
        row["accuracy_all_cells_postprocessed"] = map_accuracy(post, truth, explored_only=False)
        per_press.append(row)
        results.append(res)
        if ex.policy == "predefined" and (k + 1) % len(regions0) == 0:
            cycle_posteriors.append(_region_table(grid, regions0, voxel))
        if (k + 1) == budget // 2:
            snapshots.append(snapshot(f"k = {k + 1}"))
        progress.update(k + 1)
        reason = stop_reason(post, mean_entropy=ex.stop_mean_entropy, max_entropy=ex.stop_max_entropy)
        if reason is not None:
            stop = reason
            break
    snapshots.append(snapshot(f"k = {len(per_press)}"))
    acc_before = map_accuracy(grid, truth, explored_only=False)
    acc_after = map_accuracy(post, truth, explored_only=False)
    snapshots.append({"label": "post-processed", "probabilities": np.array(post.probabilities),
                      "explored": np.array(post.explored)})
    summary = {
        "name": entry.spec.name,
        "map": ex.map,
        "grid": {"origin_m": list(origin), "cell_size_m": ex.cell_size, "shape": list(grid.probabilities.shape[:-1])},
        "presses": len(per_press),
        "policy": ex.policy,
        "stop_reason": stop,
        "per_press": per_press,
        "regions": [[c + 1, r + 1] for c, r in regions0],
        "posterior_per_cycle": cycle_posteriors,
        "accuracy": {"explored_before_postprocessing": map_accuracy(grid, truth, explored_only=True),
                     "all_cells_before_postprocessing": acc_before,
                     "all_cells_after_postprocessing": acc_after},
        "mean_entropy_after_each_press": [r["mean_entropy"] for r in per_press],
        "mean_entropy_after_postprocessing": float(post.mean_entropy()),
        "true_materials": sorted({scenario.materials[m.name].like for m in entry.spec.materials()}),
    }
    return summary, snapshots, results, grid, post, truth


def save_layer_memories(layered, path: Path) -> None:
    """Write the per-voxel-layer memories (JSON list, null for untrained layers) beside memory.json."""
    doc = {"format": "palpate.layered_memory", "version": 1, "cell_size_m": layered.cell,
           "layers": [m if m is None or isinstance(m, str) else m.to_dict() for m in layered.layers]}
    path.write_text(json.dumps(doc))


def load_layer_memories(full, path: Path):
    """Read :func:`save_layer_memories`' file back into a LayeredMemory around ``full``."""
    from palpate.core.perception.layered_memory import LayeredMemory
    from palpate.core.perception.memory import HapticMemory

    try:
        doc = json.loads(Path(path).read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise ValidationError(f"{path}: cannot read layered memory: {exc}") from None
    if not isinstance(doc, dict) or doc.get("format") != "palpate.layered_memory" or doc.get("version") != 1:
        raise ValidationError(f"{path}: key 'format' must be 'palpate.layered_memory' version 1")
    try:
        layers = [d if d is None or isinstance(d, str) else HapticMemory.from_dict(d, source=f"{path}: layers[{i}]")
                  for i, d in enumerate(doc["layers"])]
        cell = float(doc["cell_size_m"])
    except (KeyError, TypeError, ValueError) as exc:
        raise ValidationError(f"{path}: missing or malformed key {exc}") from None
    return LayeredMemory(full, layers, cell)


def _cell_centres(origin, cell, nx, ny) -> np.ndarray:
    xs = origin[0] + (np.arange(nx) + 0.5) * cell
    ys = origin[1] + (np.arange(ny) + 0.5) * cell
    gx, gy = np.meshgrid(xs, ys)
    return np.stack([gx, gy], axis=-1)


def map_accuracy(grid, truth: np.ndarray, explored_only: bool) -> float | None:
    """Fraction of cells (with a true material) whose MAP is the truth; an undecided cell (a tie, e.g. the
    uniform prior of an unexplored cell) counts as wrong rather than as whichever material comes first."""
    p = np.asarray(grid.probabilities)
    est = grid.map_estimate()
    top2 = np.sort(p, axis=-1)[..., -2:]
    decided = (top2[..., 1] - top2[..., 0]) > 1e-9
    mask = truth >= 0
    if explored_only:
        mask &= grid.explored
    n = int(mask.sum())
    return None if n == 0 else float(np.mean((est[mask] == truth[mask]) & decided[mask]))


def _region_table(grid, regions0, voxel: bool) -> list[list[float]]:
    rows = []
    for ix, iy in regions0:
        if voxel:
            col = grid.probabilities[ix, iy]
            expl = grid.explored[ix, iy]
            p = col[expl][-1] if expl.any() else col[0]
        else:
            p = grid.probabilities[iy, ix]
        rows.append([round(float(v), 4) for v in p])
    return rows


def build_map(geom: dict):
    """An empty Grid2D or VoxelGrid from a geometry entry of :func:`map_geometry`."""
    from palpate.core.mapping.grids import Grid2D, VoxelGrid

    origin = tuple(float(v) for v in geom["origin_m"])
    if geom["map"] == "voxel":
        return VoxelGrid(list(geom["materials"]), tuple(geom["shape"]), origin=origin, z_top=float(geom["z_top_m"]),
                         cell_size=float(geom["cell_size_m"]), base=float(geom["entropy_base"]))
    return Grid2D(list(geom["materials"]), tuple(geom["shape"]), origin=origin, cell_size=float(geom["cell_size_m"]),
                  base=float(geom["entropy_base"]))


def map_geometry(scenario: Scenario) -> dict:
    """Per object, everything needed to rebuild its empty map (written into recordings for replay)."""
    ex = scenario.exploration
    out = {}
    for entry in scenario.objects:
        origin, (nx, ny) = _grid_geometry(entry, ex.cell_size)
        geom = {"map": ex.map, "origin_m": list(origin), "cell_size_m": ex.cell_size, "shape": [nx, ny],
                "entropy_base": ex.entropy_base, "materials": list(scenario.references)}
        if ex.map == "voxel":
            geom["z_top_m"] = entry.spec.height
            geom["shape"].append(max(1, int(round(ex.voxel_depth / ex.cell_size))))
        out[entry.spec.name] = geom
    return out


def run_scenario(scenario: Scenario, out_dir: str | Path, *, progress: Progress | None = None,
                 source: str | None = None, record: str | Path | None = None) -> dict:
    """Run a scenario end to end and write its outputs into ``out_dir``. Returns the summary (also summary.json).

    ``source`` names the registered simulated source that trains the memory and, with ``[actuator] kind = "sim"``,
    explores (default: ``training.source``); another actuator kind explores through
    :func:`palpate.core.session.actuators.open_actuators`. With ``record``, every press's raw streams (and ground truth)
    go to that MCAP file, annotated so that ``palpate replay`` rebuilds the same maps.
    """
    from palpate.core.session.actuators import open_actuators

    progress = progress or Progress(enabled=False)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    timing: dict[str, float] = {}
    seeds = np.random.SeedSequence(scenario.seed).generate_state(4 + len(scenario.references) + len(scenario.objects))
    source = source or scenario.training.source
    kind = scenario.actuator.kind
    geometry = map_geometry(scenario)
    with open_actuators(scenario, out, geometry, lambda: _source_factory(scenario, source)) as makers:
        log = PressLog(Path(record) if record else None,
                       {"scenario": {"name": scenario.name, "file": str(scenario.path) if scenario.path else None,
                                     "seed": scenario.seed, "fidelity": scenario.fidelity},
                        "sources": [source] if kind == "sim" else [source, kind], "maps": geometry})
        try:
            return _run(scenario, out, progress, *makers, seeds, timing, log)
        finally:
            log.close()


def _run(scenario, out, progress, make_source, make_actuator, seeds, timing, log) -> dict:
    t0 = time.perf_counter()
    if scenario.training.memory is not None:
        from palpate.core.perception.memory import HapticMemory

        memory = HapticMemory.load(scenario.training.memory)
        if list(memory.materials) != list(scenario.references):
            raise ValidationError(f"{scenario.training.memory}: memory materials {memory.materials} differ from the "
                                  f"scenario's reference materials {scenario.references}")
        crossval, training = None, {}
    else:
        memory, crossval, training = train_memory(scenario, make_source, seeds[4:], progress, log)
    memory.save(out / "memory.json")
    if scenario.exploration.map == "voxel" and training:
        from palpate.core.perception.layered_memory import train_layered_memory

        nz = max(1, int(round(scenario.exploration.voxel_depth / scenario.exploration.cell_size)))
        memory = train_layered_memory(memory, training, scenario.exploration.cell_size, nz)
        save_layer_memories(memory, out / "memory_layers.json")
    timing["training_s"] = time.perf_counter() - t0

    objects, artefacts = [], {}
    t0 = time.perf_counter()
    for entry in scenario.objects:
        if scenario.actuator.kind == "sim":
            _say_fidelity(entry, scenario, make_source, progress)
    for i, entry in enumerate(scenario.objects):
        seed_i = int(seeds[4 + len(scenario.references) + i])
        summary_i, snaps, results, grid, post, truth = explore_object(scenario, entry, memory, make_actuator,
                                                                      seed_i, progress, log)
        objects.append(summary_i)
        artefacts[entry.spec.name] = (snaps, results, grid, post, truth)
    timing["exploration_s"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    for entry in scenario.objects:
        name = entry.spec.name
        snaps, results, grid, post, truth = artefacts[name]
        (out / "maps").mkdir(exist_ok=True)
        grid.save(out / "maps" / f"{name}.npz")
        post.save(out / "maps" / f"{name}_postprocessed.npz")
        if scenario.outputs.haptic_material and scenario.exploration.map == "grid2d":
            export_haptic_material(post, grid, results, scenario, out / "haptic_materials" / name, name)
    timing["maps_s"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    figures = []
    if scenario.outputs.figures:
        from palpate.core.io import figures as fig

        figures = fig.write_run_figures(out / "figures", scenario, training, artefacts,
                                        render_3d=scenario.outputs.render_3d)
        figures.append(fig.write_progress_figure(out / "figures", objects))
    timing["figures_s"] = time.perf_counter() - t0

    summary = {
        "format": SUMMARY_FORMAT,
        "version": SUMMARY_VERSION,
        "scenario": {"name": scenario.name, "file": str(scenario.path) if scenario.path else None,
                     "fidelity": scenario.fidelity, "description": scenario.description},
        "actuator": scenario.actuator.kind,
        "seed": scenario.seed,
        "materials": list(scenario.references),
        "memory": {"file": "memory.json", "trained": scenario.training.memory is None},
        "crossval": None if crossval is None else {
            "confusion": np.asarray(crossval.confusion).tolist(),
            "mean_posterior": np.asarray(crossval.mean_posterior).tolist(),
            "accuracy": {m: float(np.asarray(crossval.confusion)[i, i]) for i, m in enumerate(scenario.references)},
        },
        "training": {name: [r.fit for r in rs] for name, rs in training.items()},
        "objects": objects,
        "figures": [str(Path(f).relative_to(out)) for f in figures],
        "timing": {k: round(v, 4) for k, v in timing.items()},
        "versions": _versions(),
    }
    _assert_finite(summary)
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    return summary


def _say_fidelity(entry: ObjectEntry, scenario: Scenario, make_source, progress: Progress) -> None:
    """Print which fidelity the source will use for an object, and why (the ``auto`` rule's reason)."""
    source = make_source((entry.spec,), 0, "robot")
    if not hasattr(source, "explain"):
        return
    ex = scenario.exploration
    x, y = entry.spec.position
    fidelity, reason = source.explain(PressTarget(x, y, depth=ex.depth, force=ex.max_force, speed=ex.speed))
    progress.message(f"fidelity {fidelity}: {reason}")


def export_haptic_material(post, grid, results: list[PressResult], scenario: Scenario, folder: Path, name: str):
    """Write the seed 002 export of one explored object: probabilities plus per-cell palpation features."""
    from palpate.core.world.haptic_material import HapticMaterialMap

    probs = np.asarray(post.probabilities)
    ny, nx = probs.shape[:2]
    sums = {k: np.zeros((ny, nx)) for k in ("rate_hardness", "contact_area_spread_rate", "local_indentation")}
    counts = np.zeros((ny, nx))
    newton_per_count = scenario.fingertip.sensel_area / scenario.taxels.gain
    for r in results:
        if r.params is None or len(r.t) < 3:
            continue
        try:
            ix, iy = grid.cell_of(*r.location)
        except ValidationError:
            continue
        force = r.c_P * newton_per_count
        sums["rate_hardness"][iy, ix] += _initial_slope(r.c_D, force)
        sums["contact_area_spread_rate"][iy, ix] += _initial_slope(r.c_A, force, whole=True)
        sums["local_indentation"][iy, ix] += r.depth
        counts[iy, ix] += 1
    measured = counts > 0
    feats = {k: np.where(measured, v / np.maximum(counts, 1), 0.0) for k, v in sums.items()}
    hm = HapticMaterialMap(tuple(grid.origin), float(grid.cell_size), list(scenario.references), probs, feats,
                           measured, meta={"object": name, "scenario": scenario.name, "palpate": __version__,
                                           "force_calibration_N_per_count": newton_per_count})
    return hm.write(folder)


def _initial_slope(x: np.ndarray, y: np.ndarray, whole: bool = False) -> float:
    """dy/dx by least squares over the first third of the press (or all of it): the 'initial rate' of seed 002."""
    n = len(x) if whole else max(3, len(x) // 3)
    xs, ys = np.asarray(x[:n], float), np.asarray(y[:n], float)
    dx = xs - xs.mean()
    denom = float(dx @ dx)
    if denom <= 0 or not np.isfinite(denom):
        return 0.0
    return max(0.0, float(dx @ (ys - ys.mean())) / denom)


def _versions() -> dict:
    import importlib.metadata as md

    out = {"palpate": __version__, "python": platform.python_version()}
    for pkg in ("numpy", "scipy", "mujoco", "matplotlib"):
        try:
            out[pkg] = md.version(pkg)
        except md.PackageNotFoundError:
            pass
    return out


def _assert_finite(obj, path: str = "summary") -> None:
    """No NaN or infinity may reach a report."""
    if isinstance(obj, float) and not np.isfinite(obj):
        raise PalpateError(f"{path} is not finite ({obj}); refusing to write a report with NaN")
    if isinstance(obj, dict):
        for k, v in obj.items():
            _assert_finite(v, f"{path}.{k}")
    elif isinstance(obj, (list, tuple)):
        for i, v in enumerate(obj):
            _assert_finite(v, f"{path}[{i}]")


__all__ = ["run_scenario", "perceive_press", "train_memory", "explore_object", "PressResult"]
