"""Scenario files (TOML): what to build, what to explore, what to report — validated on load.

Loading never executes code: the file is parsed with ``tomllib`` and every key is checked against the schema
below. Unknown keys are errors, not ignored. An error names the file, the key path and what was expected, e.g.
``scenarios/x.toml: objects[1].size_mm: expected 3 numbers for shape 'box', got 2``.

Keys carry their unit in their name (``young_kpa``, ``size_mm``, ``speed_mm_s``); the loader converts to SI.
See ``scenarios/README.md`` for the full schema with an example of every table.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from palpate.core.errors import ValidationError
from palpate.core.world.scene import (
    FingertipSpec,
    Inclusion,
    Layer,
    Material,
    ObjectSpec,
    PoseSensorSpec,
    TaxelSensorSpec,
)

FIDELITIES = ("analytic", "rigid", "flex", "auto")
MAP_KINDS = ("grid2d", "voxel")
POLICIES = ("predefined", "raster", "random", "max_entropy", "info_gain")
#: What info_gain plans on, 2-D maps (palpate.core.planning.info_gain.InfoGain): expected cells set right, or entropy.
OBJECTIVES = ("accuracy", "entropy")
VARIABILITY = ("human", "robot")
ACTUATORS = ("sim", "operator", "dynamixel")
# Keys of [actuator] beside ``kind``, per kind (a key of another kind is an error that says whose it is).
ACTUATOR_KEYS = {"sim": (), "operator": ("recordings_dir", "figures"),
                 "dynamixel": ("port", "baud", "finger", "emulate", "pose_noise_mm", "approach_mm")}
_REQUIRED = object()


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
    feature_size: float = 0.06


@dataclass(frozen=True)
class ObjectEntry:
    """An object to explore: its physical description and where to press (1-based cells, as seed Table 6.8)."""

    spec: ObjectSpec
    regions: tuple[tuple[int, int], ...] = ()
    grid_origin: tuple[float, float] | None = None
    grid_shape: tuple[int, int] | None = None


@dataclass(frozen=True)
class ActuatorSpec:
    """What presses during exploration (``[actuator]``; built by :mod:`palpate.core.session.actuators`).

    Attributes:
        kind: "sim" (the registered simulated source), "operator" (a person shown each target) or "dynamixel".
        recordings_dir: operator: folder of MCAP recordings, one per press, taken in name order (with several
            objects, one subfolder per object, named as the object).
        figures: operator: also write a PNG of the grid with the target before each press.
        port: dynamixel: serial port of the servo bus (None with ``emulate``).
        baud: dynamixel: bus bit rate.
        finger: dynamixel: finger description file (models/fingers/*.toml).
        emulate: dynamixel: press through the servo emulator on a pty, backed by MuJoCo physics of the scene.
        pose_noise: dynamixel: standard deviation of noise added to each fingertip position, m per axis.
        approach_height: dynamixel: height above the surface where each press starts, m (None: the finger file's).
    """

    kind: str = "sim"
    recordings_dir: Path | None = None
    figures: bool = True
    port: str | None = None
    baud: int = 1_000_000
    finger: Path | None = None
    emulate: bool = False
    pose_noise: float = 0.0
    approach_height: float | None = None


@dataclass(frozen=True)
class OutputSpec:
    """What the run writes besides summary.json and the maps."""

    figures: bool = True
    haptic_material: bool = True
    render_3d: bool = True


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

    @property
    def references(self) -> list[str]:
        """Names of the reference materials, in file order (the haptic memory's classes)."""
        return [n for n, m in self.materials.items() if m.reference]

    def truth_names(self) -> dict[str, str]:
        """Material name -> the reference material it counts as for ground truth."""
        return {n: m.like for n, m in self.materials.items()}


class _Reader:
    """Typed access to a TOML table that records the key path for error messages."""

    def __init__(self, file: str, table: dict, path: str):
        self.file, self.table, self.path = file, table, path
        self.used: set[str] = set()

    def err(self, key: str, msg: str) -> ValidationError:
        where = f"{self.path}.{key}" if self.path else key
        return ValidationError(f"{self.file}: {where}: {msg}")

    def get(self, key: str, kind: type | tuple, default: Any = _REQUIRED) -> Any:
        self.used.add(key)
        if key not in self.table:
            if default is _REQUIRED:
                raise self.err(key, "missing (required)")
            return default
        value = self.table[key]
        kinds = kind if isinstance(kind, tuple) else (kind,)
        if float in kinds and isinstance(value, int) and not isinstance(value, bool):
            value = float(value)
        if isinstance(value, bool) and bool not in kinds:
            raise self.err(key, f"expected {_kind_name(kinds)}, got a boolean")
        if not isinstance(value, kinds):
            raise self.err(key, f"expected {_kind_name(kinds)}, got {type(value).__name__} {value!r}")
        return value

    def number(self, key: str, default: Any = _REQUIRED, *, lo: float | None = None, hi: float | None = None,
               lo_open: bool = False) -> float:
        value = self.get(key, float, default)
        if value is None or value is default and default is not _REQUIRED:
            return value
        if value != value or value in (float("inf"), float("-inf")):
            raise self.err(key, "must be a finite number")
        if lo is not None and (value < lo or (lo_open and value == lo)):
            raise self.err(key, f"must be {'>' if lo_open else '>='} {lo}, got {value}")
        if hi is not None and value > hi:
            raise self.err(key, f"must be <= {hi}, got {value}")
        return value

    def integer(self, key: str, default: Any = _REQUIRED, *, lo: int | None = None) -> int:
        value = self.get(key, int, default)
        if lo is not None and value < lo:
            raise self.err(key, f"must be >= {lo}, got {value}")
        return value

    def choice(self, key: str, choices: tuple[str, ...], default: Any = _REQUIRED) -> str:
        value = self.get(key, str, default)
        if value not in choices:
            raise self.err(key, f"must be one of {', '.join(choices)}; got {value!r}")
        return value

    def numbers(self, key: str, count: int | tuple[int, ...], default: Any = _REQUIRED, *,
                positive: bool = False) -> tuple[float, ...]:
        value = self.get(key, list, default)
        if value is default and default is not _REQUIRED:
            return value
        counts = count if isinstance(count, tuple) else (count,)
        if len(value) not in counts or not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                                               for v in value):
            raise self.err(key, f"expected {' or '.join(map(str, counts))} numbers, got {value!r}")
        out = tuple(float(v) for v in value)
        if positive and any(v <= 0 for v in out):
            raise self.err(key, f"values must be > 0, got {value!r}")
        return out

    def sub(self, key: str, required: bool = False) -> _Reader:
        value = self.get(key, dict, _REQUIRED if required else {})
        return _Reader(self.file, value, f"{self.path}.{key}" if self.path else key)

    def subs(self, key: str) -> list[_Reader]:
        value = self.get(key, list, [])
        out = []
        for i, item in enumerate(value):
            where = f"{self.path}.{key}[{i}]" if self.path else f"{key}[{i}]"
            if not isinstance(item, dict):
                raise ValidationError(f"{self.file}: {where}: expected a table, got {item!r}")
            out.append(_Reader(self.file, item, where))
        return out

    def finish(self) -> None:
        extra = sorted(set(self.table) - self.used)
        if extra:
            raise self.err(extra[0], f"unknown key (known keys here: {', '.join(sorted(self.used))})")


def _kind_name(kinds: tuple) -> str:
    names = {str: "a string", float: "a number", int: "an integer", bool: "true or false", list: "an array",
             dict: "a table"}
    return " or ".join(names.get(k, k.__name__) for k in kinds)


def load_scenario(path: str | Path) -> Scenario:
    """Read and validate a scenario file. Raises ValidationError naming the file and key on any problem."""
    p = Path(path)
    if not p.is_file():
        raise ValidationError(f"{p}: scenario file not found")
    try:
        raw = tomllib.loads(p.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise ValidationError(f"{p}: not valid TOML: {exc}") from None
    except UnicodeDecodeError:
        raise ValidationError(f"{p}: not a UTF-8 text file") from None
    return parse_scenario(raw, str(p), base_dir=p.parent)


def parse_scenario(raw: dict, file: str = "<scenario>", base_dir: Path | None = None) -> Scenario:
    """Validate a scenario given as a parsed TOML dictionary (see :func:`load_scenario`)."""
    base = base_dir or Path.cwd()
    top = _Reader(file, raw, "")
    head = top.sub("scenario", required=True)
    name = head.get("name", str)
    description = head.get("description", str, "")
    seed = head.integer("seed", 0, lo=0)
    fidelity = head.choice("fidelity", FIDELITIES, "auto")
    head.finish()

    materials: dict[str, MaterialEntry] = {}
    for r in top.subs("materials"):
        mname = r.get("name", str)
        if mname in materials:
            raise r.err("name", f"duplicate material name {mname!r}")
        mat = Material(
            name=mname,
            young=r.number("young_kpa", lo=0.0, lo_open=True) * 1e3,
            poisson=r.number("poisson", 0.3, lo=0.0, hi=0.4999),
            damping=r.number("damping_s", 0.0, lo=0.0),
        )
        reference = r.get("reference", bool, True)
        like = r.get("like", str, mname if reference else _REQUIRED)
        r.finish()
        materials[mname] = MaterialEntry(mat, reference, like)
    if not materials:
        raise ValidationError(f"{file}: materials: at least one [[materials]] table is required")
    refs = [n for n, m in materials.items() if m.reference]
    if len(refs) < 2:
        raise ValidationError(f"{file}: materials: at least two reference materials are needed, got {refs}")
    for n, m in materials.items():
        if m.like not in refs:
            raise ValidationError(f"{file}: materials: material {n!r} has like = {m.like!r}, "
                                  f"which is not a reference material ({', '.join(refs)})")

    ft = top.sub("fingertip")
    d_ft = FingertipSpec()
    fingertip = FingertipSpec(
        radius=ft.number("radius_mm", d_ft.radius * 1e3, lo=0.0, lo_open=True) * 1e-3,
        rows=ft.integer("rows", d_ft.rows, lo=1),
        cols=ft.integer("cols", d_ft.cols, lo=1),
        pitch=ft.number("pitch_mm", d_ft.pitch * 1e3, lo=0.0, lo_open=True) * 1e-3,
        sensel_size=ft.number("sensel_mm", d_ft.sensel_size * 1e3, lo=0.0, lo_open=True) * 1e-3,
    )
    ft.finish()
    sensors = top.sub("sensors")
    tx = sensors.sub("taxels")
    d_tx = TaxelSensorSpec()
    taxels = TaxelSensorSpec(
        rate=tx.number("rate_hz", d_tx.rate, lo=0.0, lo_open=True),
        gain=tx.number("gain_counts_per_kpa", d_tx.gain * 1e3, lo=0.0, lo_open=True) * 1e-3,
        noise_std=tx.number("noise_counts", d_tx.noise_std, lo=0.0),
        threshold=tx.integer("threshold_counts", d_tx.threshold, lo=0),
        clock_offset=tx.number("clock_offset_s", d_tx.clock_offset),
    )
    tx.finish()
    po = sensors.sub("pose")
    d_po = PoseSensorSpec()
    pose = PoseSensorSpec(
        rate=po.number("rate_hz", d_po.rate, lo=0.0, lo_open=True),
        noise_std=po.number("noise_mm", d_po.noise_std * 1e3, lo=0.0) * 1e-3,
        clock_offset=po.number("clock_offset_s", d_po.clock_offset),
        jitter=po.number("jitter_ms", d_po.jitter * 1e3, lo=0.0) * 1e-3,
    )
    po.finish()
    sensors.finish()

    tr = top.sub("training")
    memory = tr.get("memory", str, "")
    training = TrainingSpec(
        presses_per_material=tr.integer("presses_per_material", 10, lo=3),
        depth=tr.number("depth_mm", 4.0, lo=0.0, lo_open=True) * 1e-3,
        max_force=_optional_force(tr),
        speed=tr.number("speed_mm_s", 10.0, lo=0.0, lo_open=True) * 1e-3,
        variability=tr.choice("variability", VARIABILITY, "human"),
        memory=_resolve(base, memory) if memory else None,
        source=_training_source(tr),
    )
    tr.finish()

    ex = top.sub("exploration")
    stop = ex.number("stop_mean_entropy", None, lo=0.0)
    exploration = ExplorationSpec(
        map=ex.choice("map", MAP_KINDS, "grid2d"),
        cell_size=ex.number("cell_mm", 10.0, lo=0.0, lo_open=True) * 1e-3,
        voxel_depth=ex.number("voxel_depth_mm", 15.0, lo=0.0, lo_open=True) * 1e-3,
        policy=ex.choice("policy", POLICIES, "predefined"),
        budget=ex.integer("budget", 10, lo=1),
        presses_per_region=ex.integer("presses_per_region", 2, lo=1),
        depth=ex.number("depth_mm", 4.0, lo=0.0, lo_open=True) * 1e-3,
        max_force=_optional_force(ex),
        speed=ex.number("speed_mm_s", 10.0, lo=0.0, lo_open=True) * 1e-3,
        variability=ex.choice("variability", VARIABILITY, "human"),
        entropy_base=ex.number("entropy_base", 10.0, lo=1.0, lo_open=True),
        stop_mean_entropy=stop,
        stop_max_entropy=ex.number("stop_max_entropy", None, lo=0.0),
        stop_min_gain=ex.number("stop_min_gain", None, lo=0.0),
        travel_cost_per_mm=ex.number("travel_cost_per_mm", 0.0, lo=0.0),
        extrapolation_passes=_extrapolation_passes(ex),
        objective=ex.choice("objective", OBJECTIVES, "accuracy"),
        feature_size=ex.number("feature_size_mm", 60.0, lo=0.0, lo_open=True) * 1e-3,
    )
    if exploration.stop_min_gain is not None and exploration.policy != "info_gain":
        raise ex.err("stop_min_gain", f"only the info_gain policy predicts a gain; policy is {exploration.policy!r}")
    for key in ("objective", "feature_size_mm"):
        if key in ex.table and exploration.policy != "info_gain":
            raise ex.err(key, f"only the info_gain policy uses it; policy is {exploration.policy!r}")
    if exploration.extrapolation_passes != 1 and exploration.map != "grid2d":
        raise ex.err("extrapolation_passes", "iterated eq. 6.15 extrapolation is a grid2d post-processing; map is "
                     f"{exploration.map!r} (leave the key out)")
    if exploration.travel_cost_per_mm > 0 and exploration.policy not in ("max_entropy", "info_gain"):
        raise ex.err("travel_cost_per_mm", "only max_entropy and info_gain weigh travel; policy is "
                     f"{exploration.policy!r}")
    ex.finish()

    objects = []
    seen_names: set[str] = set()
    for r in top.subs("objects"):
        objects.append(_object(r, materials, base))
        if objects[-1].spec.name in seen_names:
            raise r.err("name", f"duplicate object name {objects[-1].spec.name!r}")
        seen_names.add(objects[-1].spec.name)
        if exploration.policy == "predefined" and not objects[-1].regions:
            raise r.err("regions", "the 'predefined' policy needs a list of 1-based [column, row] cells")

    out = top.sub("outputs")
    outputs = OutputSpec(
        figures=out.get("figures", bool, True),
        haptic_material=out.get("haptic_material", bool, True),
        render_3d=out.get("render_3d", bool, True),
    )
    out.finish()
    actuator = _actuator(top.sub("actuator"), base)
    top.finish()
    return Scenario(name, Path(file) if file != "<scenario>" else None, description, seed, fidelity, materials,
                    fingertip, taxels, pose, training, exploration, tuple(objects), outputs, raw, actuator)


def parse_actuator(table: dict, file: str = "<scenario>", base: Path | None = None) -> ActuatorSpec:
    """Validate an ``[actuator]`` table (already parsed from TOML); relative paths resolve against ``base``."""
    if not isinstance(table, dict):
        raise ValidationError(f"{file}: actuator: expected a table, got {table!r}")
    return _actuator(_Reader(file, table, "actuator"), base or Path.cwd())


def _actuator(r: _Reader, base: Path) -> ActuatorSpec:
    kind = r.choice("kind", ACTUATORS, "sim")
    for key in r.table:
        owner = next((k for k, keys in ACTUATOR_KEYS.items() if key in keys), None)
        if owner is not None and owner != kind:
            raise r.err(key, f"is a key of kind {owner!r}, but kind is {kind!r}")
    d = ActuatorSpec()
    if kind == "operator":
        folder = r.get("recordings_dir", str)
        if not folder:
            raise r.err("recordings_dir", "must name a folder of MCAP recordings, one per press")
        spec = ActuatorSpec(kind, recordings_dir=_resolve(base, folder), figures=r.get("figures", bool, True))
    elif kind == "dynamixel":
        emulate = r.get("emulate", bool, False)
        port = r.get("port", str, "") or None
        if emulate and port:
            raise r.err("port", "not used with emulate = true (the emulator opens its own pseudo-terminal); "
                        "leave one of them out")
        if not emulate and not port:
            raise r.err("port", "missing: the servo bus's serial port (e.g. /dev/ttyUSB0), or emulate = true")
        finger = r.get("finger", str)
        if not finger:
            raise r.err("finger", "must name a finger description file (models/fingers/*.toml)")
        approach = r.number("approach_mm", None, lo=0.0, lo_open=True)
        spec = ActuatorSpec(kind, port=port, baud=r.integer("baud", d.baud, lo=1), finger=_resolve(base, finger),
                            emulate=emulate, pose_noise=r.number("pose_noise_mm", 0.0, lo=0.0) * 1e-3,
                            approach_height=None if approach is None else approach * 1e-3)
    else:
        spec = d
    r.finish()
    return spec


def _training_source(r: _Reader) -> str:
    """``training.source``: the registered source that presses the reference materials (a simulation)."""
    value = r.get("source", str, "sim")
    if value in ("operator", "dynamixel"):
        raise r.err("source", f"{value!r} is an exploration actuator ([actuator] kind); the reference materials "
                    "are pressed by a registered simulated source (e.g. 'sim'), or give training.memory")
    if not value:
        raise r.err("source", "must name a registered source, e.g. 'sim'")
    return value


def _optional_force(r: _Reader) -> float | None:
    value = r.number("max_force_n", 5.0, lo=0.0)
    return None if value == 0 else value


def _extrapolation_passes(r: _Reader) -> int | None:
    """``extrapolation_passes``: an integer >= 1 (1 = seed 000 eq. 6.15 once) or "all" (None: repeat until every
    cell is filled)."""
    value = r.get("extrapolation_passes", (int, str), 1)
    if isinstance(value, str):
        if value != "all":
            raise r.err("extrapolation_passes", f'expected an integer >= 1 or "all", got {value!r}')
        return None
    if value < 1:
        raise r.err("extrapolation_passes", f'must be >= 1 (or "all"), got {value}')
    return value


def _resolve(base: Path, value: str) -> Path:
    p = Path(value)
    if p.is_absolute() or p.exists():
        return p
    return base / p if (base / p).exists() else base.parent / p


def _material(r: _Reader, key: str, materials: dict[str, MaterialEntry], default: Any = _REQUIRED) -> Material:
    name = r.get(key, str, default)
    if name not in materials:
        raise r.err(key, f"unknown material {name!r}; defined materials: {', '.join(materials)}")
    return materials[name].material


def _object(r: _Reader, materials: dict[str, MaterialEntry], base: Path) -> ObjectEntry:
    name = r.get("name", str)
    shape = r.choice("shape", ("box", "cylinder", "mesh"), "box")
    count = {"box": 3, "cylinder": 2, "mesh": 3}[shape]
    size = tuple(v * 1e-3 for v in r.numbers("size_mm", count, positive=True))
    position = tuple(v * 1e-3 for v in r.numbers("position_mm", 2, (0.0, 0.0)))
    bulk = _material(r, "material", materials)
    mesh = r.get("mesh", str, "")
    layers = []
    for lr in r.subs("layers"):
        thickness = lr.number("thickness_mm", lo=0.0, lo_open=True) * 1e-3
        layers.append(Layer(_material(lr, "material", materials), thickness))
        lr.finish()
    inclusions = []
    for ir in r.subs("inclusions"):
        ishape = ir.choice("shape", ("sphere", "box", "column"))
        icount = {"sphere": 1, "box": 3, "column": 2}[ishape]
        centre = ir.numbers("center_mm", (2, 3))
        centre3 = (centre[0] * 1e-3, centre[1] * 1e-3, (centre[2] if len(centre) == 3 else 0.0) * 1e-3)
        inclusions.append(Inclusion(_material(ir, "material", materials), ishape, centre3,
                                    tuple(v * 1e-3 for v in ir.numbers("size_mm", icount, positive=True))))
        ir.finish()
    material_map = None
    map_path = r.get("material_map", str, "")
    if map_path:
        from palpate.core.world.haptic_material import HapticMaterialMap

        folder = _resolve(base, map_path)
        hm = HapticMaterialMap.read(folder)
        unknown = [m for m in hm.materials if m not in materials]
        if unknown:
            raise r.err("material_map", f"{folder} names materials {unknown} that the scenario does not define")
        material_map = hm
    regions = []
    for i, cell in enumerate(r.get("regions", list, [])):
        if not (isinstance(cell, list) and len(cell) == 2 and all(isinstance(c, int) and c >= 1 for c in cell)):
            raise r.err(f"regions[{i}]", f"expected a 1-based [column, row] pair of integers, got {cell!r}")
        regions.append((cell[0], cell[1]))
    grid_origin = r.numbers("grid_origin_mm", 2, None)
    grid_shape = r.get("grid_cells", list, None)
    if grid_shape is not None and not (len(grid_shape) == 2 and all(isinstance(v, int) and v > 0 for v in grid_shape)):
        raise r.err("grid_cells", f"expected [columns, rows] positive integers, got {grid_shape!r}")
    r.finish()
    try:
        map_materials = tuple(materials[n].material for n in material_map.materials) if material_map else ()
        spec = ObjectSpec(name, shape, size, position, bulk, tuple(layers), tuple(inclusions),
                          mesh_path=str(_resolve(base, mesh)) if mesh else None, material_map=material_map,
                          map_materials=map_materials)
    except ValidationError as exc:
        raise ValidationError(f"{r.file}: {r.path}: {exc}") from None
    return ObjectEntry(spec, tuple(regions),
                       tuple(v * 1e-3 for v in grid_origin) if grid_origin else None,
                       tuple(grid_shape) if grid_shape else None)
