"""A run's files besides its summary: map files, haptic-material exports and figures."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

from palpate.core.io.exports import export_haptic_material
from palpate.core.names import file_stem, inside
from palpate.core.perception.press import PressResult
from palpate.core.session.explore import ObjectResult
from palpate.core.session.figure_jobs import FigureDrawer, object_jobs, progress_job, training_jobs
from palpate.core.session.progress import Progress
from palpate.core.world.scenario import Scenario


def write_maps(out: Path, objects: Sequence[ObjectResult], scenario: Scenario) -> None:
    """``maps/<object>.npz`` (+ ``_postprocessed``) with JSON sidecars, and the haptic-material export per object
    (the object's name made a safe file stem, every path checked to lie inside ``out``)."""
    (out / "maps").mkdir(exist_ok=True)
    for obj in objects:
        stem = file_stem(obj.name)
        obj.grid.save(inside(out, out / "maps" / f"{stem}.npz"))
        obj.post.save(inside(out, out / "maps" / f"{stem}_postprocessed.npz"))
        if scenario.outputs.haptic_material and not obj.geometry.voxel:
            export_haptic_material(obj.post, obj.grid, obj.results, scenario,
                                   inside(out, out / "haptic_materials" / stem), obj.name)


def write_figures(folder: Path, training: Mapping[str, Sequence[PressResult]], objects: Sequence[ObjectResult],
                  render_3d: bool = True, progress: Progress | None = None) -> list[Path]:
    """Every figure of a run, drawn now in this process with a progress bar; returns the written paths. (A run
    draws the same figures in the background as their data become ready: :mod:`.figure_jobs`.)"""
    jobs = training_jobs(training)
    for obj in objects:
        jobs += object_jobs(obj, render_3d)
    jobs.append(progress_job(objects))
    with FigureDrawer(folder, background=False) as drawer:
        drawer.submit(jobs)
        return drawer.finish(progress)
