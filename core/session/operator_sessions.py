"""The presses a person made, from palpate's own recordings in a folder: one press per file, or a whole session.

A file in the operator's folder is a palpate recording holding both the fingertip's poses and the pad's taxel
frames on one clock: a file made by ``palpate import session`` (a Tekscan export merged with a Liberty recording),
by ``palpate record session`` (pad and tracker recorded live), or any recording of one press. A file whose c_P shows
several contacts holds as many presses, taken in time order, each cut half-way to its neighbours (so its approach and
retreat come with it); a file with one contact or none is one press. Press k of the exploration is the k-th press of
the files in name order. A file with only taxels or only poses (the two halves of a session before they are merged)
is refused with the command that merges them.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from palpate.core.alignment.events import press_windows
from palpate.core.errors import ValidationError
from palpate.core.io.mcap_reader import read_recording
from palpate.core.io.recording import recording_to_press_recording
from palpate.core.perception.streams import GroundTruth, PressRecording


def split_presses(rec: PressRecording, where: str) -> list[PressRecording]:
    """The presses one recording holds (see the module docstring); ValidationError naming ``where`` when it lacks
    poses or taxels."""
    if not rec.frames or len(rec.poses) < 2:
        has = "taxel frames but no fingertip poses" if rec.frames else (
            "fingertip poses but no taxel frames" if rec.poses else "neither taxel frames nor poses")
        raise ValidationError(
            f"{where} holds {has}: a press needs both on one clock. Merge the pad's export and the tracker's "
            "recording first: palpate import session --taxels EXPORT --poses LIBERTY.mcap --out SESSION.mcap")
    t = np.array([f.t for f in rec.frames])
    c_p = np.array([float(f.counts.sum()) for f in rec.frames])
    windows = press_windows(t, c_p)
    if len(windows) == 1:
        return [rec]
    return [_cut(rec, a, b, {**rec.meta, "press_in_file": i + 1, "presses_in_file": len(windows)})
            for i, (a, b) in enumerate(windows)]


def _cut(rec: PressRecording, t0: float, t1: float, meta: dict) -> PressRecording:
    # windows are half-open [t0, t1): a sample exactly on a cut (the middle of two frames an even count apart)
    # belongs to the later press only, so every sample is in exactly one press
    ft = np.array([f.t for f in rec.frames])
    pt = np.array([p.t for p in rec.poses])
    f0, f1 = np.searchsorted(ft, t0, "left"), np.searchsorted(ft, t1, "left")
    p0, p1 = np.searchsorted(pt, t0, "left"), np.searchsorted(pt, t1, "left")
    truth = rec.truth
    if truth is not None:  # a simulated session carries its ground truth: cut it alike
        i0, i1 = np.searchsorted(truth.t, t0, "left"), np.searchsorted(truth.t, t1, "left")
        truth = GroundTruth(truth.t[i0:i1], truth.force[i0:i1], truth.indentation[i0:i1], truth.material) \
            if i1 > i0 else None
    return PressRecording(rec.frames[f0:f1], rec.poses[p0:p1], truth, meta)


@dataclass
class _Cached:
    stamp: tuple[int, int]
    presses: list[PressRecording]


class SessionFolder:
    """The presses of the recordings in a folder, in name order; files are read once (again if they change)."""

    def __init__(self, folder: Path):
        self.folder = Path(folder)
        self._cache: dict[Path, _Cached] = {}

    def files(self) -> list[Path]:
        return sorted(self.folder.glob("*.mcap"))

    def _presses_of(self, path: Path) -> list[PressRecording]:
        st = path.stat()
        stamp = (st.st_mtime_ns, st.st_size)
        cached = self._cache.get(path)
        if cached is None or cached.stamp != stamp:
            rec = recording_to_press_recording(read_recording(path))
            rec.meta = {**rec.meta, "file": str(path)}
            cached = self._cache[path] = _Cached(stamp, split_presses(rec, str(path)))
        return cached.presses

    def press(self, k: int) -> tuple[PressRecording | None, int]:
        """(press k, 0-based, or None if the folder does not hold that many yet; how many presses it holds)."""
        seen = 0
        for path in self.files():
            presses = self._presses_of(path)
            if k < seen + len(presses):
                return presses[k - seen], seen + len(presses)
            seen += len(presses)
        return None, seen
