"""Speed and accuracy of the core signal path (sync -> features -> segmentation -> fits) on synthetic streams.

Run: .venv/bin/python benchmarks/signal_path.py [--quick]

Table 1: time per stage for a long recording (50 Hz taxels, 30 Hz poses, one press every 1.4 s).
Table 2: error of the kinesthetic slope n1 (known: 60 counts/mm^1.5) against pose noise, sensel noise and an
error in the clock offset, over many presses; shows what each noise source costs in accuracy.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))

from bench_timing import best_of  # noqa: E402
from synthetic_streams import PressSpec, make_recording  # noqa: E402

from palpate.core.perception.features import contact_features
from palpate.core.perception.pipeline import PipelineConfig, fit_presses, presses_from_recording
from palpate.core.perception.segment import segment_presses
from palpate.core.perception.sync import synchronise

N1 = 60.0


def _specs(n: int, rng: np.random.Generator) -> list[PressSpec]:
    return [PressSpec(0.3 + 1.4 * i, float(rng.uniform(0.002, 0.004)), x=0.01 * (i % 10), y=0.01 * (i // 10))
            for i in range(n)]


def timing_table(n_presses: int, repeats: int) -> None:
    rng = np.random.default_rng(1)
    rec = make_recording(_specs(n_presses, rng), rng=rng, t_end=0.3 + 1.4 * n_presses + 0.2, n1=N1,
                         pose_noise=2e-5, sensel_noise=0.5).recording
    stream = synchronise(rec.frames, rec.poses)
    series = contact_features(stream)
    seg = segment_presses(series)
    n_frames = len(rec.frames)
    rows = [
        ("synchronise", best_of(lambda: synchronise(rec.frames, rec.poses), repeats)),
        ("contact_features", best_of(lambda: contact_features(stream), repeats)),
        ("segment_presses", best_of(lambda: segment_presses(series), repeats)),
        ("fit_presses", best_of(lambda: fit_presses(seg.presses), repeats)),
        ("presses_from_recording + fit", best_of(lambda: fit_presses(presses_from_recording(rec).presses),
                                                  repeats)),
    ]
    print(f"\nTable 1. Time per stage: {n_frames} taxel frames ({n_frames / 50:.0f} s at 50 Hz), {len(rec.poses)} "
          f"poses, {len(seg.presses)} presses found of {n_presses} (best of {repeats})")
    print(f"{'stage':32s} {'total ms':>10s} {'us/frame':>10s} {'x real time':>12s}")
    for name, sec in rows:
        print(f"{name:32s} {sec * 1e3:10.2f} {sec / n_frames * 1e6:10.2f} {n_frames / 50 / sec:12.0f}")


def accuracy_table(n_presses: int) -> None:
    cases = [
        ("clean, 30 Hz poses", {}, 0.0),
        ("clean, 240 Hz poses", {"pose_rate": 240.0}, 0.0),
        ("pose noise 10 um", {"pose_noise": 1e-5}, 0.0),
        ("pose noise 50 um", {"pose_noise": 5e-5}, 0.0),
        ("sensel noise 0.5 count", {"sensel_noise": 0.5}, 0.0),
        ("sensel noise 1.5 count", {"sensel_noise": 1.5}, 0.0),
        ("c_P noise 5 counts", {"intensity_noise": 5.0}, 0.0),
        ("pose 20 um + sensel 0.5", {"pose_noise": 2e-5, "sensel_noise": 0.5}, 0.0),
        ("clock offset error 20 ms", {}, 0.02),
        ("clock offset error 100 ms", {}, 0.1),
    ]
    print(f"\nTable 2. Error of n1 (truth {N1:g} counts/mm^1.5), {n_presses} presses of 2-4 mm at 10 mm/s, 30 Hz poses "
          "unless said")
    print(f"{'condition':28s} {'found':>6s} {'bias %':>8s} {'sd %':>7s} {'max |err| %':>12s} {'median se %':>12s}")
    for name, kw, offset_error in cases:
        rng = np.random.default_rng(2)
        specs = _specs(n_presses, rng)
        # A decelerating press would show the offset error more; constant speed is the common robot case.
        rec = make_recording(specs, rng=rng, t_end=0.3 + 1.4 * n_presses + 0.2, n1=N1, clock_offset=0.1, **kw)
        fits = fit_presses(presses_from_recording(rec.recording,
                                                  PipelineConfig(clock_offset=0.1 + offset_error)).presses)
        err = (np.array([f.n1 for f in fits]) - N1) / N1 * 100
        se = np.array([f.se_n1 for f in fits]) / N1 * 100
        print(f"{name:28s} {len(fits):6d} {err.mean():8.2f} {err.std():7.2f} {np.abs(err).max():12.2f} "
              f"{np.median(se):12.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer presses and repeats")
    args = parser.parse_args()
    timing_table(40 if args.quick else 400, 2 if args.quick else 5)
    accuracy_table(10 if args.quick else 60)


if __name__ == "__main__":
    main()
