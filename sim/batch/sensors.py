"""The sensor models of :mod:`palpate.sim.sensors` over many presses at once.

Each press draws its noise from its own generators in the order one press draws it (taxel noise; pose jitter,
position noise, orientation noise), so its streams are the ones :func:`~palpate.sim.sensors.sample_taxels` and
:func:`~palpate.sim.sensors.sample_poses` give; the interpolation, the 8-bit quantisation and the quaternion
arithmetic run once over the presses' samples laid end to end (elementwise, so a sample's value does not depend on
its neighbours in the batch).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from palpate.core.errors import SimulationDiverged
from palpate.core.perception.streams import PoseSample, TaxelFrame, pose_samples, taxel_frames
from palpate.core.world.scene import FingertipSpec, PoseSensorSpec, TaxelSensorSpec
from palpate.sim.sensors import ORIENTATION_NOISE, _quat_mul
from palpate.sim.trace import PhysicsTrace, frame_times


@dataclass(frozen=True)
class Sensing:
    """What one press's sensors see: its trace, the pad (spec, fingertip, noise generator, response or None) and
    the tracker (spec, noise generator, latency s)."""

    trace: PhysicsTrace
    taxels: TaxelSensorSpec
    tip: FingertipSpec
    taxel_rng: np.random.Generator
    response: object
    pose: PoseSensorSpec
    pose_rng: np.random.Generator
    latency: float


def sense_many(items: Sequence[Sensing]) -> list[tuple[list[TaxelFrame], list[PoseSample]]]:
    """Each press's taxel frames and pose samples, equal to sampling each press alone."""
    for it in items:
        it.trace.check_finite()
    frames = _taxels(items)
    poses = _poses(items)
    return list(zip(frames, poses, strict=True))


def _lay(items: Sequence[Sensing], field: str):
    """The traces' times and ``field`` rows end to end, with each trace's first row."""
    t = np.concatenate([it.trace.t for it in items])
    values = np.concatenate([getattr(it.trace, field).reshape(len(it.trace.t), -1) for it in items])
    starts = np.cumsum([0] + [len(it.trace.t) for it in items])[:-1]
    return t, values, starts


def _interp(queries: list[np.ndarray], items: Sequence[Sensing], t: np.ndarray, values: np.ndarray,
            starts: np.ndarray) -> np.ndarray:
    """palpate.sim.sensors._interp_rows of every press at once: (sum of queries, columns); the shares of
    :func:`palpate.sim.trace.bracket` over all presses' rows in one pass (half its cost a press, called alone)."""
    idx = np.concatenate([
        np.clip(np.searchsorted(it.trace.t, q, side="right") - 1, 0, len(it.trace.t) - 2) + s
        for q, it, s in zip(queries, items, starts, strict=True)])
    q = np.concatenate(queries)
    span = t[idx + 1] - t[idx]
    w = np.clip((q - t[idx]) / np.where(span > 0, span, 1.0), 0.0, 1.0)[:, None]
    return values[idx] * (1.0 - w) + values[idx + 1] * w


def _taxels(items: Sequence[Sensing]) -> list[list[TaxelFrame]]:
    if not items:
        return []
    t, values, starts = _lay(items, "sensel_pressure")
    queries = [frame_times(it.trace.t, it.taxels.rate) for it in items]
    flat = _interp(queries, items, t, values, starts)
    cut = np.cumsum([len(q) for q in queries])[:-1]
    pressures = [p.reshape((len(q),) + it.trace.sensel_pressure.shape[1:])
                 for p, q, it in zip(np.split(flat, cut), queries, items, strict=True)]
    pressures = [p if it.response is None else it.response(q, p)
                 for p, q, it in zip(pressures, queries, items, strict=True)]
    every = np.concatenate(pressures)
    if not np.all(np.isfinite(every)):
        raise SimulationDiverged("non-finite sensel pressure reached the taxel model; reduce the timestep")
    sizes = [len(q) for q in queries]
    shape = (-1,) + (1,) * (every.ndim - 1)
    raw = every * np.repeat([it.taxels.gain for it in items], sizes).reshape(shape)
    start = 0
    for p, it in zip(pressures, items, strict=True):
        if it.taxels.noise_std > 0:  # each press's own draw, in its order; p * gain + std * noise as one press adds
            raw[start:start + len(p)] += it.taxels.noise_std * it.taxel_rng.standard_normal(p.shape)
        start += len(p)
    # rounding, saturation and the threshold: elementwise over every press, each press's own threshold
    counts = np.clip(np.rint(raw), 0, 255)
    counts[counts <= np.repeat([float(it.taxels.threshold) for it in items], sizes).reshape(shape)] = 0
    counts = counts.astype(np.uint8)
    out, start = [], 0
    for q, it in zip(queries, items, strict=True):
        out.append(taxel_frames(q + it.taxels.clock_offset, counts[start:start + len(q)], it.tip.sensel_area))
        start += len(q)
    return out


def _poses(items: Sequence[Sensing]) -> list[list[PoseSample]]:
    if not items:
        return []
    times, seen, pos_noise, rot_draws = [], [], [], []
    for it in items:
        tr, spec, rng = it.trace, it.pose, it.pose_rng
        period = 1.0 / spec.rate
        n = int(np.floor((tr.t[-1] - tr.t[0]) / period + 1e-9)) + 1
        nominal = tr.t[0] + np.arange(n) * period
        t_true = nominal + (spec.jitter * rng.standard_normal(n) if spec.jitter > 0 else 0.0)
        t_true = np.clip(t_true, tr.t[0], tr.t[-1])
        t_true = t_true[np.concatenate([[True], np.diff(t_true) > 0])]
        times.append(t_true)
        seen.append(t_true if it.latency == 0 else np.clip(t_true - it.latency, tr.t[0], tr.t[-1]))
        m = len(t_true)
        pos_noise.append(spec.noise_std * rng.standard_normal((m, 3)) if spec.noise_std > 0 else None)
        rot_draws.append(rng.standard_normal((m, 3)))  # _small_rotation's draw, taken in the press's order
    t, positions, starts = _lay(items, "tip_position")
    pos = _interp(seen, items, t, positions, starts)
    _, quats, _ = _lay(items, "tip_quaternion")
    quat = _interp(seen, items, t, quats, starts)
    start = 0
    for s, p in zip(seen, pos_noise, strict=True):
        if p is not None:
            pos[start:start + len(s)] += p
        start += len(s)
    rot = _unit_rotation(np.concatenate(rot_draws))
    quat = _quat_mul(quat, rot)
    out, start = [], 0
    for tt, it in zip(times, items, strict=True):
        stop = start + len(tt)
        out.append(pose_samples(tt + it.pose.clock_offset, pos[start:stop], quat[start:stop]))
        start = stop
    return out


def _unit_rotation(draws: np.ndarray) -> np.ndarray:
    """:func:`palpate.sim.sensors._small_rotation` from its standard-normal draws (n, 3)."""
    half = 0.5 * ORIENTATION_NOISE * draws
    q = np.column_stack([np.ones(len(draws)), half])
    return q / np.linalg.norm(q, axis=1, keepdims=True)

