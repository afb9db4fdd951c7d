"""A run's files besides its summary: map files, haptic-material exports and figures."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from palpate.core.io import figures as fig
from palpate.core.io.exports import export_haptic_material
from palpate.core.perception.press import PressResult
from palpate.core.session.explore import ObjectResult
from palpate.core.session.progress import Progress
from palpate.core.world.scenario import Scenario


def write_maps(out: Path, objects: Sequence[ObjectResult], scenario: Scenario) -> None:
    """``maps/<object>.npz`` (+ ``_postprocessed``) with JSON sidecars, and the haptic-material export per object."""
    (out / "maps").mkdir(exist_ok=True)
    for obj in objects:
        obj.grid.save(out / "maps" / f"{obj.name}.npz")
        obj.post.save(out / "maps" / f"{obj.name}_postprocessed.npz")
        if scenario.outputs.haptic_material and not obj.geometry.voxel:
            export_haptic_material(obj.post, obj.grid, obj.results, scenario, out / "haptic_materials" / obj.name,
                                   obj.name)


def progress_series(obj: ObjectResult) -> fig.ProgressSeries:
    """An object's mean entropy and explored-cell accuracy against presses, for the progress figure."""
    return fig.ProgressSeries(
        obj.name, np.array([s.k for s in obj.steps]), np.array([s.mean_entropy for s in obj.steps]),
        np.array([np.nan if s.accuracy_explored is None else s.accuracy_explored for s in obj.steps]))


def write_figures(folder: Path, training: Mapping[str, Sequence[PressResult]], objects: Sequence[ObjectResult],
                  render_3d: bool = True, progress: Progress | None = None) -> list[Path]:
    """Every figure of a run, with a progress bar per figure; returns the written paths."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    jobs: list = []  # (file name, draw(path) -> path or None)
    if training:
        jobs.append(("training_series.png", lambda p: fig.plot_training_series(p, training)))
        jobs.append(("interaction_profiles.png", lambda p: fig.plot_interaction_profiles(p, training)))
    for obj in objects:
        name, materials = obj.name, list(obj.geometry.materials)
        if not obj.geometry.voxel:
            jobs.append((f"{name}_map.png", lambda p, o=obj: fig.plot_map_snapshots(p, o.name, o.snapshots,
                                                                                   o.geometry, o.truth)))
            jobs.append((f"{name}_entropy.png", lambda p, o=obj: fig.plot_entropy(
                p, o.name, o.snapshots[-2].probabilities, o.snapshots[-1].probabilities, o.geometry)))
        else:
            jobs.append((f"{name}_columns.png", lambda p, o=obj, m=materials: fig.plot_voxel_columns(
                p, o.name, o.grid, o.post, m)))
            if render_3d:
                jobs.append((f"{name}_voxels_3d.png", lambda p, o=obj, m=materials: fig.render_voxels_3d(
                    p, o.post, o.grid.cell_size, o.name, m)))
    series = [progress_series(o) for o in objects]
    jobs.append(("exploration_progress.png", lambda p: fig.plot_progress(p, series)))
    progress = progress or Progress(enabled=False)
    progress.start("drawing figures", len(jobs))
    paths = []
    for i, (file, draw) in enumerate(jobs):
        path = draw(folder / file)
        if path is not None:
            paths.append(path)
        elif file.endswith("_voxels_3d.png"):
            progress.message(f"{file} skipped: the 3-D render needs the 'viz' extra (pip install 'palpate[viz]')")
        progress.update(i + 1, file)
    return paths
