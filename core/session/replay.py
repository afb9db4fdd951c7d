"""Replay a recording through the same perception stack as a live or simulated run.

Two kinds of recordings:

- written by ``palpate run --record``: every press carries a ``press`` annotation (phase, object, cell, planned
  target, time window) and the metadata holds each object's map geometry, so replay cuts the stream into the
  same presses and rebuilds the same maps, bit for bit;
- anything else (a Tekscan import, a Liberty + finger session): the whole stream is segmented into presses and
  mapped on a grid that covers the press locations (``cell_size`` m, default 1 cm).
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from palpate.core import __version__, files
from palpate.core.alignment.merge import pipeline_for, session_pipeline
from palpate.core.errors import ValidationError
from palpate.core.files import brief
from palpate.core.io import figures as fig
from palpate.core.io.mcap_reader import read_recording
from palpate.core.io.mcap_writer import RecordingWriter
from palpate.core.io.recording import Annotation, recording_to_press_recording
from palpate.core.mapping.calibration import MapCalibration
from palpate.core.mapping.geometry import MapGeometry
from palpate.core.mapping.grids import new_map
from palpate.core.mapping.regions import map_region_report
from palpate.core.mapping.snapshot import MapSnapshot
from palpate.core.names import inside, unique_stems
from palpate.core.perception.classifier_memory import ClassifierMemory
from palpate.core.perception.layered_memory import LayeredMemory
from palpate.core.perception.memory import HapticMemory
from palpate.core.perception.memory_loading import check_replayable, memory_algorithms
from palpate.core.perception.pipeline import presses_from_recording
from palpate.core.perception.press import PressResult, perceive_press, press_result
from palpate.core.perception.streams import GroundTruth, PressRecording
from palpate.core.session.boundaries import (
    plane_fine_map,
    replay_edge_reach,
    replay_lump_evidence,
    replay_reader,
    save_fine_map,
    save_lump_layer,
    training_moduli,
    voxel_lump_layer,
    with_curves,
)
from palpate.core.session.explore import MapPostprocessing, apply_press
from palpate.core.session.output_guard import prepare_output_folder
from palpate.core.session.progress import Progress
from palpate.core.session.report import assert_finite, fit_summary, versions

REPLAY_FORMAT = "palpate-replay-summary"


@dataclass(frozen=True)
class _Timeline:
    """A recording's frame and pose times, worked out once so each press window is two binary searches."""

    stream: PressRecording
    frame_t: np.ndarray
    pose_t: np.ndarray

    @classmethod
    def of(cls, rec: PressRecording) -> _Timeline:
        return cls(rec, np.array([f.t for f in rec.frames]), np.array([p.t for p in rec.poses]))

    def span(self) -> str:
        """Where the recording's frames and poses lie, for an error about a press window (s)."""
        def of(t: np.ndarray) -> str:
            return f"{t[0]:g}..{t[-1]:g} s" if len(t) else "none"
        return f" (the recording's taxel frames: {of(self.frame_t)}; poses: {of(self.pose_t)})"

    def window(self, t0: float, t1: float) -> PressRecording:
        """The part of the recording with t0 <= t <= t1 (frames, poses and truth)."""
        rec = self.stream
        f0, f1 = np.searchsorted(self.frame_t, t0, "left"), np.searchsorted(self.frame_t, t1, "right")
        p0, p1 = np.searchsorted(self.pose_t, t0, "left"), np.searchsorted(self.pose_t, t1, "right")
        truth = None
        if rec.truth is not None:
            keep = (rec.truth.t >= t0) & (rec.truth.t <= t1)
            if keep.any():
                truth = GroundTruth(rec.truth.t[keep], rec.truth.force[keep], rec.truth.indentation[keep],
                                    rec.truth.material)
        return PressRecording(rec.frames[f0:f1], rec.poses[p0:p1], truth, {})


@dataclass
class _Replayed:
    """One object's map as it is rebuilt."""

    geometry: MapGeometry
    grid: object
    rows: list = field(default_factory=list)
    readings: list = field(default_factory=list)  # (location, boundary reading or None, press result)


@dataclass
class _Playback:
    """Sends each replayed press's streams, and the map after it, to a live view at ``speed`` x real time."""

    writer: RecordingWriter
    speed: float
    start: tuple[float, float] | None = None  # (recording time, wall clock) of the first press

    def press(self, sub: PressRecording, annotation: Annotation | None, name: str, grid, geometry: MapGeometry,
              res: PressResult) -> None:
        times = [x.t for x in sub.frames[:1] + sub.poses[:1]]
        t = min(times) if times else (annotation.t if annotation else 0.0)
        if self.speed > 0:
            if self.start is None:
                self.start = (t, time.monotonic())
            wait = (t - self.start[0]) / self.speed - (time.monotonic() - self.start[1])
            if wait > 0:
                time.sleep(wait)
        if annotation is not None:
            self.writer.write_annotation(annotation.t, annotation.kind, annotation.data)
        for f in sub.frames:
            self.writer.write_taxel(f)
        for p in sub.poses:
            self.writer.write_pose(p)
        t_end = max([t] + [x.t for x in sub.frames[-1:] + sub.poses[-1:]])
        surface = geometry.z_top if geometry.voxel else (res.press.h0 if res.press is not None else 0.0)
        self.writer.write_map(t_end, name, grid.probabilities, grid.explored, geometry, float(surface))


