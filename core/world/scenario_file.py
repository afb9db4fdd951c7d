"""Scenario files (TOML): what to build, what to explore, what to report — validated on load.

Loading never executes code: the file is parsed with ``tomllib`` and every key is checked against the schema
below. Unknown keys are errors, not ignored. An error names the file, the key path and what was expected, e.g.
``scenarios/x.toml: objects[1].size_mm: expected 3 numbers for shape 'box', got 2``.

Keys carry their unit in their name (``young_kpa``, ``size_mm``, ``speed_mm_s``); the loader converts to SI.
Names of policies, objectives, map kinds and actuator kinds come from the modules that implement them.
See ``scenarios/README.md`` for the full schema with an example of every table.
"""

from __future__ import annotations

from pathlib import Path

from palpate.core import limits, plugins
from palpate.core.errors import ValidationError
from palpate.core.files import read_toml
from palpate.core.mapping.calibration import DEFAULT_CALIBRATION, MapCalibration
from palpate.core.mapping.geometry import MAP_KINDS
from palpate.core.names import check_name, unique_stems
from palpate.core.perception.memory import MIN_SAMPLES
from palpate.core.planning.info_gain import OBJECTIVES
from palpate.core.planning.registry import policy_names
from palpate.core.world.actuator_kinds import SIM, actuator_names, load_actuator_kind, owner_of
from palpate.core.world.scenario import (
    ActuatorSpec,
    ExplorationSpec,
    MaterialEntry,
    OutputSpec,
    Scenario,
    TrainingSpec,
)
from palpate.core.world.scenario_tables import (
    MAX_SIZE_MM,
    extrapolation_passes,
    object_entry,
    optional_force,
    realism_spec,
    training_source,
)
from palpate.core.world.scene import FingertipSpec, Material, PoseSensorSpec, TaxelSensorSpec
from palpate.core.world.table_reader import REQUIRED, TableReader, resolve_path
from palpate.core.world.workspace import object_geometry

FIDELITIES = ("analytic", "bem", "rigid", "flex", "auto")
VARIABILITY = ("human", "robot")

# Physically plausible ranges, checked at load so that an absurd value is named here and not met later as a
# simulation that cannot be resolved (young_kpa = 1e300 asked for "a timestep of at most 0 s").
#: Young's modulus, kPa: from the softest gels (1 Pa) to 1 GPa, far stiffer than anything a fingertip can indent.
MIN_YOUNG_KPA, MAX_YOUNG_KPA = 1e-3, 1e6
#: Fingertip, sensel, depth and noise lengths, mm.
MAX_TOOL_MM = 100.0
#: Smallest map cell, mm.
MIN_CELL_MM = 0.1
#: Sensor rates, Hz.
MIN_RATE_HZ, MAX_RATE_HZ = 1.0, 1e5
#: Sensor clock offsets, s.
MAX_OFFSET_S = 3600.0
#: Press speed, mm/s.
MAX_SPEED_MM_S = 1000.0
#: Presses per material, per region, per object.
MAX_PRESSES = 100_000
#: Sensels along one side of the pad (the product is bounded by the limit ``taxels``).
MAX_PAD_SIDE = 1024
#: Largest seed (numpy's SeedSequence takes any integer; 128 bits are plenty).
MAX_SEED = 2**128 - 1


def load_scenario(path: str | Path) -> Scenario:
    """Read and validate a scenario file. Raises ValidationError naming the file and key on any problem."""
    p = Path(path)
    raw = read_toml(p, "scenario file")
    return parse_scenario(raw, str(p), base_dir=p.parent)


