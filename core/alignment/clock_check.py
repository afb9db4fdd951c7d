"""A clock map given by the user, checked against the presses both devices saw, as an estimate is checked: the
poses mapped by it must meet the c_P peaks and agree finely on it. A tracker recording of other presses fails."""

from __future__ import annotations

import numpy as np

from palpate.core.alignment.clock import MATCH_TOLERANCE, TIE_RESIDUAL, ClockMap, _fine_map, check_overlap
from palpate.core.alignment.events import contacts, reversals
from palpate.core.errors import ValidationError
from palpate.core.perception.streams import PoseSample, TaxelFrame, frames_to_arrays, poses_to_arrays


def check_clock_map(frames: list[TaxelFrame], poses: list[PoseSample], cmap: ClockMap) -> int:
    """Check a given clock map against the presses: the number of presses that confirm it, or ValidationError.

    With the poses mapped by ``cmap``, each c_P peak inside the mapped pose span must meet a reversal of the
    fingertip within the match tolerance (at least half of them, and two), and the fine offsets of the paired
    presses must agree on one map (rms within ``TIE_RESIDUAL``): what the estimate asks of its own answer. Poses of
    other presses meet few peaks, and those they meet disagree finely.
    """
    t, counts, _ = frames_to_arrays(frames)
    tp, pos, _ = poses_to_arrays(poses)
    return check_clock_map_arrays(t, counts.reshape(len(t), -1).sum(axis=1, dtype=np.int64).astype(float), tp, pos,
                                  cmap)


def check_clock_map_arrays(t: np.ndarray, c_p: np.ndarray, tp: np.ndarray, pos: np.ndarray, cmap: ClockMap) -> int:
    """:func:`check_clock_map` from arrays (frame times s and c_P; pose times s and positions m)."""
    t, c_p = np.asarray(t, dtype=float), np.asarray(c_p, dtype=float)
    check_overlap(cmap, tp, t)
    mapped = cmap.to_taxel(tp)
    found = [c for c in contacts(t, c_p) if mapped[0] <= c.t_peak <= mapped[-1]]
    revs = np.sort([r.t for r in reversals(mapped, pos)])
    if not found or len(revs) == 0:
        raise ValidationError(f"the given clock map pairs no press: {len(found)} contact(s) in the pose span, "
                              f"{len(revs)} reversal(s) of the fingertip; the files may not be of the same presses")
    near = np.min(np.abs(np.array([c.t_peak for c in found])[:, None] - revs[None, :]), axis=1)
    pairs = [c for c, d in zip(found, near, strict=True) if d <= MATCH_TOLERANCE]
    if len(pairs) < max(2, 0.5 * len(found)):
        raise ValidationError(f"the given clock offset pairs {len(pairs)} of {len(found)} presses with reversals of "
                              "the fingertip; the files are not of the same presses, or the offset is wrong")
    try:
        fit = _fine_map(t, c_p, mapped, pos, 0.0, pairs)
    except ValidationError as exc:
        raise ValidationError(f"the given clock offset does not hold finely: {exc}") from None
    if fit.residual is not None and fit.residual > TIE_RESIDUAL:
        raise ValidationError(f"the given clock offset pairs {len(pairs)} presses but their fine offsets disagree "
                              f"(rms {fit.residual * 1e3:.0f} ms); the files are not of the same presses")
    return fit.presses
