"""Batched analytic presses against the one-at-a-time loop, measured in one run.

Three workloads, each at N = 1, 16, 64 and 256 presses:

- ``robot``: one SimSource pressing three 300 mm blocks (30, 150, 600 kPa) at five depths in turn, as a training
  protocol does: ``[source.press(t) for t in targets]`` against ``source.press_many(targets)``;
- ``human``: the same with the human press (lateral jitter, depth and speed spread) and the ``thesis_ch6``
  realism profile (the shipped main job's training presses);
- ``specs``: N presses of :func:`palpate.sim.simulate_press` on blocks of three materials, four depths and N seeds,
  against :func:`palpate.sim.batch.simulate_presses` of the same specs (each spec a fresh source, as
  simulate_press makes: the loop solves a contact law per press, the batch once per distinct robot press).

Every source's contact laws are solved before timing (a shared, warmed law cache), except in ``specs``, whose
point is the law each fresh press solves. Rounds interleave loop and batch, so the machine's load hits both alike;
each prints the median CPU time (``time.process_time``) per press and the throughput ratio loop / batch. The
batch's results equal the loop's (tests/test_sim_batch.py); this script checks it again on the first round. The
floor is what a batch equal to the loop cannot vectorise away (:func:`floor_workload`: each press's seeds and noise
generators, its frame, pose and recording objects), timed in the same rounds: loop / floor bounds the ratio.

Run: .venv/bin/python benchmarks/speed_batch.py [--rounds 5] [--quick]
"""

from __future__ import annotations

import argparse
import gc
import time

import numpy as np

from palpate.core.session.sources import PressTarget
from palpate.core.world.scene import Material, ObjectSpec, Scene
from palpate.sim.api import simulate_press
from palpate.sim.batch import PressSpec, simulate_presses
from palpate.sim.source import SimSource

MATERIALS = (Material("soft", 30e3, 0.45), Material("mid", 150e3, 0.4), Material("hard", 600e3, 0.3))


def blocks() -> Scene:
    """Three 300 mm blocks 40 mm thick, 400 mm apart (no edge within a press's reach)."""
    return Scene(tuple(ObjectSpec(f"b{i}", "box", (0.3, 0.3, 0.04), (0.4 * i, 0.0), m)
                       for i, m in enumerate(MATERIALS)))


def targets(n: int) -> list[PressTarget]:
    return [PressTarget(0.4 * (k % 3), 0.0, depth=0.002 + 0.0005 * (k % 5), speed=0.01) for k in range(n)]


def source_workload(variability: str, realism: str | None, n: int, laws: dict):
    """(loop, batch) callables of one source workload, on sources sharing the warmed ``laws``."""
    scene, tg = blocks(), targets(n)

    def make():
        return SimSource(scene, fidelity="analytic", seed=5, variability=variability, realism=realism, laws=laws)

    make().press_many(tg)  # solves every law these presses need

    def loop():
        src = make()
        return [src.press(t) for t in tg]

    def batch():
        return make().press_many(tg)

    return loop, batch


def spec_workload(n: int):
    specs = [PressSpec(m.young, m.poisson, "analytic", depth=0.002 + 0.0005 * (k % 4), seed=k)
             for k, m in zip(range(n), [MATERIALS[k % 3] for k in range(n)], strict=True)]

    def loop():
        return [simulate_press(s.young, s.poisson, s.fidelity, s.depth, s.speed, s.seed) for s in specs]

    def batch():
        return simulate_presses(specs)

    return loop, batch


def same(a, b) -> bool:
    return all(len(x.frames) == len(y.frames) and all(np.array_equal(f.counts, g.counts) and f.t == g.t
                                                      for f, g in zip(x.frames, y.frames, strict=True))
               and all(np.array_equal(p.position, q.position) for p, q in zip(x.poses, y.poses, strict=True))
               for x, y in zip(a, b, strict=True))


def floor_workload(recordings: list):
    """What any batch whose recordings equal the loop's must still do per press, whatever it vectorises: draw the
    press's seeds and make its noise generators (each press's own stream, as SimSource._plan and the sensors do),
    and hand out its frames, poses, ground truth and recording (the objects a PressRecording is made of), from the
    arrays of ``recordings`` (a batch's output). Its time bounds the ratio a batch can reach: loop / floor."""
    from palpate.core.perception.streams import (
        GroundTruth,
        PressRecording,
        frames_to_arrays,
        pose_samples,
        pose_times_positions,
        taxel_frames,
    )

    arrays = [(*frames_to_arrays(r.frames), *pose_times_positions(r.poses), np.array([p.quaternion for p in r.poses]),
               r.truth) for r in recordings]

    def floor():
        out = []
        gc.disable()  # as the batch does while it builds its recordings
        for k, (tf, counts, area, tp, pos, quat, truth) in enumerate(arrays):
            _, s_taxel, s_pose, _ = np.random.SeedSequence([5, k]).spawn(4)
            np.random.default_rng(s_taxel), np.random.default_rng(s_pose)
            out.append(PressRecording(frames=taxel_frames(tf, counts, area), poses=pose_samples(tp, pos, quat),
                                      truth=GroundTruth(truth.t.copy(), truth.force.copy(),
                                                        truth.indentation.copy(), truth.material), meta={}))
        gc.enable()
        return out

    return floor


def cpu(fn):
    t0 = time.process_time()
    out = fn()
    return time.process_time() - t0, out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--quick", action="store_true", help="N = 1, 16, 64 only, 3 rounds")
    args = ap.parse_args()
    sizes = (1, 16, 64) if args.quick else (1, 16, 64, 256)
    rounds = 3 if args.quick else args.rounds
    print(f"{'workload':9s} {'N':>4s} {'loop ms/press':>14s} {'batch ms/press':>15s} {'ratio':>6s}  equal  "
          f"{'floor ms/press':>14s} {'loop / floor':>12s}")
    for name in ("robot", "human", "specs"):
        for n in sizes:
            if name == "specs":
                loop, batch = spec_workload(n)
            else:
                loop, batch = source_workload("robot" if name == "robot" else "human",
                                              None if name == "robot" else "thesis_ch6", n, {})
            tl, tb, tf, equal, floor = [], [], [], None, None
            for r in range(rounds):
                a, ra = cpu(loop)
                b, rb = cpu(batch)
                if r == 0:
                    equal = same(ra, rb)
                    floor = floor_workload(rb)
                tl.append(a)
                tb.append(b)
                tf.append(cpu(floor)[0])
            ml, mb, mf = (float(np.median(x)) / n for x in (tl, tb, tf))
            print(f"{name:9s} {n:4d} {ml * 1e3:14.3f} {mb * 1e3:15.3f} {ml / mb:6.1f}  {equal!s:5s}  "
                  f"{mf * 1e3:14.3f} {ml / mf:12.1f}")


if __name__ == "__main__":
    main()
