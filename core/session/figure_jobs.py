"""A run's figures as jobs, drawn while the run goes on.

Drawing is the one stage of a run that needs nothing but finished results, so each figure is handed to a
background process as soon as its data exist: the training figures after training, an object's maps after its
exploration, the progress plot after the last object. The background process imports matplotlib while training
runs and draws on the machine's other core, so by the time exploration ends most figures are on disk and the run
waits only for the last ones. With a single core (or ``background=False``) the same jobs are drawn in this process
when :meth:`FigureDrawer.finish` is called. Either way the files are identical.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from palpate.core.io import figure_worker, fine_figures
from palpate.core.io import figures as fig
from palpate.core.mapping.geometry import plane_probabilities
from palpate.core.names import file_stem, inside
from palpate.core.perception.press import PressResult
from palpate.core.session.explore import ObjectResult
from palpate.core.session.progress import Progress


@dataclass(frozen=True)
class FigureJob:
    """One figure: its file name and ``draw(path, *args) -> path or None`` (a module-level function, so the job can
    be sent to another process)."""

    file: str
    draw: Callable
    args: tuple


def training_jobs(training: Mapping[str, Sequence[PressResult]]) -> list[FigureJob]:
    """The training series and the interaction profiles (none without training presses)."""
    if not training:
        return []
    training = {name: list(results) for name, results in training.items()}
    return [FigureJob("training_series.png", fig.plot_training_series, (training,)),
            FigureJob("interaction_profiles.png", fig.plot_interaction_profiles, (training,))]


def object_jobs(obj: ObjectResult, render_3d: bool = True) -> list[FigureJob]:
    """An explored object's figures: map snapshots and entropy (2-D), or voxel columns and the 3-D render."""
    name, geometry, stem = obj.name, obj.geometry, file_stem(obj.name)  # a name from a file is never a path
    if not geometry.voxel:
        return [FigureJob(f"{stem}_map.png", fig.plot_map_snapshots, (name, obj.snapshots, geometry, obj.truth)),
                FigureJob(f"{stem}_entropy.png", fig.plot_entropy,
                          (name, obj.snapshots[-2].probabilities, obj.snapshots[-1].probabilities, geometry))]
    materials = list(geometry.materials)
    # no explored column (no press fitted): no columns figure rather than an empty one
    jobs = ([FigureJob(f"{stem}_columns.png", fig.plot_voxel_columns, (name, obj.grid, obj.post, materials))]
            if np.asarray(obj.grid.explored).any() else [])
    if render_3d:
        jobs.append(FigureJob(f"{stem}_voxels_3d.png", fig.render_voxels_3d,
                              (obj.post, obj.grid.cell_size, name, materials)))
    return jobs


def progress_series(obj: ObjectResult) -> fig.ProgressSeries:
    """An object's mean entropy and explored-cell accuracy against presses, for the progress figure."""
    return fig.ProgressSeries(
        obj.name, np.array([s.k for s in obj.steps]), np.array([s.mean_entropy for s in obj.steps]),
        np.array([np.nan if s.accuracy_explored is None else s.accuracy_explored for s in obj.steps]))


def progress_job(objects: Sequence[ObjectResult]) -> FigureJob:
    """Mean entropy and accuracy against presses, every object in one figure."""
    base = objects[0].geometry.entropy_base if objects else 10.0
    return FigureJob("exploration_progress.png", fig.plot_progress, ([progress_series(o) for o in objects], base))


class FigureDrawer:
    """Draws :class:`FigureJob` s into ``folder``, in one background process when ``background`` and the machine
    has more than one core, else in this process at :meth:`finish`. Use as a context manager (the background process
    is stopped on the way out, also on errors). ``preload``: modules the background process imports at start
    (e.g. ``("pyvista",)`` when a 3-D render will be drawn)."""

    def __init__(self, folder: Path, background: bool = True, preload: tuple[str, ...] = ()):
        self.folder = Path(folder)
        self._pending: list[tuple[FigureJob, Future | None]] = []
        self._pool = None
        import multiprocessing

        # fork (Linux): the drawer is a copy of this process, so it neither imports the caller's script again
        # (as spawn would: a script without a __main__ guard would run twice) nor palpate and numpy. Elsewhere, and
        # in a daemonic process (a pool's worker may not start processes), figures are drawn inline.
        if (background and (os.cpu_count() or 1) > 1 and sys.platform.startswith("linux")
                and not multiprocessing.current_process().daemon):
            self._pool = ProcessPoolExecutor(max_workers=1, mp_context=multiprocessing.get_context("fork"),
                                             initializer=figure_worker.start, initargs=(tuple(preload),))

    def __enter__(self) -> FigureDrawer:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def submit(self, jobs: Sequence[FigureJob]) -> None:
        """Queue figures (started at once in the background process, if there is one)."""
        self.folder.mkdir(parents=True, exist_ok=True)
        for job in jobs:
            future = None
            if self._pool is not None:
                try:
                    future = self._pool.submit(figure_worker.draw, job.draw, self._path(job), job.args)
                except BrokenProcessPool:
                    self._pool = None
            self._pending.append((job, future))

    def finish(self, progress: Progress | None = None) -> list[Path]:
        """Wait for (or draw) every queued figure, with a progress bar; returns the written paths in job order."""
        progress = progress or Progress(enabled=False)
        progress.start("drawing figures", len(self._pending))
        paths = []
        for i, (job, future) in enumerate(self._pending):
            path = None
            if future is not None:
                try:
                    path = future.result()
                except BrokenProcessPool:  # the background process died: draw the rest here
                    future = None
            if future is None:
                path = job.draw(self._path(job), *job.args)
            if path is not None:
                paths.append(Path(path))
            elif job.file.endswith("_voxels_3d.png"):
                progress.message(f"{job.file} skipped: the 3-D render needs the 'viz' extra "
                                 "(pip install 'palpate[viz]')")
            progress.update(i + 1, job.file)
        self._pending = []
        return paths

    def _path(self, job: FigureJob) -> Path:
        return inside(self.folder, self.folder / job.file)

    def close(self) -> None:
        """Stop the background process (figures not yet drawn are dropped)."""
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None


def fine_map_job(obj: ObjectResult, fine, truth: np.ndarray | None, anomalies: list[dict] | None = None) -> FigureJob:
    """An object's fine map beside its cell map and the truth (:mod:`palpate.core.io.fine_figures`), with its
    stiffness spots (``anomalies``: summary.json's ``stiffness_anomalies``)."""
    cells = fine.cells_on_raster(plane_probabilities(obj.post.probabilities))
    walls = [(tuple(np.asarray(s.result.location) + s.boundary.foot), tuple(s.boundary.normal)) for s in obj.steps
             if s.boundary is not None and s.boundary.p_boundary > 0.5]
    spots = [(tuple(a["centroid_m"]), a["sign"]) for a in anomalies or ()]
    return FigureJob(f"{file_stem(obj.name)}_fine_map.png", fine_figures.plot_fine_map,
                     (obj.name, fine, cells, truth, walls, spots))


def lump_layer_job(obj: ObjectResult, layer, truth: np.ndarray | None,
                   anomalies: list[dict] | None = None) -> FigureJob:
    """A voxel map's lump layer cut at a few depths above the truth there (:mod:`palpate.core.io.fine_figures`),
    with its stiffness spots (``anomalies``: summary.json's ``stiffness_anomalies``)."""
    spots = [(tuple(a["centroid_m"]), a["sign"]) for a in anomalies or ()]
    return FigureJob(f"{file_stem(obj.name)}_lumps.png", fine_figures.plot_lump_layer, (obj.name, layer, truth, spots))
