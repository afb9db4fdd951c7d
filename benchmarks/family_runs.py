"""Runs of exploration policies on the shape-family scenes (benchmarks/scene_families.py), offline and with physics.

Offline, a press is answered without simulating it: the cell's *felt* reference material is worked out once per
cell from the physics model's contact law there (sim/contact: the modulus of the Hertz law through the force the
press reaches; a press on a wall or on a one-cell feature feels a blend, which may read as a third material), and
each press then draws one of the memory's predicted posteriors for that material (palpate.core.planning.outcomes).
With physics, every press is simulated (analytic fidelity) and perceived through the run's own loop (explore_object).

Both record the post-processed map's accuracy after every press; the *ceiling* of a scene is what a raster reaches
with every cell pressed once (the attainable accuracy), and a run's presses are counted to 95% of the ceiling and to
95% absolute.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
import tempfile
from dataclasses import dataclass
from functools import cache
from pathlib import Path

import numpy as np
from exploration import make_source_for
from scene_families import GENERATOR_VERSION, REFERENCES, FamilyScene, scene

import palpate.core.world.scene as world_scene
import palpate.sim.contact as contact_package
import palpate.sim.reference as reference_package
from palpate.core.errors import ValidationError
from palpate.core.mapping.accuracy import map_accuracy
from palpate.core.mapping.calibration import MapCalibration, calibration_sample
from palpate.core.mapping.grids import new_map
from palpate.core.planning.outcomes import outcome_posteriors
from palpate.core.planning.registry import make_policy
from palpate.core.session.explore import MapPostprocessing, explore_object
from palpate.core.session.progress import Progress
from palpate.core.session.training import train_memory
from palpate.core.world.scenario_file import parse_scenario
from palpate.core.world.workspace import ground_truth_map, object_geometry
from palpate.sim.contact.stack import object_law
from palpate.sim.stability import MAX_DEPTH_OVER_RADIUS

#: Benchmark rows: name -> (scenario policy, info_gain objective).
ROWS = {"raster": ("raster", None), "max_entropy": ("max_entropy", None),
        "info_gain_entropy": ("info_gain", "entropy"), "info_gain": ("info_gain", "accuracy")}
ACCURACY = 0.95
OF_CEILING = 0.95
#: Where felt materials are cached (recomputed when missing; delete to recompute after changing the generator).
CACHE_DIR = Path(tempfile.gettempdir()) / f"palpate_families_v{GENERATOR_VERSION}_law"
#: Fractions of a scene's cells pressed at which the map's calibration is sampled.
CALIBRATION_AT = (0.2, 0.35, 0.5, 1.0)


@cache
def law_digest() -> str:
    """A digest of the code felt cells come from (the contact law and its FE surrogate, the scene's material
    lookup): a cache filled before that code changed must not answer for it."""
    files = [*sorted(Path(contact_package.__file__).parent.glob("*.py")),
             *sorted(Path(reference_package.__file__).parent.glob("*.py")), Path(world_scene.__file__)]
    h = hashlib.sha1()
    for f in files:
        h.update(f.read_bytes())
    return h.hexdigest()[:10]


@dataclass(frozen=True)
class Run:
    """One policy on one scene: accuracy of the post-processed map before the first press and after each press,
    and the post-processed maps' (confidence, right) per cell at :data:`CALIBRATION_AT`."""

    accuracy: np.ndarray
    confidence: np.ndarray
    right: np.ndarray

    def presses_to(self, level: float) -> int | None:
        hit = np.flatnonzero(self.accuracy >= level - 1e-12)
        return int(hit[0]) if hit.size else None


@cache
def memory_for(references: tuple[str, ...], moduli: tuple[float, ...]):
    """The haptic memory of reference materials (names, Young's moduli kPa), trained once with physics presses
    (10 per material)."""
    mats = [{"name": n, "young_kpa": e, "poisson": next(r[2] for r in REFERENCES if r[0] == n)}
            for n, e in zip(references, moduli, strict=True)]
    raw = scene(0).scenario_dict()
    raw["materials"] = mats
    raw["objects"][0]["material"] = references[0]
    sc = parse_scenario(raw, "training")
    return train_memory(sc, make_source_for(sc), np.arange(len(references)) + 1000, Progress(enabled=False)).memory


@cache
def answers_for(references: tuple[str, ...], moduli: tuple[float, ...], samples: int = 40) -> np.ndarray:
    """Predicted per-press posteriors (M, S, M) of the memory of ``references`` (offline presses draw from them)."""
    return outcome_posteriors(memory_for(references, moduli), samples, seed=99)


