"""The streaming signal path (sync + contact features + segmentation, one sample at a time): cost per sample over a
long stream, its growth with the stream's length, and the batch path on the same stream for reference.

Run: .venv/bin/python benchmarks/speed_streaming.py [--quick] [--minutes M]

The stream is synthetic and seeded: a fingertip pressing a soft surface again and again (random depths 1-5 mm,
random pauses, random places), a 4x4 taxel pad at 50 Hz with sensel noise, a pose tracker at 240 Hz with position
noise and one 0.3 s dropout a minute. Frames and poses are fed in time order, as a live session delivers them.
Every call is timed (CPU time); the p50/p99 are over all samples, frames and poses together, and per fifth of the
stream (a cost that grew with the stream would show as a rising row). The presses found must be the batch path's
(``presses_from_recording`` on the whole stream with the same thresholds), bit for bit, before anything is shown.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from palpate.core.perception.pipeline import presses_from_recording
from palpate.core.perception.stream_pipeline import StreamingPipeline
from palpate.core.perception.streams import PoseSample, PressRecording, TaxelFrame

TARGET_P99_MS = 0.2
TAXEL_HZ, POSE_HZ = 50.0, 240.0
PITCH = 2.5e-3  # m
SURFACE = 0.03  # m


def long_stream(minutes: float, seed: int) -> PressRecording:
    """Presses one after another for ``minutes``: heights, counts and poses (see the module docstring)."""
    rng = np.random.default_rng(seed)
    t_end = 60.0 * minutes
    knots_t, knots_z, places = [0.0], [SURFACE + 0.003], [(0.0, 0.0, 0.0)]
    t = 0.5
    while t < t_end - 3.0:
        depth, speed = rng.uniform(0.001, 0.005), rng.uniform(0.006, 0.015)
        travel = (0.003 + depth) / speed
        knots_t += [t, t + travel, t + 2 * travel]
        knots_z += [SURFACE + 0.003, SURFACE - depth, SURFACE + 0.003]
        places.append((t, *rng.uniform(-0.02, 0.02, 2)))
        t += 2 * travel + rng.uniform(0.3, 2.0)
    knots_t.append(t_end + 1.0)
    knots_z.append(SURFACE + 0.003)
    starts = np.array([p[0] for p in places])
    xy = np.array([p[1:] for p in places])

    tf = np.arange(0.0, t_end, 1.0 / TAXEL_HZ)
    depth = np.clip(SURFACE - np.interp(tf, knots_t, knots_z), 0.0, None)
    total = 60.0 * (depth * 1e3) ** 1.5
    r2 = (((np.arange(4) - 1.5) * PITCH)[:, None] ** 2 + ((np.arange(4) - 1.5) * PITCH)[None, :] ** 2).ravel()
    w = np.exp(-r2[None, :] / (2 * 0.01 * np.clip(depth, 1e-6, None)[:, None]))
    counts = total[:, None] * w / w.sum(axis=1, keepdims=True) + 0.6 * rng.standard_normal((len(tf), 16))
    counts = np.clip(np.rint(counts), 0, 255).astype(np.uint8).reshape(-1, 4, 4)
    frames = [TaxelFrame(float(ti), c, PITCH**2) for ti, c in zip(tf, counts, strict=True)]

    tp = np.arange(0.0, t_end + 0.1, 1.0 / POSE_HZ)
    for m in range(int(minutes)):  # one dropout a minute
        tp = tp[(tp < 60.0 * m + 30.0) | (tp > 60.0 * m + 30.3)]
    k = np.clip(np.searchsorted(starts, tp, side="right") - 1, 0, len(starts) - 1)
    pos = np.column_stack([xy[k], np.interp(tp, knots_t, knots_z)]) + 2e-5 * rng.standard_normal((len(tp), 3))
    poses = [PoseSample(float(ti), p) for ti, p in zip(tp, pos, strict=True)]
    return PressRecording(frames, poses)


def stream(rec: PressRecording, thresholds) -> tuple[StreamingPipeline, list, np.ndarray, np.ndarray]:
    """Feed the samples in time order; returns the pipeline, the presses, the CPU time of every call, s, and
    which calls were poses."""
    tf = np.array([f.t for f in rec.frames])
    tp = np.array([p.t for p in rec.poses])
    is_pose = np.argsort(np.concatenate([tf, tp]), kind="stable") >= len(tf)
    pipe = StreamingPipeline(thresholds)
    feed_frame, feed_pose, clock = pipe.feed_frame, pipe.feed_pose, time.process_time_ns
    frames, poses = iter(rec.frames), iter(rec.poses)
    cost = np.empty(len(is_pose))
    presses = []
    for i, pose in enumerate(is_pose.tolist()):
        sample = next(poses) if pose else next(frames)
        t0 = clock()
        out = feed_pose(sample) if pose else feed_frame(sample)
        cost[i] = clock() - t0
        presses += out
    return pipe, presses + pipe.finish(), cost * 1e-9, is_pose


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="a 2-minute stream (default 20 minutes)")
    ap.add_argument("--minutes", type=float, default=None, help="length of the stream, min")
    args = ap.parse_args()
    minutes = args.minutes or (2.0 if args.quick else 20.0)
    rec = long_stream(minutes, seed=7)
    t0 = time.process_time()
    batch = presses_from_recording(rec)
    t_batch = time.process_time() - t0
    pipe, presses, cost, is_pose = stream(rec, batch.thresholds)
    same = len(presses) == len(batch.presses) and all(
        all(np.array_equal(getattr(p, k), v) if isinstance(v, np.ndarray) else getattr(p, k) == v
            for k, v in vars(q).items()) for p, q in zip(presses, batch.presses, strict=True))
    same = same and [(r.index, r.reason) for r in pipe.rejected] == [(r.index, r.reason) for r in batch.rejected]
    if not same:
        raise SystemExit("the streaming presses differ from the batch path's")
    n = len(cost)
    print(f"Streaming sync + features + segmentation, {minutes:g} min: {len(rec.frames)} taxel frames "
          f"({TAXEL_HZ:g} Hz) and {len(rec.poses)} poses ({POSE_HZ:g} Hz), {len(presses)} presses and "
          f"{len(pipe.rejected)} rejected contacts, identical to the batch path's (bit for bit)")
    p50, p99, pmax = np.percentile(cost, [50, 99, 100]) * 1e3
    print(f"per sample, CPU time: p50 {p50:.4f} ms   p99 {p99:.4f} ms   max {pmax:.3f} ms   "
          f"(target p99 <= {TARGET_P99_MS} ms: {'met' if p99 <= TARGET_P99_MS else 'NOT met'})")
    poses_cost, frames_cost = cost[is_pose], cost[~is_pose]
    for name, part in (("taxel frames", frames_cost), ("poses", poses_cost)):
        q50, q99 = np.percentile(part, [50, 99]) * 1e3
        print(f"  {name:<12} p50 {q50:.4f} ms   p99 {q99:.4f} ms")
    print(f"{'part of the stream':<22}{'p50 ms':>10}{'p99 ms':>10}{'mean ms':>10}")
    for k in range(5):
        part = cost[k * n // 5:(k + 1) * n // 5]
        q50, q99 = np.percentile(part, [50, 99]) * 1e3
        print(f"{f'min {k * minutes / 5:.1f}-{(k + 1) * minutes / 5:.1f}':<22}{q50:10.4f}{q99:10.4f}"
              f"{part.mean() * 1e3:10.4f}")
    first, last = cost[: n // 5].mean(), cost[-n // 5:].mean()
    print(f"growth of the mean cost per sample, last fifth / first fifth: {last / first:.2f}")
    print(f"batch path on the whole stream (reference): {t_batch / n * 1e3:.4f} ms per sample on average; "
          f"streaming mean / batch mean: {cost.mean() / (t_batch / n):.2f}")


if __name__ == "__main__":
    main()
