"""Pose and taxel streams of presses on two clocks a KNOWN map apart, shared by the clock map's tests and
``benchmarks/clock_bias.py``: the session recorder's emulated fingertip (:func:`~palpate.hardware.polhemus.emulator.
press_motion`, 5 mm raised cosine every 2 s, 3 mm into the block) and its pad's Hertz counts
(:func:`~palpate.hardware.tactile.emulator.press_counts`), sampled at chosen rates without the serial emulators, so
no host timing enters."""

from __future__ import annotations

import numpy as np

from palpate.core.perception.streams import PoseSample, TaxelFrame
from palpate.hardware.polhemus.emulator import press_motion
from palpate.hardware.tactile.emulator import press_counts

OFFSET = 0.0123  # s, taxel clock minus pose clock
SENSEL_AREA = 4.84e-6  # m^2
QUAT = np.array([1.0, 0.0, 0.0, 0.0])


def streams(seed: int, sigma: float, *, presses: int = 6, pose_rate: float = 240.0, taxel_rate: float = 50.0,
            offset: float = OFFSET, drift_ppm: float = 0.0) -> tuple[list[TaxelFrame], list[PoseSample]]:
    """Taxel frames (taxel clock) and poses (pose clock, ``sigma`` m of noise per axis) of ``presses`` presses.

    The pose clock reads ``t_pose = (1 - rate) t_taxel - offset`` with ``rate = -drift_ppm 1e-6``, so the clock map
    ``t_taxel = t_pose + offset + rate t_taxel`` holds with ``t_ref = 0``. Both streams start at a seed-dependent
    phase so the samples do not fall at the same place of every press."""
    rng = np.random.default_rng(seed)
    motion = press_motion()
    duration = 2.0 * presses
    source = press_counts(motion, seed=seed)
    t = rng.uniform(0.0, 1.0 / taxel_rate) + np.arange(0.0, duration, 1.0 / taxel_rate)
    frames = [TaxelFrame(float(ti), source(float(ti)), SENSEL_AREA) for ti in t]
    rate = -drift_ppm * 1e-6
    # pose samples every 1/pose_rate on the pose clock; their true (taxel-clock) times invert the map
    tp = (-offset + rng.uniform(0.0, 1.0 / pose_rate)) + np.arange(0.0, duration, 1.0 / pose_rate)
    t_true = (tp + offset) / (1.0 - rate)
    path = np.array([motion(float(ti), 1)[0] for ti in t_true])
    path = path + rng.normal(0.0, sigma, path.shape)
    poses = [PoseSample(float(ti), p, QUAT) for ti, p in zip(tp, path, strict=True)]
    return frames, poses


def human_streams(seed: int, *, presses: int = 24, period: tuple[float, float] = (2.0, 3.0), jitter: float = 0.1,
                  sigma: float = 1e-4,
                  offset: float = OFFSET, pose_rate: float = 240.0, taxel_rate: float = 50.0
                  ) -> tuple[list[TaxelFrame], list[PoseSample], np.ndarray]:
    """Presses at a person's rhythm: a period drawn from ``period`` s (uniform) for the session, each press starting
    that period plus a normal ``jitter`` s after the last, lasting 1.0-1.6 s down and up (3-5 mm, raised cosine),
    the hand moving 20 mm sideways to the next cell in between. Returns taxel
    frames (taxel clock), poses (pose clock, ``sigma`` m of noise per axis, ``offset`` s behind) and the presses'
    start times (taxel clock, s)."""
    rng = np.random.default_rng(seed)
    beat = rng.uniform(*period)
    gaps = np.maximum(beat + rng.normal(0.0, jitter, presses - 1), 1.7)
    starts = 1.0 + np.concatenate([[0.0], np.cumsum(gaps)])
    lengths = rng.uniform(1.0, 1.6, presses)
    depths = rng.uniform(0.003, 0.005, presses)
    end = starts[-1] + beat + 1.0
    surface = 0.048

    def motion(t: float, station: int = 1) -> tuple[np.ndarray, np.ndarray]:
        k = int(np.searchsorted(starts, t, side="right")) - 1
        x, z = 0.02 * max(k, 0), surface + 0.002
        if k >= 0:
            u = (t - starts[k]) / lengths[k]
            if u < 1.0:
                z -= (0.002 + depths[k]) * 0.5 * (1.0 - np.cos(2.0 * np.pi * u))
            elif k + 1 < presses:  # glide to the next cell
                x += 0.02 * min((t - starts[k] - lengths[k]) / (starts[k + 1] - starts[k] - lengths[k]), 1.0)
        return np.array([x, 0.0, z]), QUAT

    source = press_counts(motion, surface_z=surface, seed=seed)
    t = rng.uniform(0.0, 1.0 / taxel_rate) + np.arange(0.0, end, 1.0 / taxel_rate)
    frames = [TaxelFrame(float(ti), source(float(ti)), SENSEL_AREA) for ti in t]
    t_true = rng.uniform(0.0, 1.0 / pose_rate) + np.arange(0.0, end, 1.0 / pose_rate)
    path = np.array([motion(float(ti))[0] for ti in t_true]) + rng.normal(0.0, sigma, (len(t_true), 3))
    poses = [PoseSample(float(ti - offset), p, QUAT) for ti, p in zip(t_true, path, strict=True)]
    return frames, poses, starts