def felt_cells(fs: FamilyScene) -> np.ndarray:
    """(ny, nx) reference index a press at each cell centre reads: the reference whose E* is nearest (in log) to
    the effective modulus felt under a 4 mm / 10 N press there (the Hertz law's E* through the contact law's force at
    the press's depth: layers, lumps and the table under a thin object)."""
    sc = fs.scenario()
    entry = sc.objects[0]
    spec = entry.spec
    geom = object_geometry(sc, entry)
    refs = sc.references
    e_ref = np.log([sc.materials[r].material.effective_modulus for r in refs])
    radius = sc.fingertip.radius
    top = spec.height
    centres = geom.cell_centres()
    out = np.empty(centres.shape[:2], dtype=int)
    laws: dict = {}  # one scene's cells share column stacks: each column's FE energy shares are solved once
    for iy in range(centres.shape[0]):
        for ix in range(centres.shape[1]):
            x, y = (float(v) for v in centres[iy, ix])
            law = object_law(spec, x, y, top, radius, MAX_DEPTH_OVER_RADIUS * radius, cache=laws)
            force = sc.exploration.max_force
            reach = law.depth_for_force(force) if force < law.force[-1] else law.max_depth
            d = min(sc.exploration.depth, reach)
            e = 3.0 * float(law.force_at(d)) / (4.0 * math.sqrt(radius) * d**1.5)
            out[iy, ix] = int(np.argmin(np.abs(e_ref - math.log(e))))
    return out


class RunTrace:
    """What a run records as it goes: the post-processed map's accuracy after each press (:meth:`accuracy`), and
    its (confidence, right) per cell at :data:`CALIBRATION_AT` (:meth:`calibration`); :meth:`run` builds the Run."""

    def __init__(self, truth: np.ndarray) -> None:
        self.truth = truth
        self.checkpoints = {max(1, int(round(f * truth.size))) for f in CALIBRATION_AT}
        self.acc: list[float] = []
        self.confs: list[np.ndarray] = []
        self.rights: list[np.ndarray] = []

    def accuracy(self, post_p) -> float:
        """Record (and return) the accuracy of the map after the next press (before any press first)."""
        self.acc.append(map_accuracy(post_p, self.truth) or 0.0)
        return self.acc[-1]

    def calibration(self, k: int, post_p) -> None:
        """Sample the map's calibration if ``k`` presses is one of the checkpoints."""
        if k in self.checkpoints:
            conf, right, _ = calibration_sample(np.asarray(post_p), self.truth)
            self.confs.append(conf)
            self.rights.append(right)

    def run(self) -> Run:
        return Run(np.array(self.acc), np.concatenate(self.confs) if self.confs else np.zeros(0),
                   np.concatenate(self.rights) if self.rights else np.zeros(0, bool))


def offline_run(fs: FamilyScene, row: str, *, stop_at: float | None = None, memory=None, answers=None,
                felt=None, settings: dict | None = None, policy_for=None) -> Run:
    """One policy on one scene with presses answered offline (module docstring); stops once the accuracy reaches
    ``stop_at`` (None: after one press per cell). ``settings`` replaces fields of the built policy (e.g. info_gain's
    ``entropy_weight``), for sweeps on the tuning seeds; ``policy_for(policy, truth)``, when given, returns the
    policy to run instead (a reference built on it, e.g. benchmarks/oracle_risk.py)."""
    kind, objective = ROWS[row]
    sc = fs.scenario(kind, objective=objective)
    entry = sc.objects[0]
    geom = object_geometry(sc, entry)
    truth = ground_truth_map(entry, sc, geom)
    felt = felt_cells_cached(fs) if felt is None else felt
    memory = memory_for(fs.references, fs.moduli()) if memory is None else memory
    answers = answers_for(fs.references, fs.moduli()) if answers is None else answers
    ex = sc.exploration
    regions = [(c - 1, r - 1) for c, r in entry.regions]
    cal = ex.calibration
    policy = make_policy(kind, cells=regions, seed=fs.seed, memory=memory, objective=ex.objective,
                         feature_size=ex.feature_size, certainty=cal.extrapolation_certainty)
    if settings:
        policy = dataclasses.replace(policy, **settings)
    if policy_for is not None:
        policy = policy_for(policy, truth)
    grid = new_map(geom)
    rng = np.random.default_rng(fs.seed + 7000)
    n = truth.size
    trace = RunTrace(truth)
    last = None
    post = postprocess(grid, cal)
    for k in range(n + 1):
        got = trace.accuracy(post.probabilities)
        trace.calibration(k, post.probabilities)
        if k == n or (stop_at is not None and got >= stop_at):
            break
        t = policy.next_target(grid, planned_on(grid, cal, post), last)
        if t is None:
            break
        grid.update_cell(t.ix, t.iy, cal.evidence(answers[felt[t.iy, t.ix], rng.integers(answers.shape[1])]))
        last = (t.ix, t.iy)
        post = postprocess(grid, cal)
    return trace.run()


def felt_cells_cached(fs: FamilyScene) -> np.ndarray:
    """:func:`felt_cells` of a scene, kept in CACHE_DIR and looked up in the committed FELT_ARCHIVE (a cell with a
    wall within reach costs an axisymmetric FE solve, so a scene takes up to a minute the first time)."""
    name = _felt_name(fs)
    path = CACHE_DIR / f"{name}.npy"
    if path.is_file():
        got = np.load(path, allow_pickle=False)
        if got.shape == fs.grid_cells[::-1]:
            return got
    got = _archived(name, fs)
    if got is not None:
        return got
    out = felt_cells(fs)
    CACHE_DIR.mkdir(parents=True, exist_ok=True)
    np.save(path, out, allow_pickle=False)
    return out


