"""The run loop: train a haptic memory, explore each object, keep its map, and write every output.

The loop only talks to a *source* (:mod:`palpate.core.session.sources`): it asks for a press at a target and gets
raw taxel and pose streams back. The simulation, a replayed recording or a robot finger are interchangeable, so
what this module computes on a simulation is what it computes on hardware.

Stages (each timed in ``summary["timing"]``, wall seconds, and ``summary["cpu"]``, this process's CPU seconds):

1. training (:mod:`~palpate.core.session.training`): press each reference material ``presses_per_material``
   times, segment, fit the 3/2-power laws, fit the haptic memory, leave-one-out cross-validation (skipped when the
   scenario names a trained memory);
2. exploration (:mod:`~palpate.core.session.explore`), per object: a policy picks cells, each press's fit gives a
   posterior over the reference materials that updates the map (seed 001 eq. 2); entropy and accuracy against
   ground truth are kept after every press;
3. post-processing: entropy-weighted extrapolation (2-D: eq. 6.15; voxels: vertical extrapolation then
   continuity verification);
4. outputs: summary.json, maps (NPZ + JSON), memory.json, figures, a haptic-material export per object.
"""

from __future__ import annotations

import dataclasses
import json
import time
from pathlib import Path

import numpy as np

from palpate.core import files, plugins
from palpate.core.boundary.templates import Pad
from palpate.core.errors import ValidationError
from palpate.core.io.realism_figures import compared_materials, plot_sim_vs_real
from palpate.core.names import file_stem, inside
from palpate.core.perception.classifier_memory import HAPTIC_MEMORY, ClassifierMemory, classifier_for
from palpate.core.perception.feature_extractors import extractor_name
from palpate.core.perception.layered_memory import train_layered_memory
from palpate.core.perception.memory import HapticMemory
from palpate.core.perception.param_stats import table_from_csv, table_from_fits
from palpate.core.session.actuators import open_actuators
from palpate.core.session.boundaries import (
    EDGE_KEY,
    NOISE_KEY,
    boundary_reader,
    export_fine_map,
    lump_evidence,
    noise_metadata,
    object_fine_map,
    save_fine_map,
    save_lump_layer,
    training_moduli,
)
from palpate.core.session.ceiling import Ceiling, attainable_accuracy, ceiling_summary, is_full_raster
from palpate.core.session.explore import MapPostprocessing, ObjectResult, explore_object
from palpate.core.session.figure_jobs import (
    FigureDrawer,
    FigureJob,
    fine_map_job,
    lump_layer_job,
    object_jobs,
    progress_job,
    training_jobs,
)
from palpate.core.session.output_guard import check_output_file, prepare_output_folder
from palpate.core.session.outputs import write_maps
from palpate.core.session.predictive import predictive_report
from palpate.core.session.press_log import PressLog
from palpate.core.session.progress import Progress
from palpate.core.session.report import (
    SUMMARY_FORMAT,
    SUMMARY_VERSION,
    assert_finite,
    fit_summary,
    object_summary,
    run_calibration,
    saturation,
    saturation_warning,
    solver_warning,
    solver_warnings,
)
from palpate.core.session.report import versions as _versions
from palpate.core.session.sim_to_real import sim_to_real_summary
from palpate.core.session.sources import PressTarget, scenario_source_maker
from palpate.core.session.training import TrainingResult, dropped_message, run_seeds, train_memory
from palpate.core.world.scenario import ObjectEntry, Scenario
from palpate.core.world.workspace import contact_radius, map_geometries