def parse_scenario(raw: dict, file: str = "<scenario>", base_dir: Path | None = None) -> Scenario:
    """Validate a scenario given as a parsed TOML dictionary (see :func:`load_scenario`)."""
    base = base_dir or Path.cwd()
    top = TableReader(file, raw, "")
    head = top.sub("scenario", required=True)
    name = check_name(head.get("name", str), f"{file}: scenario.name")
    description = head.get("description", str, "")
    seed = head.integer("seed", 0, lo=0, hi=MAX_SEED)
    fidelity = head.choice("fidelity", FIDELITIES, "auto")
    tolerance = head.number("tolerance_pct", 5.0, lo=0.0, lo_open=True, hi=99.0) / 100.0
    flex_iterations = head.integer("flex_iterations", None, lo=1, hi=100_000)
    head.finish()

    materials: dict[str, MaterialEntry] = {}
    for r in top.subs("materials"):
        mname = check_name(r.get("name", str), f"{file}: {r.path}.name")
        if mname in materials:
            raise r.err("name", f"duplicate material name {mname!r}")
        mat = Material(
            name=mname,
            young=r.number("young_kpa", lo=MIN_YOUNG_KPA, hi=MAX_YOUNG_KPA) * 1e3,
            poisson=r.number("poisson", 0.3, lo=0.0, hi=0.4999),
            damping=r.number("damping_s", 0.0, lo=0.0, hi=10.0),
        )
        reference = r.get("reference", bool, True)
        like = r.get("like", str, mname if reference else REQUIRED)
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
        radius=ft.number("radius_mm", d_ft.radius * 1e3, lo=0.0, lo_open=True, hi=MAX_TOOL_MM) * 1e-3,
        rows=ft.integer("rows", d_ft.rows, lo=1, hi=MAX_PAD_SIDE),
        cols=ft.integer("cols", d_ft.cols, lo=1, hi=MAX_PAD_SIDE),
        pitch=ft.number("pitch_mm", d_ft.pitch * 1e3, lo=0.0, lo_open=True, hi=MAX_TOOL_MM) * 1e-3,
        sensel_size=ft.number("sensel_mm", d_ft.sensel_size * 1e3, lo=0.0, lo_open=True, hi=MAX_TOOL_MM) * 1e-3,
    )
    limits.check("taxels", f"{file}: fingertip.rows x fingertip.cols", fingertip.rows * fingertip.cols)
    ft.finish()
    sensors = top.sub("sensors")
    tx = sensors.sub("taxels")
    d_tx = TaxelSensorSpec()
    taxels = TaxelSensorSpec(
        rate=tx.number("rate_hz", d_tx.rate, lo=MIN_RATE_HZ, hi=MAX_RATE_HZ),
        gain=tx.number("gain_counts_per_kpa", d_tx.gain * 1e3, lo=0.0, lo_open=True, hi=1e4) * 1e-3,
        noise_std=tx.number("noise_counts", d_tx.noise_std, lo=0.0, hi=255.0),
        threshold=tx.integer("threshold_counts", d_tx.threshold, lo=0, hi=255),
        clock_offset=tx.number("clock_offset_s", d_tx.clock_offset, lo=-MAX_OFFSET_S, hi=MAX_OFFSET_S),
    )
    tx.finish()
    po = sensors.sub("pose")
    d_po = PoseSensorSpec()
    pose = PoseSensorSpec(
        rate=po.number("rate_hz", d_po.rate, lo=MIN_RATE_HZ, hi=MAX_RATE_HZ),
        noise_std=po.number("noise_mm", d_po.noise_std * 1e3, lo=0.0, hi=MAX_TOOL_MM) * 1e-3,
        clock_offset=po.number("clock_offset_s", d_po.clock_offset, lo=-MAX_OFFSET_S, hi=MAX_OFFSET_S),
        jitter=po.number("jitter_ms", d_po.jitter * 1e3, lo=0.0, hi=1000.0) * 1e-3,
    )
    po.finish()
    sensors.finish()

    tr = top.sub("training")
    memory = tr.get("memory", str, "")
    # a material's Gaussian needs MIN_SAMPLES presses and leave-one-out holds one more out
    training = TrainingSpec(
        presses_per_material=tr.integer("presses_per_material", 10, lo=MIN_SAMPLES + 1, hi=MAX_PRESSES),
        depth=tr.number("depth_mm", 4.0, lo=0.0, lo_open=True, hi=MAX_TOOL_MM) * 1e-3,
        max_force=optional_force(tr),
        speed=tr.number("speed_mm_s", 10.0, lo=0.0, lo_open=True, hi=MAX_SPEED_MM_S) * 1e-3,
        variability=tr.choice("variability", VARIABILITY, "human"),
        memory=resolve_path(base, memory) if memory else None,
        source=training_source(tr),
        classifier=tr.choice("classifier", tuple(plugins.names(plugins.CLASSIFIERS)), "haptic_memory"),
        features=tr.choice("features", tuple(plugins.names(plugins.FEATURES)), "power_law"),
    )
    if training.memory is not None and (training.classifier, training.features) != ("haptic_memory", "power_law"):
        raise tr.err("memory", "a trained memory file is a haptic memory over [n1, n2, a1, a2]; leave out "
                     "classifier and features, or leave out memory to train the classifier")
    tr.finish()

    ex = top.sub("exploration")
    stop = ex.number("stop_mean_entropy", None, lo=0.0)
    exploration = ExplorationSpec(
        map=ex.choice("map", MAP_KINDS, "grid2d"),
        cell_size=ex.number("cell_mm", 10.0, lo=MIN_CELL_MM, hi=MAX_SIZE_MM) * 1e-3,
        voxel_depth=ex.number("voxel_depth_mm", 15.0, lo=0.0, lo_open=True, hi=MAX_SIZE_MM) * 1e-3,
        policy=ex.choice("policy", tuple(policy_names()), "predefined"),
        budget=ex.integer("budget", 10, lo=1, hi=MAX_PRESSES),
        presses_per_region=ex.integer("presses_per_region", 2, lo=1, hi=MAX_PRESSES),
        depth=ex.number("depth_mm", 4.0, lo=0.0, lo_open=True, hi=MAX_TOOL_MM) * 1e-3,
        max_force=optional_force(ex),
        speed=ex.number("speed_mm_s", 10.0, lo=0.0, lo_open=True, hi=MAX_SPEED_MM_S) * 1e-3,
        variability=ex.choice("variability", VARIABILITY, "human"),
        entropy_base=ex.number("entropy_base", 10.0, lo=1.0, lo_open=True, hi=1e6),
        stop_mean_entropy=stop,
        stop_max_entropy=ex.number("stop_max_entropy", None, lo=0.0),
        stop_min_gain=ex.number("stop_min_gain", None, lo=0.0),
        travel_cost_per_mm=ex.number("travel_cost_per_mm", 0.0, lo=0.0, hi=1e6),
        extrapolation_passes=extrapolation_passes(ex),
        objective=ex.choice("objective", OBJECTIVES, "accuracy"),
        feature_size=None if "feature_size_mm" not in ex.table else ex.number(
            "feature_size_mm", lo=0.0, lo_open=True, hi=MAX_SIZE_MM) * 1e-3,
        calibration=MapCalibration(**{key: ex.number(key, getattr(DEFAULT_CALIBRATION, key), lo=0.0, lo_open=True,
                                                     hi=1.0) for key in DEFAULT_CALIBRATION.to_dict()}),
        voxel_lateral=ex.get("lateral_extrapolation", bool, False),
    )
    if exploration.voxel_lateral and exploration.map != "voxel":
        raise ex.err("lateral_extrapolation", "fills voxels from their neighbours in a layer; map is "
                     f"{exploration.map!r} (grid2d maps always extrapolate laterally: extrapolation_passes)")
    if exploration.policy == "boundary" and exploration.map != "grid2d":
        raise ex.err("policy", f"the boundary policy plans on a fine 2-D map; map is {exploration.map!r}")
    if exploration.stop_min_gain is not None and exploration.policy != "info_gain":
        raise ex.err("stop_min_gain", f"only the info_gain policy predicts a gain; policy is {exploration.policy!r}")
    for key in ("objective", "feature_size_mm"):
        if key in ex.table and exploration.policy != "info_gain":
            raise ex.err(key, f"only the info_gain policy uses it; policy is {exploration.policy!r}")
    if exploration.extrapolation_passes != 1 and exploration.map != "grid2d":
        raise ex.err("extrapolation_passes", "iterated eq. 6.15 extrapolation is a grid2d post-processing; map is "
                     f"{exploration.map!r} (leave the key out)")
    if exploration.travel_cost_per_mm > 0 and exploration.policy not in ("max_entropy", "info_gain", "boundary"):
        raise ex.err("travel_cost_per_mm", "only max_entropy, info_gain and boundary weigh travel; policy is "
                     f"{exploration.policy!r}")
    ex.finish()

    objects = []
    seen_names: set[str] = set()
    for r in top.subs("objects"):
        objects.append(object_entry(r, materials, base))
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
        attainable_accuracy=out.get("attainable_accuracy", bool, False),
    )
    out.finish()
    actuator = _actuator(top.sub("actuator"), base)
    realism = realism_spec(top.sub("realism"), base)
    top.finish()
    unique_stems(materials, f"{file}: materials")
    unique_stems((o.spec.name for o in objects), f"{file}: objects")
    scenario = Scenario(name, Path(file) if file != "<scenario>" else None, description, seed, fidelity, materials,
                        fingertip, taxels, pose, training, exploration, tuple(objects), outputs, raw, actuator,
                        realism, fidelity_tolerance=tolerance,
                        flex_iterations=flex_iterations)
    for i, entry in enumerate(objects):
        try:
            object_geometry(scenario, entry)
        except ValidationError as exc:
            raise ValidationError(f"{file}: objects[{i}] ({entry.spec.name}): its map (size_mm or grid_cells over "
                                  f"exploration.cell_mm): {exc}") from None
    return scenario


def parse_actuator(table: dict, file: str = "<scenario>", base: Path | None = None) -> ActuatorSpec:
    """Validate an ``[actuator]`` table (already parsed from TOML); relative paths resolve against ``base``."""
    if not isinstance(table, dict):
        raise ValidationError(f"{file}: actuator: expected a table, got {table!r}")
    return _actuator(TableReader(file, table, "actuator"), base or Path.cwd())


def _actuator(r: TableReader, base: Path) -> ActuatorSpec:
    """``[actuator]``: ``kind`` from the registry, then the kind's own keys, parsed by the kind."""
    name = r.choice("kind", actuator_names(), SIM)
    kind = None if name == SIM else load_actuator_kind(name)
    own = () if kind is None else kind.keys
    for key in r.table:
        if key != "kind" and key not in own:
            owner = owner_of(key, but=name)
            if owner is not None:
                raise r.err(key, f"is a key of kind {owner!r}, but kind is {name!r}")
    options = None if kind is None else kind.parse(r, base)
    r.finish()
    return ActuatorSpec(name, options)
