"""The public API's functions: load a scenario, press one point of it, train its memory, run it.

Each is a thin layer over what ``palpate run`` does (:mod:`palpate.core.world.scenario_file`,
:mod:`palpate.core.session`) and returns the same typed results the command line writes. Presses go through the
registered source the scenario names (``training.source``, ``sim`` by default), so this module never imports the
simulator itself. SI units throughout: lengths m, forces N, speeds m/s, moduli Pa.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from palpate.core import plugins
from palpate.core.errors import ValidationError
from palpate.core.perception.fit import PressFit
from palpate.core.perception.memory import HapticMemory
from palpate.core.perception.press import PressResult, perceive_press
from palpate.core.perception.streams import GroundTruth, PoseSample, PressRecording, TaxelFrame
from palpate.core.session.progress import Progress
from palpate.core.session.sources import PressTarget, check_seed, scenario_source_maker
from palpate.core.session.training import TrainingResult, training_seeds
from palpate.core.session.training import train_memory as _train_memory
from palpate.core.world.resources import find_scenario
from palpate.core.world.scenario import ObjectEntry, Scenario
from palpate.core.world.scenario_file import load_scenario as _load_file
from palpate.core.world.scene import check_finite, integer
from palpate.core.world.workspace import object_geometry


def load_scenario(scenario: str | Path) -> Scenario:
    """Read and validate a scenario: a ``.toml`` path, or the name of a shipped one (``"thesis_ch6"``,
    ``"sweeps/tiny_base"``; ``palpate scenarios list``). Lengths in the result are m, moduli Pa, forces N.

    Raises ValidationError naming the file and key on anything wrong (and the shipped names when neither).
    """
    return _load_file(find_scenario(scenario))


@dataclass(frozen=True)
class PressOutcome:
    """One press at a point of a scenario object: its raw streams and how palpate perceives them.

    Attributes:
        recording: the raw streams (taxel frames in counts, poses in m, the simulation's ground truth).
        result: the perceived press: press-phase samples, the 3/2-power fits (None when unfittable, with reasons).
        target: the planned (x, y), m, world frame.
    """

    recording: PressRecording
    result: PressResult
    target: tuple[float, float]

    @property
    def frames(self) -> list[TaxelFrame]:
        """Taxel frames (t s, raw 8-bit counts (rows, cols), sensel area m^2)."""
        return self.recording.frames

    @property
    def poses(self) -> list[PoseSample]:
        """Fingertip poses (t s, position m, orientation quaternion)."""
        return self.recording.poses

    @property
    def truth(self) -> GroundTruth | None:
        """The simulation's ground truth (t s, force N, indentation m); None for real presses."""
        return self.recording.truth

    @property
    def fit(self) -> PressFit | None:
        """The 3/2-power fits of the press (kinesthetic N = (n1, n2), cutaneous A = (a1, a2))."""
        return self.result.fit

    @property
    def params(self) -> np.ndarray | None:
        """The fitted parameters [n1, n2, a1, a2] (units of the fit: c_P counts and c_A m^2 against c_D m), or
        None when the press could not be fitted (``result.rejected`` says why)."""
        return self.result.params


def _object(scenario: Scenario, name: str | None) -> ObjectEntry:
    names = [e.spec.name for e in scenario.objects]
    if name is None and len(names) == 1:
        return scenario.objects[0]
    for entry in scenario.objects:
        if entry.spec.name == name:
            return entry
    raise ValidationError(f"scenario {scenario.name!r} has no object {name!r}; its objects: {', '.join(names)}")


def press(scenario: Scenario, obj: str | None = None, xy: tuple[float, float] | None = None, *,
          cell: tuple[int, int] | None = None, depth: float | None = None, force: float | None = None,
          speed: float | None = None, seed: int = 0, variability: str = "robot",
          source: str | None = None) -> PressOutcome:
    """Simulate (or perform, with another registered source) one press-and-release on an object of a scenario.

    Args:
        scenario: from :func:`load_scenario`.
        obj: the object's name (may be left out when the scenario has one object).
        xy: where to press, (x, y) m in the world frame; or
        cell: the map cell to press at its centre, 1-based (column, row) as a scenario's ``regions``.
        depth: indentation to reach, m; force: force limit, N; speed: m/s (default: the scenario's
            ``[exploration]`` values).
        seed: seed of the press's variability and sensor noise.
        variability: "robot" (the exact target) or "human" (speed, depth and position vary).
        source: registered source (default: the scenario's ``training.source``, "sim").

    Returns:
        a :class:`PressOutcome`: ``frames``, ``poses``, ``truth`` and the fitted ``params``.
    """
    entry = _object(scenario, obj)
    if (xy is None) == (cell is None):
        raise ValidationError("press: give either xy (m) or cell (1-based column, row), not both or neither")
    if cell is not None:
        if not (isinstance(cell, (tuple, list)) and len(cell) == 2
                and all(integer(v) for v in cell)):
            raise ValidationError(f"press: cell must be two whole numbers (column, row), 1-based, got {cell!r}")
        centres = object_geometry(scenario, entry).cell_centres()  # (ny, nx, 2)
        ny, nx = centres.shape[:2]
        col, row = (int(v) for v in cell)
        if not (1 <= col <= nx and 1 <= row <= ny):
            raise ValidationError(f"press: cell {cell} is outside the {nx} x {ny} map of {entry.spec.name!r} "
                                  "(1-based column, row)")
        xy = tuple(float(v) for v in centres[row - 1, col - 1])
    if isinstance(xy, (str, bytes)) or np.shape(xy) != (2,):
        raise ValidationError(f"press: xy must be (x, y) in m, got {xy!r}")
    check_finite("press", x=xy[0], y=xy[1])
    x, y = (float(v) for v in xy)
    ex = scenario.exploration
    make = scenario_source_maker(scenario, source or scenario.training.source)
    target = PressTarget(x, y, depth=ex.depth if depth is None else depth,
                         force=ex.max_force if force is None else force, speed=ex.speed if speed is None else speed,
                         label=f"{entry.spec.name} at ({x * 1e3:.1f}, {y * 1e3:.1f}) mm")
    recording = make((entry.spec,), check_seed(seed, "press: seed"), variability).press(target)
    return PressOutcome(recording, perceive_press(recording).at_target((x, y)), (x, y))


def train_memory(scenario: Scenario, *, source: str | None = None, progress: bool = False) -> TrainingResult:
    """Press every reference material of ``scenario`` as its ``[training]`` says (``presses_per_material`` on a
    thick block, seeded from ``scenario.seed`` as a run is) and fit the haptic memory.

    Returns a TrainingResult: ``memory`` (a fitted :class:`~palpate.core.perception.memory.HapticMemory`, what
    ``memory.json`` holds), ``crossval`` (leave-one-out, seed 000 Table 6.7) and ``presses`` (every perceived
    press, by material). ``progress`` shows bars on stderr.
    """
    make = scenario_source_maker(scenario, source or scenario.training.source)
    return _train_memory(scenario, make, training_seeds(scenario), Progress(enabled=progress))


@dataclass(frozen=True)
class RunResult:
    """A finished run: its folder and its summary (the contents of ``summary.json``).

    Attributes:
        out: the output folder (summary.json, memory.json, maps/, figures/, haptic_materials/).
        summary: the run's summary (``scenarios/README.md`` describes every key).
    """

    out: Path
    summary: dict

    def map(self, obj: str, postprocessed: bool = True):
        """The map of object ``obj`` as the run saved it (a Grid2D or VoxelGrid; probabilities per cell)."""
        from palpate.core.mapping.grids import Grid2D, VoxelGrid
        from palpate.core.names import file_stem

        found = [o for o in self.summary["objects"] if o["name"] == obj]
        if not found:
            names = ", ".join(o["name"] for o in self.summary["objects"])
            raise ValidationError(f"run {self.out}: no object {obj!r}; its objects: {names}")
        path = self.out / "maps" / f"{file_stem(obj)}{'_postprocessed' if postprocessed else ''}.npz"
        return (VoxelGrid if found[0]["map"] == "voxel" else Grid2D).load(path)


def with_settings(scenario: Scenario, **tables) -> Scenario:
    """``scenario`` with parts of its file replaced, validated as the file is: a table's keys are merged
    (``with_settings(s, exploration={"policy": "random"})``), an array of tables is replaced (``objects=[...]``).
    Keys carry the file's units (``depth_mm``), not SI; ValidationError names the key on anything wrong."""
    from palpate.core.world.scenario_file import parse_scenario

    raw = dict(scenario.raw)
    for table, value in tables.items():
        raw[table] = {**raw.get(table, {}), **value} if isinstance(value, dict) else value
    file = str(scenario.path) if scenario.path else "<scenario>"
    return parse_scenario(raw, file, base_dir=scenario.path.parent if scenario.path else None)


def run(scenario: Scenario, out: str | Path, *, policy: str | None = None, classifier=None, features=None,
        source: str | None = None, force: bool = False, progress: bool = False) -> RunResult:
    """Run a scenario end to end as ``palpate run`` does and write its outputs into ``out``.

    Args:
        scenario: from :func:`load_scenario`.
        out: output folder: new, empty, or an earlier run's (replaced only with ``force``).
        policy: exploration policy name (palpate's own or a plugin's, :func:`register_policy`), instead of the
            scenario's ``exploration.policy``.
        classifier: what judges the presses instead of the scenario's ``training.classifier``: a registered name
            (:func:`register_classifier`), or an unfitted classifier with ``fit(X, y)`` and ``predict_proba(X)``
            (any scikit-learn classifier), trained on the training presses.
        features: what the classifier sees of each press instead of ``training.features``: a registered name
            (:func:`register_features`) or an extractor ``f(PressResult) -> 1-D array | None``.
        source: registered source that trains and explores (default: the scenario's ``training.source``).
        progress: show progress bars on stderr.

    Returns:
        a :class:`RunResult` (the folder and ``summary.json``'s contents; ``summary["algorithms"]`` names the
        policy, classifier and features used and where each came from).
    """
    from palpate.core.perception.classifier_memory import ClassifierMemory, classifier_for
    from palpate.core.session.run import run_scenario

    training = {k: v for k, v in (("classifier", classifier), ("features", features)) if isinstance(v, str)}
    if policy is not None or training:
        scenario = with_settings(scenario, **({"exploration": {"policy": policy}} if policy is not None else {}),
                                 **({"training": training} if training else {}))
    memory = None
    given_classifier = classifier is not None and not isinstance(classifier, str)
    given_features = features is not None and not isinstance(features, str)
    if given_classifier or given_features:  # objects, not names: the rest still comes from the scenario's names
        refs = scenario.references
        named, _ = classifier_for(scenario.training.classifier, scenario.training.features, refs)
        if isinstance(classifier, ClassifierMemory):
            memory = classifier
        elif given_classifier:
            memory = ClassifierMemory(classifier, refs, features=named.features if named else None)
        else:
            memory = named or ClassifierMemory(HapticMemory(refs), refs, scenario.training.classifier)
        if given_features:
            memory = ClassifierMemory(memory.estimator, memory.materials_arg, memory.name, features)
    summary = run_scenario(scenario, out, progress=Progress(enabled=progress), source=source, force=force,
                           classifier=memory)
    return RunResult(Path(out), summary)


def register_policy(name: str, factory, *, replace: bool = False) -> None:
    """Register an exploration policy for this process: ``factory(context) -> policy``, where ``context`` is a
    :class:`~palpate.core.planning.registry.PolicyContext` (the object's map geometry, seed, memory, regions,
    budget, depth m) and ``policy.next_target(grid, post, last)`` returns a
    :class:`~palpate.core.planning.policies.Target` (0-based ix, iy) or None. A scenario may then name it
    (``exploration.policy``). Installed packages register through the entry-point group ``palpate.policies``."""
    plugins.register(plugins.POLICIES, name, factory, replace)


def register_classifier(name: str, factory, *, replace: bool = False) -> None:
    """Register a classifier for this process: ``factory()`` returns a new unfitted classifier with ``fit(X, y)``
    and ``predict_proba(X)`` (e.g. ``sklearn.linear_model.LogisticRegression`` itself). A scenario may then name it
    (``training.classifier``). Entry-point group: ``palpate.classifiers``."""
    plugins.register(plugins.CLASSIFIERS, name, factory, replace)


def register_features(name: str, extractor, *, replace: bool = False) -> None:
    """Register a per-press feature extractor for this process: ``extractor(result)`` takes a perceived press
    (:class:`~palpate.core.perception.press.PressResult`: ``press`` samples t s, c_P counts, c_A m^2, c_D m;
    ``fit``) and returns a 1-D float array or None. A scenario may then name it (``training.features``).
    Entry-point group: ``palpate.features``."""
    plugins.register(plugins.FEATURES, name, extractor, replace)


def unregister(name: str) -> None:
    """Remove an in-process registration of ``name`` (policy, classifier or feature extractor)."""
    for registry in (plugins.POLICIES, plugins.CLASSIFIERS, plugins.FEATURES):
        plugins.unregister(registry, name)


def available() -> dict[str, list[str]]:
    """Every name a scenario may use: {"policies": [...], "classifiers": [...], "features": [...]}, palpate's own
    first, then the plugins (in-process registrations and installed entry points)."""
    return {"policies": plugins.names(plugins.POLICIES), "classifiers": plugins.names(plugins.CLASSIFIERS),
            "features": plugins.names(plugins.FEATURES)}
