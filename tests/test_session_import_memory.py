"""``palpate import session`` streams a Tekscan export as ``palpate import tekscan`` does: its peak memory does not
follow the export's length (measured with tracemalloc on generated exports of the same presses followed by a
resting pad for longer and longer)."""

from __future__ import annotations

import gc
import tracemalloc

import numpy as np
import pytest

from palpate.core.io.mcap_reader import read_recording
from palpate.core.io.mcap_writer import RecordingWriter
from palpate.core.perception.streams import PoseSample
from palpate.hardware.rig.session_import import import_session

PERIOD = 0.02  # s, the pad's frames
OFFSET = -3.0  # s added to the tracker's times to put them on the pad's clock


def _depth_fraction(t: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """0 -> 1 -> 0 over 1.2 s from each start (raised cosine)."""
    u = t[:, None] - starts[None, :]
    return np.where((u >= 0) & (u < 1.2), 0.5 * (1 - np.cos(2 * np.pi * u / 1.2)), 0.0).sum(axis=1)


def _write_session(d, rest: float, size: int = 24, seconds: float = 30.0):
    """A Tekscan export of ``seconds`` of presses then ``rest`` s of a resting pad on a size x size map (the pad at
    1:5,1:5), and the tracker's poses of the presses."""
    rng = np.random.default_rng(1)
    starts = 1.0 + np.cumsum(rng.uniform(1.8, 3.2, int(seconds / 2.5)))
    starts = starts[starts < seconds - 2.0]
    t = np.arange(0.0, seconds + rest, PERIOD)
    pad = np.rint(200 * np.clip(_depth_fraction(t, starts) - 0.3, 0.0, None)).astype(int)
    export = d / f"press{rest:.0f}.csv"
    with open(export, "w", newline="") as f:
        f.write(f"DATA_TYPE MOVIE\r\nROWS {size}\r\nCOLS {size}\r\nROW_SPACING 0.25 cm\r\nCOL_SPACING 0.25 cm\r\n"
                f"SENSEL_AREA 0.0484 sq cm\r\nSECONDS_PER_FRAME {PERIOD}\r\nSTART_FRAME 1\r\nUNITS RAW\r\n"
                "ASCII_DATA @@\r\n\r\n")
        zero = ",".join(["0"] * size)
        inner = ",".join(["0"] * (size - 5))
        for k, v in enumerate(pad):
            row = f"0,{v},{v},{v},{v}," + inner
            f.write(f"Frame {k + 1}\r\n{zero}\r\n" + f"{row}\r\n" * 4 + f"{zero}\r\n" * (size - 5) + "\r\n")
    tp = np.arange(0.0, seconds, 1 / 240.0)
    path = np.column_stack([np.zeros_like(tp), np.zeros_like(tp), 0.05 - 0.005 * _depth_fraction(tp, starts)])
    path += rng.normal(0.0, 1e-4, path.shape)
    poses = d / "liberty.mcap"
    with RecordingWriter(poses, {"scenario": None}) as w:
        for ti, p in zip(tp, path, strict=True):
            w.write_pose(PoseSample(float(ti - OFFSET), p, np.array([1.0, 0.0, 0.0, 0.0]), "liberty_station1"))
    return export, poses


def _peak(export, poses, out) -> int:
    gc.collect()
    tracemalloc.start()
    try:
        summary = import_session(export, poses, out, region="1:5,1:5")
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert summary.clock.to_taxel(10.0 - OFFSET) == pytest.approx(10.0, abs=0.005)
    return peak


def test_peak_memory_does_not_follow_the_export_length(tmp_path):
    # both exports longer than a few of the reader's blocks (1 MB of text), whose parsing sets the steady peak
    small, poses = _write_session(tmp_path, 40.0)
    large, _ = _write_session(tmp_path, 120.0)
    grown = large.stat().st_size - small.stat().st_size  # 4000 frames, ~5 MB more
    peak_small = _peak(small, poses, tmp_path / "small.mcap")
    peak_large = _peak(large, poses, tmp_path / "large.mcap")
    # holding the export costs at least its counts (576 bytes a frame) and a frame object each; streamed, what grows
    # is each frame's time and c_P (16 bytes)
    # (held whole it grew by half the added text; streamed, by 5-11 % of it: the blocks' parse varies with where
    # their boundaries fall)
    assert peak_large - peak_small < 0.25 * grown, (peak_small, peak_large, grown)
    a, b = read_recording(tmp_path / "small.mcap"), read_recording(tmp_path / "large.mcap")
    assert (len(a.frames), len(b.frames)) == (3500, 7500) and len(a.poses) == len(b.poses)
    np.testing.assert_array_equal(np.array([f.counts for f in a.frames]),
                                  np.array([f.counts for f in b.frames[:3500]]))
