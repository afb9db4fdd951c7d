"""A simulated rig session: presses made by the simulation on three blocks, seen by a Tekscan-like pad and a
Liberty-like tracker that run on separate clocks, in a tracker frame that is not the grid's, written as the files
the real devices leave (a Tekscan ASCII export, a Liberty MCAP, a touch recording for the workspace).

The world frame is the grid frame shifted in z: the grid origin is the world origin, its z = 0 is the height of the
tracked point (the tip sphere's centre) when the pad rests on the blocks' top.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from palpate.core.alignment.calibration import matrix_to_quaternion, quat_multiply
from palpate.core.alignment.merge import session_pipeline
from palpate.core.io.mcap_reader import read_recording
from palpate.core.io.mcap_writer import RecordingWriter
from palpate.core.io.recording import recording_to_press_recording
from palpate.core.perception.memory import HapticMemory
from palpate.core.perception.pipeline import presses_from_recording
from palpate.core.perception.press import perceive_press, press_result
from palpate.core.perception.streams import PoseSample
from palpate.core.session.sources import PressTarget
from palpate.core.world.scene import Material, ObjectSpec, PoseSensorSpec, Scene
from palpate.sim.source import SimSource

TOP = 0.03
TIP_R = 0.008
# Pa. Softer than ~50 kPa the pad reads few counts at first contact and the perception's first-contact height varies by
# a few tenths of a mm with a millisecond's change of timing (seen on one clock too): c_D cannot be held to 0.2 mm.
MATERIALS = {"soft": 6e4, "medium": 2e5, "firm": 6e5}
BLOCK_X = {"soft": 0.02, "medium": 0.07, "firm": 0.12}  # block centres, m (blocks 4 cm wide, y centred at 0.03)
FRAME = 0.02  # s: the pad's 50 Hz
POSE_RATE = 240.0  # Hz: a Liberty
DEPTH = 0.0025  # m
LIBERTY_ID = "liberty_station1"


def scene() -> Scene:
    objects = tuple(ObjectSpec(name, "box", (0.04, 0.06, TOP), (BLOCK_X[name], 0.03), Material(name, e))
                    for name, e in MATERIALS.items())
    return Scene(objects, pose=PoseSensorSpec(rate=POSE_RATE, noise_std=1e-4, jitter=2e-4))


def tracker_frame() -> tuple[np.ndarray, np.ndarray]:
    """(A, b) with p_tracker = A p_world + b: the source 40 cm away, turned 110 degrees about z and tilted 30
    degrees about a horizontal axis (a tracker's z is not the blocks' normal)."""
    def rot(axis, angle):
        axis = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
        k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
        return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * k @ k
    a = rot([1.0, 1.0, 0.0], math.radians(30)) @ rot([0, 0, 1], math.radians(110))
    return a, np.array([0.31, -0.22, 0.12])


@dataclass
class RigSession:
    """The simulated presses and what each device recorded.

    Attributes:
        t_press: start time of each press, s (true time = the pad's clock).
        materials: material pressed each time.
        truth_depth: true largest indentation of each press, m (the simulation's).
        sim_labels: how the memory classifies each press perceived straight from the simulation (one clock).
        sim_depth: c_D of each press perceived straight from the simulation, m.
        frames_t, counts: the pad's frames (true time), counts (n, 4, 4) uint8.
        pose_t, pose_p, pose_q: the tracker's samples: true time s, world position m, world orientation (w,x,y,z).
    """

    t_press: np.ndarray
    materials: list
    truth_depth: np.ndarray
    sim_labels: list
    sim_depth: np.ndarray
    frames_t: np.ndarray
    counts: np.ndarray
    pose_t: np.ndarray
    pose_p: np.ndarray
    pose_q: np.ndarray
    locations: np.ndarray


def train_memory(seed: int = 100) -> HapticMemory:
    """A memory from simulated presses of the three materials (its own seeds, not the session's)."""
    params, labels = [], []
    source = SimSource(scene(), fidelity="analytic", seed=seed, variability="human")
    for name in MATERIALS:
        for k in range(6):
            rec = source.press(PressTarget(BLOCK_X[name] + 0.004 * (k - 2.5), 0.03, depth=DEPTH))
            params.append(perceive_press(rec).params)
            labels.append(name)
    return HapticMemory().fit(np.array(params), labels)


def simulate(memory: HapticMemory, *, seed: int = 7, n_per_material: int = 5, steady: float | None = None
             ) -> RigSession:
    """Presses in a shuffled order at irregular intervals (``steady``: at a fixed interval instead), the hand
    gliding at hover height between them."""
    rng = np.random.default_rng(seed)
    source = SimSource(scene(), fidelity="analytic", seed=seed, variability="human")
    order = [m for m in MATERIALS for _ in range(n_per_material)]
    rng.shuffle(order)
    t0 = 1.0
    frames = {}
    pose_t, pose_p, pose_q = [], [], []
    t_press, truth, sim_labels, sim_depth, locations = [], [], [], [], []
    last = None
    for name in order:
        x = BLOCK_X[name] + rng.uniform(-0.012, 0.012)
        y = 0.03 + rng.uniform(-0.02, 0.02)
        speed = 0.01 if steady is not None else rng.uniform(0.006, 0.014)
        rec = source.press(PressTarget(x, y, depth=DEPTH, speed=speed))
        res = perceive_press(rec)
        sim_labels.append(memory.predict(res.params[None])[0])
        sim_depth.append(res.depth)
        truth.append(float(rec.truth.indentation.max()))
        locations.append((x, y))
        t_press.append(t0)
        for f in rec.frames:
            frames[round((f.t + t0) / FRAME)] = f.counts
        tp = np.array([p.t for p in rec.poses]) + t0
        pp = np.array([p.position for p in rec.poses])
        qq = np.array([p.quaternion for p in rec.poses])
        if last is not None:  # glide from the end of the last press to the start of this one
            ts = np.arange(last[0] + 1 / POSE_RATE, tp[0] - 0.5 / POSE_RATE, 1 / POSE_RATE)
            w = ((ts - last[0]) / (tp[0] - last[0]))[:, None]
            pose_t.append(ts)
            pose_p.append((1 - w) * last[1] + w * pp[0] + 1e-4 * rng.standard_normal((len(ts), 3)))
            pose_q.append(np.tile(qq[0], (len(ts), 1)))
        pose_t.append(tp)
        pose_p.append(pp)
        pose_q.append(qq)
        last = (tp[-1], pp[-1])
        gap = steady if steady is not None else rng.uniform(1.0, 6.0)
        t0 = round((tp[-1] + gap) / FRAME) * FRAME
    n_frames = int(round(t0 / FRAME)) + 50
    counts = np.zeros((n_frames, 4, 4), dtype=np.uint8)
    for k, c in frames.items():
        counts[k] = c
    return RigSession(np.array(t_press), order, np.array(truth), sim_labels, np.array(sim_depth),
                      np.arange(n_frames) * FRAME, counts, np.concatenate(pose_t), np.concatenate(pose_p),
                      np.concatenate(pose_q), np.array(locations))


def write_tekscan(path: Path, s: RigSession, period: float = FRAME) -> None:
    """The pad's frames as a Tekscan ASCII movie export (RAW counts, a 6x6 map with the pad at 1:5,1:5)."""
    lines = ["DATA_TYPE MOVIE", "ROWS 6", "COLS 6", "ROW_SPACING 0.25 cm", "COL_SPACING 0.25 cm",
             "SENSEL_AREA 0.0484 sq cm", f"SECONDS_PER_FRAME {period}", "START_FRAME 1", "UNITS RAW",
             "ASCII_DATA @@", ""]
    for k, c in enumerate(s.counts):
        full = np.zeros((6, 6), dtype=int)
        full[1:5, 1:5] = c
        lines.append(f"Frame {k + 1}")
        lines += [",".join(map(str, r)) for r in full]
        lines.append("")
    path.write_text("\r\n".join(lines), newline="")


def liberty_times(t_true: np.ndarray, offset: float, drift_ppm: float) -> np.ndarray:
    """The tracker's clock: its own origin and rate, 1 ms ticks."""
    return np.round(((t_true * (1 + drift_ppm * 1e-6)) + offset) * 1000.0) / 1000.0


def write_liberty(path: Path, t_dev: np.ndarray, p_world: np.ndarray, q_world: np.ndarray,
                  turned: bool = True) -> None:
    """Poses in the tracker frame (the world frame unless ``turned``) on the tracker clock, as ``palpate record
    liberty`` writes them."""
    a, b = tracker_frame() if turned else (np.eye(3), np.zeros(3))
    qa = matrix_to_quaternion(a)
    p = p_world @ a.T + b
    q = quat_multiply(np.broadcast_to(qa, q_world.shape), q_world)
    keep = np.concatenate([[True], np.diff(t_dev) > 0])  # 1 ms ticks: a device sends one record per tick
    meta = {"scenario": None, "sources": {"pose": {"device": "polhemus-liberty", "time_base": "device",
                                                   "emulated": True}}}
    with RecordingWriter(path, meta) as w:
        for ti, pi, qi in zip(t_dev[keep], p[keep], q[keep], strict=True):
            w.write_pose(PoseSample(float(ti), pi, qi, LIBERTY_ID))


def touches(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A touch recording in the world frame: rests at the grid origin, on +x, on the +y side (pad on the top)."""
    z = TOP + TIP_R
    points = [np.array([0.0, 0.0, z]), np.array([0.10, 0.0, z]), np.array([0.03, 0.06, z])]
    t, p = [], []
    now = 0.0
    for k, point in enumerate(points):
        ts = now + np.arange(0, 1.5, 1 / POSE_RATE)
        t.append(ts)
        p.append(point + 1e-4 * rng.standard_normal((len(ts), 3)))
        now = ts[-1] + 1 / POSE_RATE
        if k < 2:  # lift, move over, put down: 1 s
            nxt = points[k + 1]
            ts = now + np.arange(0, 1.0, 1 / POSE_RATE)
            w = (ts - now)[:, None]
            lift = 0.01 * np.sin(np.pi * w)
            t.append(ts)
            p.append((1 - w) * point + w * nxt + np.hstack([np.zeros((len(ts), 2)), lift]))
            now = ts[-1] + 1 / POSE_RATE
    t = np.concatenate(t)
    return t, np.concatenate(p), np.tile([1.0, 0.0, 0.0, 0.0], (len(t), 1))


def perceived_labels(memory: HapticMemory, recording) -> tuple[list, np.ndarray, np.ndarray]:
    """Labels, depths (m) and locations (m) of every press the perception finds in a session recording."""
    rec = read_recording(recording)
    seg = presses_from_recording(recording_to_press_recording(rec), session_pipeline(rec.metadata))
    results = [press_result(p) for p in seg.presses]
    labels = memory.predict(np.array([r.params for r in results])) if results else []
    return list(labels), np.array([r.depth for r in results]), np.array([r.location for r in results])
