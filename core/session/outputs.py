"""A run's files besides its summary: map files, haptic-material exports and figures."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from palpate.core.io import figures as fig
from palpate.core.io.exports import export_haptic_material
from palpate.core.names import file_stem, inside
from palpate.core.perception.press import PressResult
from palpate.core.session.explore import ObjectResult
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


def progress_series(obj: ObjectResult) -> fig.ProgressSeries:
    """An object's mean entropy and explored-cell accuracy against presses, for the progress figure."""
    return fig.ProgressSeries(
        obj.name, np.array([s.k for s in obj.steps]), np.array([s.mean_entropy for s in obj.steps]),
        np.array([np.nan if s.accuracy_explored is None else s.accuracy_explored for s in obj.steps]))


def write_figures(folder: Path, training: Mapping[str, Sequence[PressResult]], objects: Sequence[ObjectResult],
                  render_3d: bool = True) -> list[Path]:
    """Every figure of a run; returns the written paths."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    if training:
        paths.append(fig.plot_training_series(folder / "training_series.png", training))
        paths.append(fig.plot_interaction_profiles(folder / "interaction_profiles.png", training))
    for obj in objects:
        name, materials = obj.name, list(obj.geometry.materials)
        path = {k: inside(folder, folder / f"{file_stem(name)}_{k}.png")
                for k in ("map", "entropy", "columns", "voxels_3d")}
        if not obj.geometry.voxel:
            paths.append(fig.plot_map_snapshots(path["map"], name, obj.snapshots, obj.geometry, obj.truth))
            paths.append(fig.plot_entropy(path["entropy"], name, obj.snapshots[-2].probabilities,
                                          obj.snapshots[-1].probabilities, obj.geometry))
        else:
            paths.append(fig.plot_voxel_columns(path["columns"], name, obj.grid, obj.post, materials))
            if render_3d:
                p = fig.render_voxels_3d(path["voxels_3d"], obj.post, obj.grid.cell_size)
                if p is not None:
                    paths.append(p)
    paths.append(fig.plot_progress(folder / "exploration_progress.png", [progress_series(o) for o in objects]))
    return paths
