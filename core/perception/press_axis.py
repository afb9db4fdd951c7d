"""The press axis of each press taken from the press itself: the direction the fingertip moved while in contact.

A robot presses along the axis it was told; a person presses roughly along the surface normal, and a tracker on the
fingertip reports positions in its own frame, which need not have its z along that normal. Indentation measured
along a fixed axis tilted by theta from the real press direction is short by a factor cos(theta) (6% at 20
degrees: 0.24 mm of a 4 mm press). Measured along the motion of the press, it is right whatever the tracker's
orientation.

For each contact found on c_P (the same hysteresis as the segmentation), the axis is the principal direction of the
fingertip positions during the contact (first contact to release: in, and out the same way), pointing from the
first contact towards the deepest point. The height along that axis replaces the series' height from the previous
release to this release, so each press's first-contact height and indentation are measured along its own motion.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from palpate.core.perception.features import ContactSeries
from palpate.core.perception.segment import Thresholds, contact_intervals

# Fewest in-contact pose samples from which a direction is taken; below, the series' own axis is kept.
MIN_AXIS_SAMPLES = 4


def motion_axis(positions: np.ndarray, deepest: int) -> np.ndarray | None:
    """Unit direction of the motion of ``positions`` (n, 3), m, oriented from the first towards row ``deepest``;
    None when the points do not move (a direction cannot be told from noise)."""
    p = np.asarray(positions, dtype=float)
    if len(p) < MIN_AXIS_SAMPLES:
        return None
    centred = p - p.mean(axis=0)
    _, s, vt = np.linalg.svd(centred, full_matrices=False)
    if s[0] <= 0:
        return None
    axis = vt[0]
    if np.dot(p[deepest] - p[0], axis) < 0:
        axis = -axis
    return axis


def heights_along_motion(series: ContactSeries, position: np.ndarray, thresholds: Thresholds) -> ContactSeries:
    """The series with each press's height measured along that press's motion (see the module docstring).

    Args:
        series: contact features (its height along a fixed axis).
        position: fingertip position at each sample, m, shape (n, 3) (the synchronised stream's).
        thresholds: the hysteresis levels the segmentation will use (so both find the same contacts).
    """
    position = np.asarray(position, dtype=float)
    height = np.array(series.height, dtype=float, copy=True)
    start = 0
    for onset, release in contact_intervals(series.c_P, thresholds.on, thresholds.off):
        if onset < 0 or release is None:
            start = release or start
            continue
        window = np.arange(onset, release + 1)
        window = window[series.valid[window]]
        if len(window) >= MIN_AXIS_SAMPLES:
            deepest = int(np.argmax(series.c_P[window]))
            axis = motion_axis(position[window], deepest)
            if axis is not None:
                height[start:release + 1] = -(position[start:release + 1] @ axis)
        start = release
    return replace(series, height=height)
