"""Sensor models: a physics trace sampled into the streams a Tekscan pad and a Polhemus tracker give.

Taxels: at ``rate`` Hz, the mean pressure over each sensel (Pa) times the gain (counts/Pa), plus seeded Gaussian
noise, rounded to integers, saturated at 255, and readings at or below the threshold reported as 0.
Pose: at ~``rate`` Hz with Gaussian sample-time jitter, the tip position plus seeded sub-millimetre noise and a
small orientation noise; both sensors stamp samples on their own clock (simulation time + clock offset).
Ground truth (force, indentation) is copied beside them at the physics rate.

A realism profile (:mod:`palpate.sim.realism`) may add the pad's non-ideal response (a ``response`` applied to the
sensel pressures before the counts) and the tracker's latency; without them the models are exactly the above.
"""

from __future__ import annotations

import numpy as np

from palpate.core.errors import SimulationDiverged
from palpate.core.perception.streams import GroundTruth, PoseSample, TaxelFrame, pose_samples, taxel_frames
from palpate.core.world.scene import FingertipSpec, PoseSensorSpec, TaxelSensorSpec
from palpate.sim.trace import PhysicsTrace, bracket, frame_times

#: Orientation noise of the pose model, rad (Polhemus Liberty: ~0.0012 deg static accuracy; 0.15 deg is generous).
ORIENTATION_NOISE = np.deg2rad(0.15)


def _interp_rows(t_query: np.ndarray, t: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Linear interpolation of (n, ...) values at t_query, vectorised over the trailing axes."""
    flat = values.reshape(len(t), -1)
    idx, w = bracket(t_query, t)
    w = w[:, None]
    out = flat[idx] * (1.0 - w) + flat[idx + 1] * w
    return out.reshape((len(t_query),) + values.shape[1:])


def taxel_counts(pressure: np.ndarray, spec: TaxelSensorSpec, rng: np.random.Generator) -> np.ndarray:
    """Raw 8-bit counts from mean sensel pressures (Pa), shape preserved, dtype uint8."""
    p = np.asarray(pressure, dtype=float)
    if not np.all(np.isfinite(p)):
        raise SimulationDiverged("non-finite sensel pressure reached the taxel model; reduce the timestep")
    raw = p * spec.gain
    if spec.noise_std > 0:
        raw = raw + spec.noise_std * rng.standard_normal(p.shape)
    counts = np.clip(np.rint(raw), 0, 255)
    counts[counts <= spec.threshold] = 0
    return counts.astype(np.uint8)


def sample_taxels(
    trace: PhysicsTrace, spec: TaxelSensorSpec, tip: FingertipSpec, rng: np.random.Generator,
    sensor_id: str = "taxels", response=None,
) -> list[TaxelFrame]:
    """Taxel frames at ``spec.rate`` Hz over the trace, stamped on the sensor clock (t + clock_offset).

    ``response(t, pressure) -> pressure`` (Pa, shape (n, rows, cols)), when given, is what the pad reports of the
    true sensel pressures at the frame times (e.g. :class:`palpate.sim.realism.taxels.TaxelResponse`).
    """
    trace.check_finite()
    t_sim = frame_times(trace.t, spec.rate)
    pressure = _interp_rows(t_sim, trace.t, trace.sensel_pressure)
    if response is not None:
        pressure = response(t_sim, pressure)
    return taxel_frames(t_sim + spec.clock_offset, taxel_counts(pressure, spec, rng), tip.sensel_area, sensor_id)


def _small_rotation(rng: np.random.Generator, n: int, std: float) -> np.ndarray:
    """n random unit quaternions (w, x, y, z) of small rotations with per-axis angle std (rad)."""
    half = 0.5 * std * rng.standard_normal((n, 3))
    q = np.column_stack([np.ones(n), half])
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def _quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product of quaternion arrays (n, 4), (w, x, y, z)."""
    aw, ax, ay, az = a.T
    bw, bx, by, bz = b.T
    return np.column_stack([
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    ])


def sample_poses(
    trace: PhysicsTrace, spec: PoseSensorSpec, rng: np.random.Generator, sensor_id: str = "pose",
    latency: float = 0.0,
) -> list[PoseSample]:
    """Pose samples at ~``spec.rate`` Hz with time jitter, position/orientation noise, on the tracker clock.

    The sample is taken at the jittered simulation time and stamped with that time + clock_offset, as a tracker
    stamps its own samples; jitter stays below a quarter period, so stamps increase strictly. With a ``latency``
    (s), a sample stamped t shows the finger where it was at t - latency (clamped to the trace).
    """
    trace.check_finite()
    period = 1.0 / spec.rate
    n = int(np.floor((trace.t[-1] - trace.t[0]) / period + 1e-9)) + 1
    nominal = trace.t[0] + np.arange(n) * period
    t_true = nominal + (spec.jitter * rng.standard_normal(n) if spec.jitter > 0 else 0.0)
    # clamp the first and last sample into the trace rather than extrapolate
    t_true = np.clip(t_true, trace.t[0], trace.t[-1])
    keep = np.concatenate([[True], np.diff(t_true) > 0])
    t_true = t_true[keep]
    t_seen = t_true if latency == 0 else np.clip(t_true - latency, trace.t[0], trace.t[-1])
    pos = _interp_rows(t_seen, trace.t, trace.tip_position)
    if spec.noise_std > 0:
        pos = pos + spec.noise_std * rng.standard_normal(pos.shape)
    quat = _interp_rows(t_seen, trace.t, trace.tip_quaternion)
    quat = _quat_mul(quat, _small_rotation(rng, len(t_true), ORIENTATION_NOISE))
    return pose_samples(t_true + spec.clock_offset, pos, quat, sensor_id)


def ground_truth(trace: PhysicsTrace) -> GroundTruth:
    """Ground truth beside the streams, on simulation time: force (N), indentation (m), material."""
    trace.check_finite()
    return GroundTruth(t=trace.t.copy(), force=trace.force.copy(), indentation=trace.indentation.copy(),
                       material=trace.material)