def run_scenario(scenario: Scenario, out_dir: str | Path, *, progress: Progress | None = None,
                 source: str | None = None, record: str | Path | None = None, force: bool = False,
                 live=None, classifier: ClassifierMemory | None = None) -> dict:
    """Run a scenario end to end and write its outputs into ``out_dir``. Returns the summary (also summary.json).

    ``source`` names the registered simulated source that trains the memory and, with ``[actuator] kind = "sim"``,
    explores (default: ``training.source``); another actuator kind explores through
    :func:`palpate.core.session.actuators.open_actuators`. With ``record``, every press's raw streams (and ground
    truth) go to that MCAP file, annotated so that ``palpate replay`` rebuilds the same maps; with ``live`` (a
    :class:`~palpate.core.io.live.LiveServer`) the same messages, and the map after every press, are served live.

    With ``classifier`` (an unfitted :class:`~palpate.core.perception.classifier_memory.ClassifierMemory`: any
    classifier with ``predict_proba`` and its feature extractor), that classifier is trained on the training presses
    and judges every press instead of the haptic memory (2-D maps; not with ``info_gain``, which predicts presses
    from the haptic memory's Gaussians, nor with a trained memory file).

    ``out_dir`` must be new, empty or an earlier run's folder; an earlier run (and an existing ``record`` file) is
    replaced only with ``force`` (:mod:`palpate.core.session.output_guard`). No input is ever overwritten.
    """
    progress = progress or Progress(enabled=False)
    origins = {"policy": plugins.resolve(plugins.POLICIES, scenario.exploration.policy).origin}
    if classifier is None:
        classifier, found = classifier_for(scenario.training.classifier, scenario.training.features,
                                           scenario.references)
        origins.update(found)
    else:
        origins.update(classifier="given in Python", features="given in Python")
    if classifier is not None:
        check_classifier_fits(scenario, classifier)
    inputs = scenario_inputs(scenario)
    if record is not None:
        check_output_file(record, inputs=inputs, force=force, option="--record", outputs=Path(out_dir), kind="run")
    own = [Path(record).name] if record is not None and Path(record).resolve().parent == Path(out_dir).resolve() \
        else []
    out = prepare_output_folder(out_dir, "run", force=force, inputs=inputs, extra=own)
    seeds = run_seeds(scenario)
    source = source or scenario.training.source
    kind = scenario.actuator.kind
    geometries = map_geometries(scenario)
    with open_actuators(scenario, out, geometries, lambda: scenario_source_maker(scenario, source)) as makers:
        log = PressLog(Path(record) if record else None,
                       {"scenario": {"name": scenario.name, "file": str(scenario.path) if scenario.path else None,
                                     "seed": scenario.seed, "fidelity": scenario.fidelity},
                        "sources": [source] if kind == "sim" else [source, kind],
                        "maps": {name: g.to_dict() for name, g in geometries.items()},
                        "map_calibration": scenario.exploration.calibration.to_dict(),
                        "map_postprocessing": MapPostprocessing.of(scenario.exploration).to_dict(),
                        NOISE_KEY: noise_metadata(scenario), EDGE_KEY: contact_radius(scenario)}, live=live,
                       # the tracked point is the fingertip sphere's centre; the pad lies at its bottom
                       pad_offset=(0.0, 0.0, -scenario.fingertip.radius))
        try:
            return _run(scenario, out, progress, *makers, seeds, log, classifier, origins)
        finally:
            log.close()


def scenario_inputs(scenario: Scenario) -> list[Path]:
    """The files a run of ``scenario`` reads (the scenario, a trained memory, meshes, actuator files, a realism
    profile file and the real per-press table)."""
    paths = [scenario.path, scenario.training.memory, *(Path(e.spec.mesh_path) for e in scenario.objects
                                                        if e.spec.mesh_path), scenario.realism.real_params]
    if scenario.realism.profile.endswith(".toml"):
        paths.append(Path(scenario.realism.profile))
    options = scenario.actuator.options
    if dataclasses.is_dataclass(options):
        paths += [v for f in dataclasses.fields(options) if isinstance(v := getattr(options, f.name), Path)]
    return [p for p in paths if p is not None]