def _layers_for(geometry: MapGeometry, memory: HapticMemory, layers: LayeredMemory | None) -> LayeredMemory | None:
    if not geometry.voxel:
        return None
    return layers if layers is not None else LayeredMemory.whole_press(memory, geometry.cell_size, geometry.shape[2])


@dataclass(frozen=True)
class PressWindow:
    """A ``press`` annotation of a recording made by ``palpate run --record``, validated: the phase, the object
    explored, the press's time window (s), its planned target (m), its number and cell."""

    phase: str
    object: str
    t_start: float
    t_end: float
    target: tuple[float, float]
    k: int | None
    cell: list | None


def press_window(data, where: str) -> PressWindow:
    """Validate one press annotation's fields (they come from a file); ValidationError naming ``where`` and the
    field."""
    if not isinstance(data, dict):
        raise ValidationError(f"{where}: expected an object of fields, got {brief(data)}")

    def number(key, default=None):
        v = data.get(key, default)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise ValidationError(f"{where}: field {key!r} must be a finite number, got {brief(v)}")
        return float(v)

    phase, obj = data.get("phase"), data.get("object", "recording")
    for key, v in (("phase", phase), ("object", obj)):
        if not isinstance(v, str):
            raise ValidationError(f"{where}: field {key!r} must be a string, got {brief(v)}")
    t_start, t_end = number("t_start"), number("t_end")
    if t_end < t_start:
        raise ValidationError(f"{where}: field 't_end' {t_end} is before 't_start' {t_start}")
    target = data.get("target_m", [math.nan, math.nan])
    if not (isinstance(target, list) and len(target) == 2
            and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in target)):
        raise ValidationError(f"{where}: field 'target_m' must be two numbers (m), got {brief(target)}")
    k, cell = data.get("k"), data.get("cell")
    if k is not None and (isinstance(k, bool) or not isinstance(k, int)):
        raise ValidationError(f"{where}: field 'k' must be an integer, got {brief(k)}")
    if cell is not None and not (isinstance(cell, list) and len(cell) <= 3
                                 and all(isinstance(c, int) and not isinstance(c, bool) for c in cell)):
        raise ValidationError(f"{where}: field 'cell' must be a list of integers, got {brief(cell)}")
    return PressWindow(phase, obj, t_start, t_end, (float(target[0]), float(target[1])), k, cell)


def _training_presses(presses, annotations, timeline, reader) -> tuple[dict[str, list], dict[str, list]]:
    """Per reference material, the boundary readings of its training presses in the recording, and the presses as
    perceived."""
    readings: dict[str, list] = {}
    results: dict[str, list] = {}
    for w in presses:
        material = annotations[id(w)].data.get("material") if w.phase == "training" else None
        if isinstance(material, str):
            sub = timeline.window(w.t_start, w.t_end)
            res = perceive_press(sub)
            readings.setdefault(material, []).append(reader(sub, res))
            results.setdefault(material, []).append(res)
    return readings, results


