"""Sessions from separate devices: how well ``palpate import session`` finds the clock map and keeps each press.

Run: ``.venv/bin/python benchmarks/session_alignment.py [--quick] [--seeds 20-29]``. For each seed, the simulation
presses three blocks (60, 200, 600 kPa) 15 times in a shuffled order at irregular intervals (human-like
variability); a Tekscan-like pad (50 Hz) and a Liberty-like tracker (240 Hz, 0.1 mm noise) record them on clocks
1.7 s and 50 ppm apart, the tracker in a frame turned 110 degrees and tilted 30 degrees from the grid's, with a touch
recording for the workspace (``tests/rig_session.py`` builds all of it, as the tests do). The session is imported
(Tekscan ASCII export + Liberty MCAP) and perceived; the table gives per seed: the largest error of the clock map
over the session's pose times, the estimated drift, presses found, the largest c_D difference from the one-clock run
(the same perception on each press's own streams), the largest c_D difference from the simulation's true
indentation (the one-clock run's own, for comparison), and whether every press is classified as the one-clock run
classified it.

The estimator's settings (match tolerance, fine search, outlier rule) were developed on seed 7 (the tests' seed)
and 8-9; seeds 20 and up were never looked at while tuning.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
import rig_session as rs  # noqa: E402  (the tests' session builder)

from palpate.core.alignment.clock import ClockMap  # noqa: E402
from palpate.core.cli import main as palpate  # noqa: E402
from palpate.core.io.mcap_reader import read_recording  # noqa: E402

OFFSET, DRIFT_PPM = 1.7, 50.0


def one(seed: int, memory, folder: Path) -> dict:
    s = rs.simulate(memory, seed=seed)
    rs.write_tekscan(folder / "press.csv", s)
    rs.write_liberty(folder / "liberty.mcap", rs.liberty_times(s.pose_t, OFFSET, DRIFT_PPM), s.pose_p, s.pose_q)
    t, p, q = rs.touches(np.random.default_rng(seed))
    rs.write_liberty(folder / "touches.mcap", rs.liberty_times(t, 500.0, DRIFT_PPM), p, q)
    out = folder / "session.mcap"
    with contextlib.redirect_stdout(io.StringIO()):
        code = palpate(["import", "session", "--taxels", str(folder / "press.csv"), "--region", "1:5,1:5",
                        "--poses", str(folder / "liberty.mcap"), "--calibration", str(folder / "touches.mcap"),
                        "--out", str(out)])
    if code != 0:
        return {"seed": seed, "error": f"import exited {code}"}
    c = read_recording(out).metadata["session"]["clock"]
    cmap = ClockMap(offset=c["offset_s"], rate=c["rate"], t_ref=c["t_ref_s"])
    err = cmap.to_taxel(rs.liberty_times(s.pose_t, OFFSET, DRIFT_PPM)) - s.pose_t
    labels, depths, _ = rs.perceived_labels(memory, out)
    found = len(depths) == len(s.sim_depth)
    return {"seed": seed, "clock_ms": 1e3 * float(np.max(np.abs(err))), "drift": c["drift_ppm"],
            "drift_std": 1e6 * (c["rate_std"] or 0.0), "presses": f"{len(depths)}/{len(s.sim_depth)}",
            "cd_run_mm": 1e3 * float(np.max(np.abs(depths - s.sim_depth))) if found else float("nan"),
            "cd_truth_mm": 1e3 * float(np.max(np.abs(depths - s.truth_depth))) if found else float("nan"),
            "run_truth_mm": 1e3 * float(np.max(np.abs(s.sim_depth - s.truth_depth))),
            "same_class": found and labels == s.sim_labels}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="three seeds")
    ap.add_argument("--seeds", default="20-29", help="seed range A-B (default 20-29, not used in tuning)")
    args = ap.parse_args()
    a, b = (int(v) for v in args.seeds.split("-"))
    seeds = list(range(a, b + 1))[: 3 if args.quick else None]
    memory = rs.train_memory()
    print(f"{'seed':>4} {'clock max err ms':>16} {'drift ppm':>14} {'presses':>8} {'c_D vs run mm':>13} "
          f"{'c_D vs truth mm':>15} {'run vs truth mm':>15} {'same class':>10}")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for seed in seeds:
            folder = Path(tmp) / f"seed{seed}"  # one folder per seed: import session never overwrites its --out
            folder.mkdir()
            r = one(seed, memory, folder)
            rows.append(r)
            if "error" in r:
                print(f"{seed:>4} {r['error']}")
                continue
            print(f"{seed:>4} {r['clock_ms']:>16.2f} {r['drift']:>7.1f} +- {r['drift_std']:>4.0f} {r['presses']:>8} "
                  f"{r['cd_run_mm']:>13.3f} {r['cd_truth_mm']:>15.3f} {r['run_truth_mm']:>15.3f} "
                  f"{str(r['same_class']):>10}")
    ok = [r for r in rows if "error" not in r]
    if ok:
        print(f"all seeds: clock error max {max(r['clock_ms'] for r in ok):.2f} ms (requirement 10 ms); c_D vs the "
              f"one-clock run max {max(r['cd_run_mm'] for r in ok):.3f} mm (0.2 mm); same classes in "
              f"{sum(r['same_class'] for r in ok)}/{len(ok)} sessions; true drift {DRIFT_PPM:.0f} ppm")
    if len(ok) < len(rows):
        sys.exit(f"{len(rows) - len(ok)} of {len(rows)} sessions failed")


if __name__ == "__main__":
    main()
