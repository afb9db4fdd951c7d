"""One timeline for a whole run: every press's streams shifted after the previous one, optionally recorded.

The run perceives the *shifted* streams, exactly what the recording holds, so ``palpate replay`` of the recording
reproduces the run's maps bit for bit.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from palpate.core.io.mcap_writer import RecordingWriter
from palpate.core.mapping.geometry import MapGeometry
from palpate.core.perception.streams import (
    GroundTruth,
    PressRecording,
    saturated_frames,
    shifted_in_time,
    solver_warning_steps,
)


class PressLog:
    """Lays every press on one timeline (so a run is one continuous stream) and optionally records it to MCAP.

    The run perceives the *shifted* streams, exactly what the recording holds, so ``palpate replay`` of the
    recording reproduces the run's maps bit for bit.
    """

    GAP = 1.0  # s of silence between presses

    def __init__(self, path: Path | None = None, metadata: dict | None = None, live=None,
                 pad_offset: tuple[float, float, float] | None = None):
        self.clock = 0.0
        self.writer = None
        if path is not None or live is not None:
            self.writer = RecordingWriter(path, metadata or {}, live=live, pad_offset=pad_offset)

    def add(self, rec, info: dict):
        """Shift ``rec`` to start at the current clock, record it with a ``press`` annotation, return it."""
        shifted = shift_recording(rec, self.clock - _start_time(rec))
        t_end = max(shifted.frames[-1].t if shifted.frames else self.clock,
                    shifted.poses[-1].t if shifted.poses else self.clock)
        if self.writer is not None:
            # saturated frames are counted in the recording itself, beside the frames that show them, and so are
            # the steps on which the simulation's solver warned
            counts = {"frames": len(shifted.frames), "saturated_frames": saturated_frames(shifted.frames),
                      "solver_warning_steps": solver_warning_steps(shifted.meta)}
            self.writer.write_annotation(self.clock, "press", {**info, **counts, "t_start": self.clock,
                                                               "t_end": t_end})
            for f in shifted.frames:
                self.writer.write_taxel(f)
            for p in shifted.poses:
                self.writer.write_pose(p)
            if shifted.truth is not None and len(shifted.truth.t):
                self.writer.write_truth(shifted.truth.t, shifted.truth.force, shifted.truth.indentation,
                                        shifted.truth.material)
        self.clock = float(np.ceil(t_end + self.GAP))
        return shifted

    def show_map(self, name: str, grid, geometry, surface_z: float, scene=()) -> None:
        """Record (and send live) an object's map as it stands after the last press, with the objects of
        ``scene`` (ObjectSpecs) as scene entities."""
        if self.writer is None:
            return
        t = max(self.clock - self.GAP, 0.0)
        if scene:
            self.writer.write_scene(t, scene)
        self.writer.write_map(t, name, grid.probabilities, grid.explored, geometry, surface_z)

    def show_fine_map(self, name: str, fine, surface_z: float) -> None:
        """Record (and send live) an object's fine map (:class:`~palpate.core.mapping.fine.FineMap`) as a grid of
        its own resolution on ``/map/<name>_fine``."""
        if self.writer is None:
            return
        ny, nx = fine.probabilities.shape[:2]
        geometry = MapGeometry("grid2d", fine.materials, fine.origin, fine.resolution, (nx, ny))
        self.writer.write_map(max(self.clock - self.GAP, 0.0), f"{name}_fine", fine.probabilities,
                              np.ones((ny, nx), dtype=bool), geometry, surface_z)

    def show_spots(self, name: str, anomalies, surface_z: float, footprint: tuple[float, float] | None = None) -> None:
        """Record (and send live) an object's stiffness spots on ``/spots/<name>`` (none: nothing written;
        ``footprint``: a voxel map's cell side and depth, m, to draw the lumps they read)."""
        if self.writer is None or not anomalies:
            return
        self.writer.write_spots(max(self.clock - self.GAP, 0.0), name, anomalies, surface_z, footprint)

    def close(self) -> None:
        """Finish the recording (idempotent): called when exploration ends, so the file is complete on disk
        before figures are drawn."""
        if self.writer is not None:
            self.writer.close()


def _start_time(rec) -> float:
    times = [rec.frames[0].t] if rec.frames else []
    times += [rec.poses[0].t] if rec.poses else []
    return min(times) if times else 0.0


def shift_recording(rec, dt: float):
    """A copy of a PressRecording with every timestamp moved by ``dt`` seconds (the samples' arrays are shared)."""
    if dt == 0.0:
        return rec
    truth = None
    if rec.truth is not None:
        truth = GroundTruth(np.asarray(rec.truth.t) + dt, rec.truth.force, rec.truth.indentation, rec.truth.material)
    return PressRecording(shifted_in_time(rec.frames, dt), shifted_in_time(rec.poses, dt), truth, dict(rec.meta))
