"""Placing the tracker's frame on the workspace grid.

The map grid has its origin at a corner of the object, x and y along its edges, z up (out of the surface). A pose
tracker reports positions in its own frame (its source's axes, wherever the source stands). A
:class:`WorkspaceTransform` ``p_grid = R p_tracker + t`` maps one onto the other; it comes either from a file
(rotation and translation written out) or from three touches of the fingertip on the surface:

1. the grid's origin,
2. a point on the grid's +x axis (the farther, the better the angle: 5 cm or more),
3. any point of the surface on the +y side of the x axis.

Record them with the tracker (``palpate record liberty ... --out touches.mcap``), holding the fingertip still for a
second on each point and lifting it between them: :func:`touches_from_poses` finds the three rests in time order.
The touched points define the grid's z = 0 at the height the tracked point had while touching (for a sensor on the
fingertip, the pad rests on the surface there), so the heights of a session are heights above the surface.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.perception.streams import PoseSample, poses_to_arrays

#: A rest: the fingertip within REST_RADIUS (m) of its mean position for at least REST_SECONDS.
REST_RADIUS = 0.0015
REST_SECONDS = 0.6
#: Touches closer than this (m) cannot give an axis.
MIN_BASELINE = 0.01


@dataclass(frozen=True)
class WorkspaceTransform:
    """``p_grid = rotation @ p_tracker + translation`` (m).

    Attributes:
        rotation: proper rotation matrix, shape (3, 3).
        translation: m, shape (3,).
        source: where it came from (a file, "touches", "identity").
    """

    rotation: np.ndarray
    translation: np.ndarray
    source: str = "identity"

    def __post_init__(self) -> None:
        r = np.asarray(self.rotation, dtype=float)
        t = np.asarray(self.translation, dtype=float).reshape(-1)
        if r.shape != (3, 3) or t.shape != (3,) or not (np.all(np.isfinite(r)) and np.all(np.isfinite(t))):
            raise ValidationError(f"workspace transform ({self.source}): rotation must be 3x3 and translation 3 "
                                  "finite numbers")
        if not (np.allclose(r @ r.T, np.eye(3), atol=1e-6) and np.linalg.det(r) > 0):
            raise ValidationError(f"workspace transform ({self.source}): rotation is not a proper rotation matrix "
                                  "(orthonormal rows, determinant +1)")
        object.__setattr__(self, "rotation", r)
        object.__setattr__(self, "translation", t)

    @property
    def quaternion(self) -> np.ndarray:
        """The rotation as a unit quaternion (w, x, y, z)."""
        return matrix_to_quaternion(self.rotation)

    def apply(self, poses: list[PoseSample]) -> list[PoseSample]:
        """Poses in the grid frame (positions moved, orientations turned), times and ids unchanged."""
        if not poses:
            return []
        _, pos, quat = poses_to_arrays(poses)
        pos = pos @ self.rotation.T + self.translation
        quat = quat_multiply(np.broadcast_to(self.quaternion, quat.shape), quat)
        return [PoseSample(p.t, x, q, p.sensor_id) for p, x, q in zip(poses, pos, quat, strict=True)]

    def to_dict(self) -> dict:
        """JSON-ready: ``{"rotation": 3x3, "translation_m": [x, y, z], "source": ...}``."""
        return {"rotation": self.rotation.tolist(), "translation_m": self.translation.tolist(), "source": self.source}


IDENTITY = WorkspaceTransform(np.eye(3), np.zeros(3))


def transform_from_dict(data, where: str) -> WorkspaceTransform:
    """A transform from ``{"rotation": [[...] x3], "translation_m": [x, y, z]}``; errors name ``where``."""
    if not isinstance(data, dict) or "rotation" not in data or "translation_m" not in data:
        raise ValidationError(f"{where}: expected an object with 'rotation' (3x3) and 'translation_m' ([x, y, z] m)")
    try:
        r = np.array(data["rotation"], dtype=float)
        t = np.array(data["translation_m"], dtype=float)
    except (TypeError, ValueError):
        raise ValidationError(f"{where}: 'rotation' and 'translation_m' must hold numbers") from None
    return WorkspaceTransform(r, t, str(where))


def read_transform(path) -> WorkspaceTransform:
    """A workspace transform JSON file (see :meth:`WorkspaceTransform.to_dict`)."""
    path = Path(path)
    try:
        if path.stat().st_size > 1 << 16:
            raise ValidationError(f"{path}: a workspace transform is a few hundred bytes; this file is larger")
        data = json.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise ValidationError(f"{path}: cannot read workspace transform: {exc.strerror}") from None
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValidationError(f"{path}: not a JSON workspace transform: {exc}") from None
    return transform_from_dict(data, str(path))


def transform_from_touches(origin, on_x, on_plane, source: str = "touches") -> WorkspaceTransform:
    """The transform taking the touched origin to 0, the x touch onto +x and the third touch into the x-y plane
    (+y side); points in the tracker frame, m."""
    p0, px, pp = (np.asarray(p, dtype=float).reshape(3) for p in (origin, on_x, on_plane))
    ex = px - p0
    if np.linalg.norm(ex) < MIN_BASELINE or np.linalg.norm(pp - p0) < MIN_BASELINE:
        raise ValidationError(f"workspace touches ({source}): the touches lie within {MIN_BASELINE * 1e3:.0f} mm of "
                              "each other; touch the origin, a point along +x and a point on the +y side, several "
                              "cm apart")
    ex /= np.linalg.norm(ex)
    ez = np.cross(ex, pp - p0)
    if np.linalg.norm(ez) < 0.2 * np.linalg.norm(pp - p0):
        raise ValidationError(f"workspace touches ({source}): the third touch lies on the x axis; touch a point "
                              "well to its +y side")
    ez /= np.linalg.norm(ez)
    ey = np.cross(ez, ex)
    rotation = np.vstack([ex, ey, ez])  # rows: the grid axes in tracker coordinates
    return WorkspaceTransform(rotation, -rotation @ p0, source)


def touches_from_poses(poses: list[PoseSample], where: str = "touches") -> tuple[np.ndarray, ...]:
    """The three rests of the fingertip in a touch recording (origin, +x, +y side), in time order, m.

    A rest is a stretch of at least ``REST_SECONDS`` with every position within ``REST_RADIUS`` of its mean.
    ValidationError naming ``where`` unless there are exactly three.
    """
    t, pos, _ = poses_to_arrays(poses)
    rests = []
    i, n = 0, len(t)
    while i < n:
        # grow the stretch from i while it stays within the radius of its running mean
        j = i
        total = pos[i].copy()
        while j + 1 < n and np.linalg.norm(pos[j + 1] - (total + pos[j + 1]) / (j - i + 2)) <= REST_RADIUS:
            j += 1
            total += pos[j]
        if t[j] - t[i] >= REST_SECONDS:
            rests.append(total / (j - i + 1))
            i = j + 1
        else:
            i += 1
    # a rest held a little longer than the radius allows splits in two: merge neighbours at one place
    merged: list[np.ndarray] = []
    for r in rests:
        if merged and np.linalg.norm(r - merged[-1]) < 2 * REST_RADIUS:
            merged[-1] = 0.5 * (merged[-1] + r)
        else:
            merged.append(r)
    if len(merged) != 3:
        raise ValidationError(f"{where}: found {len(merged)} rests of the fingertip (each still within "
                              f"{REST_RADIUS * 1e3:.1f} mm for {REST_SECONDS} s), expected 3: the origin, a point on "
                              "+x, a point on the +y side, lifting the finger between them")
    return tuple(merged)


def matrix_to_quaternion(r: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of a rotation matrix (Shepperd's method, stable for any angle)."""
    m = np.asarray(r, dtype=float)
    tr = np.trace(m)
    if tr > 0:
        s = 2.0 * np.sqrt(1.0 + tr)
        q = [0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s]
    else:
        i = int(np.argmax(np.diag(m)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * np.sqrt(1.0 + m[i, i] - m[j, j] - m[k, k])
        q = [0.0, 0.0, 0.0, 0.0]
        q[0] = (m[k, j] - m[j, k]) / s
        q[1 + i] = 0.25 * s
        q[1 + j] = (m[j, i] + m[i, j]) / s
        q[1 + k] = (m[k, i] + m[i, k]) / s
    q = np.array(q)
    return q / np.linalg.norm(q)


def quat_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product of quaternion arrays (n, 4), (w, x, y, z)."""
    aw, ax, ay, az = np.moveaxis(np.asarray(a, dtype=float), -1, 0)
    bw, bx, by, bz = np.moveaxis(np.asarray(b, dtype=float), -1, 0)
    return np.stack([aw * bw - ax * bx - ay * by - az * bz,
                     aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw], axis=-1)