#: Felt cells committed with the benchmark (one array per scene, named as the cache files), so a fresh machine
#: does not spend an hour of FE solves before the first table; entries of another law's code are never used.
FELT_ARCHIVE = Path(__file__).resolve().parent / "data" / "felt_cells.npz"
#: Largest archive read (a few hundred scenes of a few hundred cells are ~100 kB).
MAX_ARCHIVE_BYTES = 20_000_000


def _felt_name(fs: FamilyScene) -> str:
    # keyed on the materials (a variant of the same layout, --confused, feels different) and on the law's code
    key = hashlib.sha1((repr(fs.materials) + law_digest()).encode()).hexdigest()[:10]
    return f"felt_{fs.seed}_{key}"


@cache
def _archive() -> dict[str, np.ndarray]:
    if not FELT_ARCHIVE.is_file():
        return {}
    if FELT_ARCHIVE.stat().st_size > MAX_ARCHIVE_BYTES:
        raise ValidationError(f"{FELT_ARCHIVE}: {FELT_ARCHIVE.stat().st_size} bytes, more than {MAX_ARCHIVE_BYTES}")
    with np.load(FELT_ARCHIVE, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def _archived(name: str, fs: FamilyScene) -> np.ndarray | None:
    got = _archive().get(name)
    if got is None:
        return None
    if got.shape != fs.grid_cells[::-1] or got.dtype.kind not in "iu" or got.min() < 0 \
            or got.max() >= len(fs.references):
        raise ValidationError(f"{FELT_ARCHIVE}: {name} is not a {fs.grid_cells[::-1]} map of reference indices")
    return got.astype(int)


def store_felt_archive() -> int:
    """Write FELT_ARCHIVE: its own entries and this machine's cache files, those of today's law's code only (plain
    scenes, not their --confused variants); returns how many scenes it holds."""
    current = {}
    for name, felt in _archive().items():
        if name == _felt_name(scene(int(name.split("_")[1]))):
            current[name] = felt.astype(np.int8)
    for path in CACHE_DIR.glob("felt_*.npy"):
        if path.stem == _felt_name(scene(int(path.stem.split("_")[1]))):
            current[path.stem] = np.load(path, allow_pickle=False).astype(np.int8)
    FELT_ARCHIVE.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(FELT_ARCHIVE, **dict(sorted(current.items())))
    _archive.cache_clear()
    return len(current)


def physics_run(fs: FamilyScene, row: str, seed: int = 0, budget: int | None = None) -> Run:
    """One policy on one scene with simulated presses (analytic fidelity) through explore_object, one press per
    cell at most (``budget`` presses when given)."""
    res, cal = physics_explore(fs, row, seed, budget)
    trace = RunTrace(res.truth)
    trace.accuracy(new_map(res.geometry).postprocessed().probabilities)
    trace.acc += [s.accuracy_postprocessed or 0.0 for s in res.steps]
    for k, grid in checkpoint_maps(res, cal, trace.checkpoints):
        trace.calibration(k, postprocess(grid, cal).probabilities)
    return trace.run()


def physics_explore(fs: FamilyScene, row: str, seed: int = 0, budget: int | None = None,
                    calibration: MapCalibration | None = None):
    """(explore_object's result, the scenario's map calibration) of one policy on one scene with physics;
    ``calibration`` replaces the scenario's (for sweeps on the tuning seeds)."""
    kind, objective = ROWS[row]
    sc = fs.scenario(kind, budget=budget, objective=objective)
    if calibration is not None:
        sc = dataclasses.replace(sc, exploration=dataclasses.replace(sc.exploration, calibration=calibration))
    entry = sc.objects[0]
    memory = memory_for(fs.references, fs.moduli())
    res = explore_object(sc, entry, memory, make_source_for(sc), 7000 + fs.seed + seed, Progress(enabled=False))
    return res, sc.exploration.calibration


#: How the families' scenes post-process their maps: explore_object's defaults (one eq. 6.15 pass).
POSTPROCESSING = MapPostprocessing()


def postprocess(grid, cal: MapCalibration):
    """The post-processed 2-D map a run with calibration ``cal`` reports (:meth:`MapPostprocessing.apply`)."""
    return POSTPROCESSING.apply(grid, cal)


def planned_on(grid, cal: MapCalibration, post):
    """The map the policies plan on, given the reported ``post`` (:meth:`MapPostprocessing.planned_on`: without
    the wall tempering, as explore_object's policies do)."""
    return POSTPROCESSING.planned_on(grid, cal, post)


def checkpoint_maps(res, cal: MapCalibration, checkpoints):
    """(k, map after k presses) for every k in ``checkpoints``, rebuilt from what each press of the run ``res``
    fused (the run keeps only its last map); the map is updated in place after it is yielded."""
    grid = new_map(res.geometry)
    for s in res.steps:
        if s.posterior is not None:
            try:
                grid.update(*s.result.location, cal.evidence(s.posterior))
            except ValidationError:  # the finger slipped off the grid: the run updated the planned cell
                grid.update(*s.target, cal.evidence(s.posterior))
        if s.k in checkpoints:
            yield s.k, grid