def check_classifier_fits(scenario: Scenario, classifier: ClassifierMemory) -> None:
    """ValidationError, before any work, where a scenario cannot be judged by a classifier other than the haptic
    memory: a voxel map (its layers are judged by per-layer haptic memories), the info_gain and boundary policies
    (they predict presses from the memory's Gaussians), a trained memory file (it is a haptic memory)."""
    where = f"{scenario.path or 'scenario'}: classifier {classifier.label!r}"
    if scenario.exploration.map == "voxel":
        raise ValidationError(f"{where}: voxel maps judge each layer with haptic memories; use map = \"grid2d\" "
                              "or the haptic memory")
    if scenario.exploration.policy in ("info_gain", "boundary"):
        raise ValidationError(f"{where}: exploration.policy {scenario.exploration.policy} predicts presses from the "
                              "haptic memory's Gaussians; choose another policy or the haptic memory")
    if scenario.training.memory is not None:
        raise ValidationError(f"{where}: training.memory names a trained haptic memory; leave it out to train the "
                              "classifier")


def _memory(scenario: Scenario, make_source, seeds, progress: Progress, log: PressLog,
            classifier: ClassifierMemory | None = None, reader=None) -> tuple[HapticMemory | ClassifierMemory,
                                                                               TrainingResult | None]:
    """The scenario's trained memory file, or a memory (or ``classifier``) trained now (with its cross-validation
    and presses)."""
    if scenario.training.memory is None:
        training = train_memory(scenario, make_source, seeds[4:], progress, log, classifier, reader)
        return training.memory, training
    memory = HapticMemory.load(scenario.training.memory)
    if list(memory.materials) != list(scenario.references):
        raise ValidationError(f"{scenario.training.memory}: memory materials {memory.materials} differ from the "
                              f"scenario's reference materials {scenario.references}")
    return memory, None


def _run(scenario: Scenario, out: Path, progress: Progress, make_source, make_actuator, seeds,
         log: PressLog, classifier: ClassifierMemory | None, origins: dict[str, str]) -> dict:
    out_cfg = scenario.outputs
    preload = ("pyvista",) if out_cfg.render_3d and scenario.exploration.map == "voxel" else ()
    with FigureDrawer(out / "figures", background=out_cfg.figures, preload=preload) as drawer:
        return _stages(scenario, out, progress, make_source, make_actuator, seeds, log, drawer, classifier, origins)


