"""Speed of ``palpate replay``: reading a recording and rebuilding its maps, against a plain MCAP reader.

Run: ``.venv/bin/python benchmarks/speed_replay.py`` (records ``scenarios/heterogeneous.toml`` first, ~15 s), or
``--recording rec.mcap --memory memory.json`` for a recording you have. Prints, best of ``--repeat`` runs in CPU
time of this process:

- plain: the ``mcap`` package's own reader (``make_reader(...).iter_messages()``) with ``json.loads`` of every
  message: the least any reader of this file can do, written independently of palpate;
- read: :func:`read_recording` (bounded record parsing, every message decoded and validated into typed samples);
- replay: :func:`replay_recording` without figures (read + perception of every press + map updates + outputs);
- read at twice the size: the same recording written twice end to end, to show the reading is linear (time per
  message at 1x and 2x).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from palpate.core.io.mcap_reader import read_recording
from palpate.core.io.mcap_writer import RecordingWriter
from palpate.core.perception.memory import HapticMemory
from palpate.core.session.replay import replay_recording

ROOT = Path(__file__).resolve().parent.parent


def cpu_best(fn, repeat: int) -> float:
    best = float("inf")
    for _ in range(repeat):
        t = time.process_time()
        fn()
        best = min(best, time.process_time() - t)
    return best


def plain_read(path: Path) -> int:
    """Every message through the mcap package's reader and json.loads (independent of palpate)."""
    from mcap.reader import make_reader

    n = 0
    with open(path, "rb") as f:
        for _, _, message in make_reader(f).iter_messages():
            json.loads(message.data)
            n += 1
    return n


def doubled(path: Path, out: Path) -> Path:
    """The recording twice, the second copy shifted after the first (same messages, twice as many)."""
    rec = read_recording(path)
    shift = max(rec.frames[-1].t, rec.poses[-1].t) + 10.0
    with RecordingWriter(out, rec.metadata) as w:
        for dt in (0.0, shift):
            for a in rec.annotations:
                w.write_annotation(a.t + dt, a.kind, a.data)
            for fr in rec.frames:
                w.write_taxel(type(fr)(fr.t + dt, fr.counts, fr.sensel_area, fr.sensor_id))
            for p in rec.poses:
                w.write_pose(type(p)(p.t + dt, p.position, p.quaternion, p.sensor_id))
            if rec.truth is not None:
                w.write_truth(rec.truth.t + dt, rec.truth.force, rec.truth.indentation, rec.truth.material)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--recording", type=Path, help="an existing recording (default: record heterogeneous.toml)")
    ap.add_argument("--memory", type=Path, help="the memory of that run (memory.json)")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        if args.recording is None:
            rec_path, run = tmp / "rec.mcap", tmp / "run"
            print("recording scenarios/heterogeneous.toml ...", file=sys.stderr, flush=True)
            palpate = Path(sys.executable).with_name("palpate")
            subprocess.run([str(palpate), "run", str(ROOT / "scenarios/heterogeneous.toml"), "--record",
                            str(rec_path), "--out", str(run), "--quiet"], check=True)
            memory_path = run / "memory.json"
        else:
            rec_path, memory_path = args.recording, args.memory
            if memory_path is None:
                ap.error("--memory is required with --recording")
        memory = HapticMemory.load(memory_path)
        n = plain_read(rec_path)
        plain = cpu_best(lambda: plain_read(rec_path), args.repeat)
        read = cpu_best(lambda: read_recording(rec_path), args.repeat)
        replay = cpu_best(lambda: replay_recording(rec_path, memory, tmp / "replay", figures=False), args.repeat)
        twice = doubled(rec_path, tmp / "twice.mcap")
        read2 = cpu_best(lambda: read_recording(twice), args.repeat)
        size = rec_path.stat().st_size
        print(f"recording: {rec_path.name}, {size / 1e6:.1f} MB, {n} messages")
        print(f"{'':34}{'CPU s':>8}{'x plain':>9}")
        print(f"{'plain mcap reader + json.loads':34}{plain:8.3f}{1.0:9.2f}")
        print(f"{'palpate read_recording':34}{read:8.3f}{read / plain:9.2f}")
        print(f"{'palpate replay (no figures)':34}{replay:8.3f}{replay / plain:9.2f}")
        print(f"linearity: read {1e6 * read / n:.1f} us/message at 1x, {1e6 * read2 / (2 * n):.1f} us/message at 2x "
              f"({read2 / read:.2f}x the time for 2x the messages)")


if __name__ == "__main__":
    main()
