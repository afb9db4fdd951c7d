"""The validated scenario: plain frozen dataclasses, SI units (lengths m, moduli Pa, forces N, speeds m/s)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from palpate.core.mapping.calibration import DEFAULT_CALIBRATION, MapCalibration
from palpate.core.world.scene import FingertipSpec, Material, ObjectSpec, PoseSensorSpec, TaxelSensorSpec


@dataclass(frozen=True)
class MaterialEntry:
    """A material of the scenario; ``reference`` ones form the haptic memory.

    ``like`` names the reference material an object made of this material should be classified as (its ground
    truth); a reference material is its own ``like``.
    """

    material: Material
    reference: bool
    like: str


@dataclass(frozen=True)
class TrainingSpec:
    """How the reference materials are pressed to train the haptic memory."""

    presses_per_material: int = 10
    depth: float = 0.004
    max_force: float | None = 5.0
    speed: float = 0.01
    variability: str = "human"
    memory: Path | None = None
    source: str = "sim"
    #: what judges the presses: "haptic_memory" or a classifier plugin's name (palpate.classifiers)
    classifier: str = "haptic_memory"
    #: what the classifier sees of a press: "power_law" ([n1, n2, a1, a2]) or a feature plugin's name
    features: str = "power_law"


@dataclass(frozen=True)
class ExplorationSpec:
    """How each object is explored and mapped."""

    map: str = "grid2d"
    cell_size: float = 0.01
    voxel_depth: float = 0.015
    policy: str = "predefined"
    budget: int = 10
    presses_per_region: int = 2
    depth: float = 0.004
    max_force: float | None = 5.0
    speed: float = 0.01
    variability: str = "human"
    entropy_base: float = 10.0
    stop_mean_entropy: float | None = None
    stop_max_entropy: float | None = None
    stop_min_gain: float | None = None
    travel_cost_per_mm: float = 0.0
    extrapolation_passes: int | None = 1
    objective: str = "accuracy"
    feature_size: float | None = None
    calibration: MapCalibration = DEFAULT_CALIBRATION
    #: voxel maps: also fill unexplored voxels from their explored neighbours in the same layer (eq. 6.15)
    voxel_lateral: bool = False


@dataclass(frozen=True)
class ObjectEntry:
    """An object to explore: its physical description and where to press (1-based cells, as seed Table 6.8)."""

    spec: ObjectSpec
    regions: tuple[tuple[int, int], ...] = ()
    grid_origin: tuple[float, float] | None = None
    grid_shape: tuple[int, int] | None = None


@dataclass(frozen=True)
class ActuatorSpec:
    """What presses during exploration (``[actuator]``; see :mod:`palpate.core.world.actuator_kinds`).

    Attributes:
        kind: "sim" (the registered simulated source) or a kind registered in ``palpate.actuators`` (e.g.
            "operator", "dynamixel").
        options: the kind's own validated options (its :class:`~palpate.core.world.actuator_kinds.ActuatorKind`
            parsed them), None for "sim".
    """

    kind: str = "sim"
    options: object = None


@dataclass(frozen=True)
class OutputSpec:
    """What the run writes besides summary.json and the maps."""

    figures: bool = True
    haptic_material: bool = True
    render_3d: bool = True
    #: Press every column once more with the simulated source to measure the ceiling (session/ceiling.py).
    attainable_accuracy: bool = False


@dataclass(frozen=True)
class RealismSpec:
    """``[realism]``: how hard the simulated presses are, and the real data they are compared with.

    Attributes:
        profile: a realism profile for the simulated source: a preset or shipped profile's name ("ideal", "lab",
            "thesis_ch6", ...) or the path of a profile file (resolved against the scenario's folder); the
            simulation validates it when it opens the source.
        real_params: a per-press parameter table of real presses of the reference materials (the CSV of
            ``palpate memory``); when given, the run reports the simulated training presses against it.
        predictive_sessions: with ``real_params``, simulate this many more training sessions (fresh seeds) and
            judge whether the real table looks like one more of them
            (:func:`~palpate.core.perception.predictive_check.predictive_check`); 0: off (each session costs a
            training's presses).
    """

    profile: str = "ideal"
    real_params: Path | None = None
    predictive_sessions: int = 0


@dataclass(frozen=True)
class Scenario:
    """A validated scenario. Lengths in m, moduli in Pa, forces in N, speeds in m/s."""

    name: str
    path: Path | None
    description: str
    seed: int
    fidelity: str
    materials: dict[str, MaterialEntry]
    fingertip: FingertipSpec
    taxels: TaxelSensorSpec
    pose: PoseSensorSpec
    training: TrainingSpec
    exploration: ExplorationSpec
    objects: tuple[ObjectEntry, ...]
    outputs: OutputSpec = field(default_factory=OutputSpec)
    raw: dict = field(default_factory=dict, repr=False)
    actuator: ActuatorSpec = field(default_factory=ActuatorSpec)
    realism: RealismSpec = field(default_factory=RealismSpec)
    #: ``auto``'s tolerance: the largest predicted force error of a fidelity against the reference, fraction.
    fidelity_tolerance: float = 0.05
    #: MuJoCo's iteration limit for a ``flex`` press (opt.iterations); None is the simulator's default. Raise it where
    #: a run warns that the solve ran out of iterations (stiff thin layers over a soft base): it costs time.
    flex_iterations: int | None = None

    @property
    def references(self) -> list[str]:
        """Names of the reference materials, in file order (the haptic memory's classes)."""
        return [n for n, m in self.materials.items() if m.reference]

    def truth_names(self) -> dict[str, str]:
        """Material name -> the reference material it counts as for ground truth."""
        return {n: m.like for n, m in self.materials.items()}
