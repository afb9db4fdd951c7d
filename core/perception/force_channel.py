"""c_P from a force instead of a tactile pad: a one-sensel "pad" whose counts are newtons in fixed steps.

A finger with no tactile pad measures the fingertip force (a Dynamixel finger: from its joint currents). The force
travels through recordings, replay and segmentation as taxel frames of one sensel, ``count = force / FORCE_QUANTUM``,
and a press of it is perceived with ``PERCEPTION``: c_P calibrated in N (``FORCE_QUANTUM`` N per count) and the
kinesthetic law alone (there is no contact area), which the haptic memory then judges by its kinesthetic model.
A memory for such presses is trained the same way: the simulation's presses perceived through their true contact
force (:func:`with_force_channel`), as the finger would have measured it, not through the simulated pad.
"""

from __future__ import annotations

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.perception.streams import PressRecording, TaxelFrame

#: N per count of the force channel: finer than a Dynamixel's current step at the tip (~0.1 N); 255 counts = 12.75 N.
FORCE_QUANTUM = 0.05
#: The channel's one sensel has an area only because a TaxelFrame needs one; c_A is not used.
FORCE_SENSEL_AREA = 1e-4
SENSOR_ID = "joint_force"
#: How a press of the force channel is perceived (its metadata ``session.perception``).
PERCEPTION = {"channel": "force", "calibration_n_per_count": FORCE_QUANTUM, "features": "kinesthetic"}


def force_frames(t, force) -> list[TaxelFrame]:
    """Frames of the force channel at times ``t`` (s, increasing) for normal forces ``force`` (N, clipped at 0 and
    at 255 quanta)."""
    t = np.asarray(t, dtype=float)
    force = np.asarray(force, dtype=float)
    if t.shape != force.shape or not (np.all(np.isfinite(t)) and np.all(np.isfinite(force))):
        raise ValidationError("force channel: times and forces must be finite arrays of one length")
    counts = np.clip(np.rint(force / FORCE_QUANTUM), 0, 255).astype(np.uint8)
    return [TaxelFrame(float(ti), np.array([[c]], dtype=np.uint8), FORCE_SENSEL_AREA, SENSOR_ID)
            for ti, c in zip(t, counts, strict=True)]


def with_force_channel(rec: PressRecording) -> PressRecording:
    """A simulated press with its taxel frames replaced by the force channel of its true contact force (at the same
    frame times), and marked to be perceived so."""
    if rec.truth is None or not rec.frames:
        raise ValidationError("force channel: the press has no ground-truth force to measure (a simulated press is "
                              "needed)")
    t = np.array([f.t for f in rec.frames])
    force = np.interp(t, rec.truth.t, rec.truth.force)
    meta = {**rec.meta, "session": {**(rec.meta.get("session") or {}), "perception": dict(PERCEPTION)}}
    return PressRecording(force_frames(t, force), rec.poses, rec.truth, meta)
