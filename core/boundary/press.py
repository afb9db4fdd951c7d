"""The boundary reading of one recorded press: its deepest taxel frame, the pad's yaw there and the press's depth,
read against boundary templates (:func:`.reading.read_boundary`). Works the same on simulated and real streams."""

from __future__ import annotations

import numpy as np

from palpate.core.boundary.reading import BoundaryReading, NoiseModel, read_boundary
from palpate.core.boundary.templates import BoundaryTemplates
from palpate.core.errors import ValidationError
from palpate.core.perception.press import PressResult
from palpate.core.perception.streams import PressRecording

#: Relative mismatch of the recording's sensel area to the templates' pad that is still the same pad.
AREA_TOLERANCE = 0.02


def yaw_of(quaternion: np.ndarray) -> float:
    """Rotation about the world's z axis of a unit quaternion (w, x, y, z), rad: the heading of its x axis."""
    w, x, y, z = np.asarray(quaternion, dtype=float)
    return float(np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z)))


def read_press(recording: PressRecording, result: PressResult, templates: BoundaryTemplates,
               noise: NoiseModel) -> BoundaryReading | None:
    """The boundary reading of a perceived press (None when no press was found in it).

    The frame read is the one of largest total count (the deepest point of a press-and-release); its yaw is the pose
    sensor's mean heading over the recording (the pad's axes taken as the sensor's). ``noise`` is in counts.

    Raises:
        ValidationError: the recording's pad differs from the templates' (sensel area) or its frames differ in
            shape.
    """
    if result.press is None or not recording.frames or result.depth <= 0:
        return None
    frames = recording.frames
    area = templates.pad.sensel_size**2
    if abs(frames[0].sensel_area - area) > AREA_TOLERANCE * area:
        raise ValidationError(f"read_press: the boundary templates are for sensels of {area * 1e6:.3g} mm^2, the "
                              f"recording's are {frames[0].sensel_area * 1e6:.3g} mm^2; make templates for this pad")
    totals = np.array([float(np.sum(f.counts, dtype=float)) for f in frames])
    k = int(np.argmax(totals))
    # The mean heading over the recording: a press barely turns the finger, and the pose clock may not be the
    # taxel clock (a real rig's tracker counts from its own reset).
    yaws = np.array([yaw_of(p.quaternion) for p in recording.poses])
    yaw = float(np.angle(np.mean(np.exp(1j * yaws)))) if len(yaws) else 0.0
    return read_boundary(frames[k].counts.astype(float), min(result.depth, 0.999 * templates.pad.radius),
                         templates, noise, yaw=yaw)