def replay_recording(path: str | Path, memory: HapticMemory | ClassifierMemory, out_dir: str | Path, *,
                     layers: LayeredMemory | None = None, cell_size: float = 0.01, progress: Progress | None = None,
                     figures: bool = True, force: bool = False, inputs=(), salvage: bool = False, live=None,
                     live_speed: float = 1.0) -> dict:
    """Run the perception stack on a recording and write maps, figures and summary.json into ``out_dir``.

    Args:
        path: MCAP recording (palpate format).
        memory: the run's memory, fitted: a HapticMemory, or the ClassifierMemory of a run whose presses a
            classifier plugin judged (2-D maps only), e.g. from
            :func:`~palpate.core.perception.memory_loading.load_memory`.
        out_dir: output folder (created).
        layers: voxel maps: the per-layer judges the run used (default: every layer judged by ``memory``).
        cell_size: grid cell, m, for recordings without map geometry.
        progress: progress bars (silent by default).
        figures: write PNG figures.
        force: replace an earlier replay in ``out_dir``; ``inputs``: further files read (never deleted).
        salvage: replay what the complete chunks of a truncated or damaged recording hold (presses the damage cut
            off are left out).
        live: a live view (:class:`~palpate.core.io.live.LiveServer`) to send each press's streams and the map
            after it to; ``live_speed``: play at this many times real time (0: as fast as perception goes).

    Names from the recording (objects in its metadata and annotations) are only names: each map is written as
    ``maps/<safe file stem>.npz`` inside ``out_dir``.
    """
    progress = progress or Progress(enabled=False)
    if not (isinstance(cell_size, (int, float)) and math.isfinite(cell_size) and cell_size > 0):
        raise ValidationError(f"replay: cell_size must be a finite number > 0 m, got {brief(cell_size)}")
    rec = read_recording(path, salvage=salvage, progress=progress)
    stream = recording_to_press_recording(rec)
    maps = rec.metadata.get("maps") or {}
    if not isinstance(maps, dict):
        raise ValidationError(f"{path}: metadata 'maps' must be an object of map geometries, got {brief(maps)}")
    geoms = {name: MapGeometry.from_dict(g, f"{path}: metadata maps.{name}") for name, g in maps.items()}
    check_replayable(memory, [name for name, g in geoms.items() if g.voxel], layers is not None, str(path))
    for name, g in geoms.items():  # a map's columns are its materials: another memory's order would relabel them
        if tuple(g.materials) != tuple(memory.materials):
            raise ValidationError(f"{path}: map {brief(name)} was made with materials {list(g.materials)}, the memory "
                                  f"judges {list(memory.materials)}; replay with the run's own memory.json")
    # The run's map calibration (a recording made before it was recorded used the seeds' maps).
    calibration = MapCalibration.from_dict(rec.metadata.get("map_calibration") or {},
                                           f"{path}: metadata map_calibration")
    postprocessing = MapPostprocessing.from_dict(rec.metadata.get("map_postprocessing") or {},
                                                 f"{path}: metadata map_postprocessing")
    windows = [(i, a) for i, a in enumerate(rec.annotations) if a.kind == "press"]
    presses = presses_all = [press_window(a.data, f"{path}: annotation {i} (press)") for i, a in windows]
    if rec.salvaged and presses:
        # The damage cut the stream: a press whose window reaches past the last frame or pose is incomplete.
        end = min(stream.frames[-1].t if stream.frames else -np.inf, stream.poses[-1].t if stream.poses else -np.inf)
        complete = [w for w in presses if w.t_end <= end]
        if len(complete) < len(presses):
            progress.message(f"{path}: {len(presses) - len(complete)} press(es) cut off by the damage are left out")
        presses = complete
    explore = [w for w in presses if w.phase == "exploration"]
    stems = unique_stems({w.object for w in explore} if windows else {"recording"}, f"{path}: object names")
    out = prepare_output_folder(out_dir, "replay", force=force, inputs=[path, *inputs])
    objects: dict[str, _Replayed] = {}
    playback = None if live is None else _Playback(RecordingWriter(None, {}, live=live), float(live_speed))
    timeline = _Timeline.of(stream)
    annotations = {id(w): rec.annotations[i] for (i, _), w in zip(windows, presses_all, strict=True)}
    reader = replay_reader(rec.metadata, str(path))
    edge_reach = replay_edge_reach(rec.metadata, str(path))
    moduli = lumps = None
    if windows and reader is not None:  # the references' moduli from their training presses, as the run read them
        training_readings, training_results = _training_presses(presses, annotations, timeline, reader)
        moduli = training_moduli(training_readings)
        lumps = replay_lump_evidence(training_results)
    if windows:
        progress.start("replaying presses", len(explore))
        for i, w in enumerate(explore):
            if w.object not in geoms:
                raise ValidationError(f"{path}: press annotation names object {brief(w.object)}, which has no map "
                                      "geometry in the recording's metadata")
            state = objects.setdefault(w.object, _Replayed(geoms[w.object], new_map(geoms[w.object])))
            sub = timeline.window(w.t_start, w.t_end)
            # a press whose streams asked for their own perception (a session file's) is perceived so again
            perception = annotations[id(w)].data.get("perception")
            perception = perception if isinstance(perception, dict) else None
            try:
                res = perceive_press(sub, pipeline_for(perception) if perception else None).at_target(w.target)
            except ValidationError as exc:  # the streams of this press are malformed: say which press of which file
                raise ValidationError(f"{path}: press annotation {windows[presses_all.index(w)][0]} "
                                      f"({brief(w.object)}, {w.t_start:g}..{w.t_end:g} s): {exc}"
                                      f"{timeline.span()}") from None
            if reader is not None:
                state.readings.append((res.location, reader(sub, res), res))
            posterior = apply_press(state.grid, res, memory, _layers_for(state.geometry, memory, layers),
                                    fallback_xy=w.target, calibration=calibration)
            state.rows.append(_row(w.k if w.k is not None else len(state.rows) + 1, w.cell, res, posterior,
                                   state.grid))
            if playback is not None:
                playback.press(sub, annotations[id(w)], w.object, state.grid, state.geometry, res)
            progress.update(i + 1)
    else:
        # a session merged from separate devices says how it is perceived (press axis from each press's motion)
        try:
            seg = presses_from_recording(stream, session_pipeline(rec.metadata))
        except ValidationError as exc:
            raise ValidationError(f"{path}: {exc}{timeline.span()}") from None
        if not seg.presses:
            reasons = "; ".join(sorted({r.reason for r in seg.rejected})) or "no contact in the taxel stream"
            raise ValidationError(f"{path}: no press found to replay ({reasons})")
        locs = np.array([p.location for p in seg.presses])
        lo = np.floor(locs.min(axis=0) / cell_size) * cell_size
        shape = tuple(int(v) for v in np.floor((locs.max(axis=0) - lo) / cell_size) + 1)
        geometry = MapGeometry("grid2d", tuple(memory.materials), (float(lo[0]), float(lo[1])), cell_size, shape)
        state = objects.setdefault("recording", _Replayed(geometry, new_map(geometry)))
        progress.start("replaying presses", len(seg.presses))
        for k, press in enumerate(seg.presses):
            res = press_result(press)
            if res.fit is None:
                raise ValidationError(f"{path}: {res.rejected[-1]}")
            posterior = apply_press(state.grid, res, memory, None, fallback_xy=press.location,
                                    calibration=calibration)
            state.rows.append(_row(k + 1, None, res, posterior, state.grid))
            if playback is not None:
                playback.press(timeline.window(press.t_onset, press.t_release), None, "recording", state.grid,
                               geometry, res)
            progress.update(k + 1)

    summary_objects = []
    (out / "maps").mkdir(exist_ok=True)
    for name, state in objects.items():
        grid = state.grid
        post = postprocessing.apply(grid, calibration)
        grid.save(inside(out, out / "maps" / f"{stems[name]}.npz"))
        post.save(inside(out, out / "maps" / f"{stems[name]}_postprocessed.npz"))
        g = state.geometry
        summary_objects.append({
            "name": name, "map": g.kind,
            "grid": {"origin_m": list(g.origin), "cell_size_m": g.cell_size, "shape": list(g.shape)},
            "presses": len(state.rows), "per_press": state.rows,
            "mean_entropy_after_each_press": [r["mean_entropy"] for r in state.rows],
            "mean_entropy_after_postprocessing": float(post.mean_entropy()),
            "material_regions": map_region_report(g, post.probabilities),
        })
        if state.readings:
            read = [(xy, r, res) for xy, r, res in state.readings if r is not None]
            fine, findings = plane_fine_map(g, post.probabilities, [(xy, r) for xy, r, _ in read], moduli, edge_reach,
                                            with_curves(lumps, [res for _, _, res in read]))
            save_fine_map(inside(out, out / "maps" / f"{stems[name]}_fine.npz"), fine)
            summary_objects[-1]["fine_map"] = {
                "resolution_m": fine.resolution, "presses_read": len(state.readings),
                "sides_named_by": "modulus" if moduli else "neighbour cells"} | findings
            layer, layer_summary = voxel_lump_layer(g, fine, findings)
            if layer is not None:
                save_lump_layer(inside(out, out / "maps" / f"{stems[name]}_lumps.npz"), layer)
            if layer_summary is not None:
                summary_objects[-1]["fine_map"]["lump_layer"] = layer_summary
        if figures and not g.voxel:
            (out / "figures").mkdir(exist_ok=True)
            fig.plot_map_snapshots(inside(out, out / "figures" / f"{stems[name]}_map.png"), name,
                                   [MapSnapshot.of(grid, "replayed"), MapSnapshot.of(post, "post-processed")], g)
    summary = {"format": REPLAY_FORMAT, "version": 1, "recording": str(path), "salvaged": rec.salvaged,
               "materials": list(memory.materials), "algorithms": memory_algorithms(memory),
               "source_metadata": rec.metadata, "objects": summary_objects, "versions": versions(),
               "palpate": __version__}
    assert_finite(summary)
    files.write_text(out / "summary.json", json.dumps(summary, indent=2))
    return summary


def _row(k, cell, res: PressResult, posterior: np.ndarray | None, grid) -> dict:
    return {"k": k, "cell": cell, "location_m": list(res.location), "depth_m": res.depth,
            "fit": fit_summary(res.fit), "posterior": None if posterior is None else [float(v) for v in posterior],
            "mean_entropy": float(grid.mean_entropy()), "rejected": list(res.rejected)}