def _stages(scenario: Scenario, out: Path, progress: Progress, make_source, make_actuator, seeds, log: PressLog,
            drawer: FigureDrawer, classifier: ClassifierMemory | None, origins: dict[str, str]) -> dict:
    timing: dict[str, float] = {}
    cpu: dict[str, float] = {}  # this process's CPU seconds per stage (the figures are drawn in another process)
    draw = scenario.outputs.figures
    t0, c0 = time.perf_counter(), time.process_time()
    reader, no_reader = boundary_reader(scenario)
    memory, training = _memory(scenario, make_source, seeds, progress, log, classifier, reader)
    memory.save(out / "memory.json")
    layers = None
    ex = scenario.exploration
    if ex.map == "voxel" and training is not None:
        nz = max(1, int(round(ex.voxel_depth / ex.cell_size)))
        layers = train_layered_memory(memory, training.presses, ex.cell_size, nz)
        layers.save(out / "memory_layers.json")
    presses = {} if training is None else training.presses
    if draw:
        drawer.submit(training_jobs(presses))
    sim_to_real = None
    if training is not None and scenario.realism.real_params is not None:
        real = table_from_csv(scenario.realism.real_params)
        sim = table_from_fits({name: [r.fit for r in rs] for name, rs in presses.items()})
        sim_to_real = sim_to_real_summary(sim, real, scenario.realism.real_params)
        if scenario.realism.predictive_sessions:
            sim_to_real["predictive_check"] = predictive_report(scenario, make_source, real, progress)
        if draw and compared_materials(sim, real):
            drawer.submit([FigureJob("sim_vs_real.png", plot_sim_vs_real, (sim, real, memory.ddof))])
    timing["training_s"] = time.perf_counter() - t0
    cpu["training_s"] = time.process_time() - c0
    if training is not None:
        _warn(progress, dropped_message(training.dropped, scenario.training.presses_per_material))
        for name, rs in training.presses.items():
            _warn(progress, saturation_warning(f"training {name}", saturation(rs)))
            _warn(progress, solver_warning(f"training {name}", solver_warnings(rs)))

    t0, c0 = time.perf_counter(), time.process_time()
    if scenario.actuator.kind == "sim":
        for entry in scenario.objects:
            _say_fidelity(entry, scenario, make_source, progress)
    objects: list[ObjectResult] = []
    moduli = None if training is None else training_moduli(training.readings)
    lumps = lump_evidence(None if training is None else training.presses, Pad.of(scenario.fingertip))
    fines = []
    for i, entry in enumerate(scenario.objects):
        seed_i = int(seeds[4 + len(scenario.references) + i])
        objects.append(explore_object(scenario, entry, memory, make_actuator, seed_i, progress, log, layers,
                                      reader, moduli))
        fines.append(None if reader is None else object_fine_map(objects[-1], entry, scenario, moduli, lumps))
        if fines[-1] is not None:
            log.show_fine_map(objects[-1].name, fines[-1].fine, entry.spec.height)
            g = objects[-1].geometry
            log.show_spots(objects[-1].name, fines[-1].summary.get("stiffness_anomalies"), entry.spec.height,
                           (g.cell_size, g.shape[2] * g.cell_size) if g.voxel else None)
        _warn(progress, saturation_warning(entry.spec.name, saturation([s.result for s in objects[-1].steps])))
        _warn(progress, solver_warning(entry.spec.name, solver_warnings([s.result for s in objects[-1].steps])))
        if draw:
            drawer.submit(object_jobs(objects[-1], scenario.outputs.render_3d))
    if draw:
        drawer.submit([progress_job(objects)])
    log.close()  # the recording is complete on disk before maps and figures are written
    timing["exploration_s"] = time.perf_counter() - t0
    cpu["exploration_s"] = time.process_time() - c0

    t0, c0 = time.perf_counter(), time.process_time()
    ceilings: list[Ceiling | None] = [None] * len(objects)
    if scenario.actuator.kind == "sim":
        for i, (entry, obj) in enumerate(zip(scenario.objects, objects, strict=True)):
            if not (scenario.outputs.attainable_accuracy or is_full_raster(obj)):
                continue  # opt-in: a press on every cell more (a full raster is its own ceiling, free)
            ceilings[i] = attainable_accuracy(scenario, entry, memory, make_source, int(seeds[3]) + i, progress, obj,
                                              layers)
    timing["attainable_accuracy_s"] = time.perf_counter() - t0
    cpu["attainable_accuracy_s"] = time.process_time() - c0

    t0, c0 = time.perf_counter(), time.process_time()
    write_maps(out, objects, scenario)
    for obj, fine in zip(objects, fines, strict=True):
        if fine is not None:
            save_fine_map(inside(out, out / "maps" / f"{file_stem(obj.name)}_fine.npz"), fine.fine)
            if fine.lumps is not None:
                save_lump_layer(inside(out, out / "maps" / f"{file_stem(obj.name)}_lumps.npz"), fine.lumps)
            if scenario.outputs.haptic_material:
                export_fine_map(inside(out, out / "haptic_materials" / f"{file_stem(obj.name)}_fine"), fine.fine,
                                obj.name, scenario)
            if draw:
                drawer.submit([fine_map_job(obj, fine.fine, fine.truth, fine.summary.get("stiffness_anomalies"))])
                if fine.lumps is not None and fine.lumps.lumps:
                    drawer.submit([lump_layer_job(obj, fine.lumps, fine.lumps_truth,
                                                  fine.summary.get("stiffness_anomalies"))])
    timing["maps_s"] = time.perf_counter() - t0
    cpu["maps_s"] = time.process_time() - c0

    # Most figures were drawn in the background while the run went on: this is the wait for the rest.
    t0, c0 = time.perf_counter(), time.process_time()
    figures = drawer.finish(progress) if draw else []
    timing["figures_s"] = time.perf_counter() - t0
    cpu["figures_s"] = time.process_time() - c0
    n_presses = (sum(len(rs) for rs in presses.values()) + sum(len(o.steps) for o in objects)
                 + sum(c.presses for c in ceilings if c is not None and not c.reused_run))
    press_cpu = cpu["training_s"] + cpu["exploration_s"] + cpu["attainable_accuracy_s"]

    crossval = None if training is None else training.crossval
    summary = {
        "format": SUMMARY_FORMAT,
        "version": SUMMARY_VERSION,
        "scenario": {"name": scenario.name, "file": str(scenario.path) if scenario.path else None,
                     "fidelity": scenario.fidelity, "fidelity_tolerance_pct": 100.0 * scenario.fidelity_tolerance,
                     # None: MuJoCo's default iteration limit (what the solver warnings were counted against)
                     "flex_iterations": scenario.flex_iterations,
                     "description": scenario.description},
        "actuator": scenario.actuator.kind,
        "seed": scenario.seed,
        "materials": list(scenario.references),
        "memory": {"file": "memory.json", "trained": scenario.training.memory is None},
        # the algorithms this run used, by the names they are registered under
        "algorithms": {"policy": ex.policy,
                       "classifier": HAPTIC_MEMORY if classifier is None else classifier.label,
                       "features": extractor_name(None if classifier is None else classifier.features),
                       "origins": origins},
        "crossval": None if crossval is None else {
            "confusion": np.asarray(crossval.confusion).tolist(),
            "mean_posterior": np.asarray(crossval.mean_posterior).tolist(),
            "accuracy": {m: float(np.asarray(crossval.confusion)[i, i]) for i, m in enumerate(scenario.references)},
        },
        "training": {name: [fit_summary(r.fit) for r in rs] for name, rs in presses.items()},
        # presses without a fit are left out of the memory and the tables: how many, per material
        "training_dropped": None if training is None else training.dropped,
        "training_saturation": {name: saturation(rs).to_dict() for name, rs in presses.items()},
        "training_solver_warnings": {name: solver_warnings(rs).to_dict() for name, rs in presses.items()},
        "realism": scenario.realism.profile,
        "sim_to_real": sim_to_real,
        "map_calibration": ex.calibration.to_dict(),
        "map_postprocessing": MapPostprocessing.of(ex).to_dict(),
        "objects": [object_summary(o) | {"attainable_accuracy": ceiling_summary(o, c),
                                         "fine_map": f.summary if f is not None else {"skipped": no_reader}}
                    for o, c, f in zip(objects, ceilings, fines, strict=True)],
        "calibration": run_calibration(objects),
        "figures": [str(Path(f).relative_to(out)) for f in figures],
        "timing": {k: round(v, 4) for k, v in timing.items()},
        "cpu": {k: round(v, 4) for k, v in cpu.items()} | {
            "presses": n_presses, "per_press_s": round(press_cpu / n_presses, 5) if n_presses else None},
        "versions": _versions(),
    }
    assert_finite(summary)
    files.write_text(out / "summary.json", json.dumps(summary, indent=2))
    return summary


def _warn(progress: Progress, message: str | None) -> None:
    if message:
        progress.message(message)


def _say_fidelity(entry: ObjectEntry, scenario: Scenario, make_source, progress: Progress) -> None:
    """Print which fidelity the source will use for an object, and why (the ``auto`` rule's reason)."""
    source = make_source((entry.spec,), 0, "robot")
    if not hasattr(source, "explain"):
        return
    ex = scenario.exploration
    x, y = entry.spec.position
    # the source's choice: its ``fidelity`` and the ``reason`` it gives (palpate.sim.validity.choice.Choice)
    choice = source.explain(PressTarget(x, y, depth=ex.depth, force=ex.max_force, speed=ex.speed))
    progress.message(f"fidelity {choice.fidelity}: {choice.reason}")


__all__ = ["run_scenario", "scenario_inputs"]
