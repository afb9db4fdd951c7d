"""Contact features of a synchronised stream (eq. 6.2-6.4 of seed 000).

- c_P, contact intensity (eq. 6.2): the sum of the sensel outputs. Raw counts by default; force in N when a
  calibration is given (a scalar N per count, or a callable mapping a counts array to N per sensel).
- c_A, contact area (eq. 6.3): the number of active sensels times the sensel area, m^2.
- c_D, indentation (eq. 6.4): height at first contact minus current height, m, positive into the object. The height
  at first contact belongs to one press, so c_D is computed per press by
  :mod:`palpate.core.perception.segment`; here the series carries the height along the press axis.

A sensel is active when its count exceeds ``noise_threshold``. Sensels at or below the threshold are treated as
silent for both c_P and c_A, so the two features describe the same contact patch; with the default threshold 0
this is exactly eq. 6.2 and 6.3.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.perception.streams import ContactSample
from palpate.core.perception.sync import SyncedStream

Calibration = Callable[[np.ndarray], np.ndarray] | float | None


@dataclass
class ContactSeries:
    """Contact features at every taxel time.

    Attributes:
        t: time, s, shape (n,).
        c_P: contact intensity, shape (n,): sum of counts, or N when ``calibrated``.
        c_A: contact area, m^2, shape (n,).
        height: fingertip position along -press_axis, m, shape (n,) (the z coordinate for a vertical press).
        xy: fingertip (x, y) position, m, shape (n, 2).
        valid: True where the pose is usable (see :class:`palpate.core.perception.sync.SyncedStream`), shape (n,).
        calibrated: True when c_P is a force in N rather than a sum of counts.
        z: fingertip z coordinate, m, shape (n,).
    """

    t: np.ndarray
    c_P: np.ndarray
    c_A: np.ndarray
    height: np.ndarray
    xy: np.ndarray
    valid: np.ndarray
    calibrated: bool = False
    z: np.ndarray | None = None

    def __post_init__(self) -> None:
        n = len(self.t)
        for name in ("c_P", "c_A", "height", "xy", "valid"):
            if len(getattr(self, name)) != n:
                raise ValidationError(f"ContactSeries.{name} has {len(getattr(self, name))} rows, expected {n}")
        if self.z is None:
            self.z = np.asarray(self.height, dtype=float)

    def __len__(self) -> int:
        return len(self.t)

    def slice(self, start: int, stop: int) -> ContactSeries:
        """Rows start:stop as a new series (arrays are views)."""
        return ContactSeries(
            t=self.t[start:stop],
            c_P=self.c_P[start:stop],
            c_A=self.c_A[start:stop],
            height=self.height[start:stop],
            xy=self.xy[start:stop],
            valid=self.valid[start:stop],
            calibrated=self.calibrated,
            z=self.z[start:stop],
        )

    def to_samples(self, h0: float | None = None) -> list[ContactSample]:
        """One :class:`ContactSample` per row.

        Args:
            h0: height at first contact, m, from which c_D = h0 - height is measured. When None, the height at the
                first row with contact (c_A > 0) is used, and c_D is 0 everywhere if there is no contact.
        """
        if h0 is None:
            touching = np.flatnonzero(self.c_A > 0)
            h0 = float(self.height[touching[0]]) if len(touching) else None
        c_d = np.zeros(len(self)) if h0 is None else h0 - self.height
        return [
            ContactSample(
                t=float(self.t[i]),
                c_P=float(self.c_P[i]),
                c_A=float(self.c_A[i]),
                c_D=float(c_d[i]),
                xy=(float(self.xy[i, 0]), float(self.xy[i, 1])),
                z=float(self.z[i]),
            )
            for i in range(len(self))
        ]


def press_axis_unit(press_axis) -> np.ndarray:
    """The press axis as a unit 3-vector; ValidationError if it is not a finite non-zero 3-vector."""
    if isinstance(press_axis, tuple):
        try:
            return _unit_axis(press_axis)
        except TypeError:  # a tuple holding something unhashable: checked below
            pass
    return _unit_axis_checked(press_axis)


@lru_cache(maxsize=64)
def _unit_axis(press_axis: tuple) -> np.ndarray:
    """Cached for the few axes a process presses along: every press asks for the same one."""
    axis = _unit_axis_checked(press_axis)
    axis.flags.writeable = False
    return axis


def _unit_axis_checked(press_axis) -> np.ndarray:
    axis = np.asarray(press_axis, dtype=float).reshape(-1)
    if axis.shape != (3,) or not np.all(np.isfinite(axis)) or np.linalg.norm(axis) < 1e-12:
        raise ValidationError(f"press_axis must be a finite non-zero 3-vector, got {press_axis!r}")
    return axis / np.linalg.norm(axis)


def contact_features(
    stream: SyncedStream,
    *,
    noise_threshold: int = 0,
    calibration: Calibration = None,
    press_axis=(0.0, 0.0, -1.0),
) -> ContactSeries:
    """Compute c_P, c_A, height and xy at every frame of a synchronised stream.

    Args:
        stream: output of :func:`palpate.core.perception.sync.synchronise`.
        noise_threshold: a sensel is active when its count is strictly above this (0..254).
        calibration: None (c_P in counts), a positive scalar in N per count, or a callable taking the float
            counts array (n, rows, cols) and returning the force on each sensel in N (same shape, finite, >= 0).
        press_axis: direction in which the finger presses (world frame); height is measured along its opposite.

    Returns:
        A :class:`ContactSeries` (c_A in m^2, height and xy in m).

    Raises:
        ValidationError: bad threshold, calibration or press axis, or a calibration returning bad values.
    """
    check_noise_threshold(noise_threshold)
    axis = press_axis_unit(press_axis)
    c_p, c_a = intensity_and_area(np.asarray(stream.counts), float(stream.sensel_area), noise_threshold,
                                  calibration)
    position = np.asarray(stream.position, dtype=float)
    z = position[:, 2].copy()
    return ContactSeries(
        t=np.asarray(stream.t, dtype=float),
        c_P=c_p,
        c_A=c_a,
        height=_height(position, z, axis),
        xy=position[:, :2].copy(),
        valid=np.asarray(stream.valid, dtype=bool),
        calibrated=calibration is not None,
        z=z,
    )


def _height(position: np.ndarray, z: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """Height along -axis of positions (n, 3), m: element by element, so a pose's height does not depend on how
    many poses are computed with it (a matrix product's rounding does), and a stream fed sample by sample gets the
    same floats."""
    if axis[0] == 0.0 and axis[1] == 0.0 and axis[2] == -1.0:
        return z  # pressing straight down: -(0 x + 0 y - z) is z to the bit, but for the sign of a zero
    return -(position[:, 0] * axis[0] + position[:, 1] * axis[1] + position[:, 2] * axis[2])


def check_noise_threshold(noise_threshold) -> None:
    """ValidationError unless the threshold is an integer count in 0..254."""
    if isinstance(noise_threshold, bool) or not isinstance(noise_threshold, int | np.integer):
        raise ValidationError(f"noise_threshold must be an integer count (0..254), got {noise_threshold!r}")
    if not 0 <= noise_threshold <= 254:
        raise ValidationError(f"noise_threshold must be in 0..254 counts, got {noise_threshold}")


def intensity_and_area(counts: np.ndarray, sensel_area: float, noise_threshold: int,
                       calibration: Calibration) -> tuple[np.ndarray, np.ndarray]:
    """c_P (counts, or N when calibrated) and c_A (m^2) of frames (n, rows, cols): eq. 6.2 and 6.3 over the
    sensels above ``noise_threshold``. The threshold is trusted to be checked (see :func:`contact_features`)."""
    active = counts > noise_threshold
    c_a = active.reshape(len(counts), -1).sum(axis=1) * sensel_area
    return _intensity(counts, active, calibration, noise_threshold), c_a


def _intensity(counts: np.ndarray, active: np.ndarray, calibration: Calibration, noise_threshold: int) -> np.ndarray:
    """Sum over the active sensels of each frame, in counts or (calibrated) N."""
    n = len(counts)
    if calibration is None:
        # Unsigned counts: with threshold 0 the inactive sensels already contribute nothing.
        live = counts if noise_threshold == 0 and counts.dtype.kind == "u" else np.where(active, counts, 0)
        return live.reshape(n, -1).sum(axis=1, dtype=np.int64).astype(float)
    if callable(calibration):
        force = np.asarray(calibration(counts.astype(float)), dtype=float)
        if force.shape != counts.shape:
            raise ValidationError(
                f"calibration returned shape {force.shape}; expected the counts' shape {counts.shape} (N per sensel)"
            )
        if not np.all(np.isfinite(force)) or np.any(force < 0):
            raise ValidationError("calibration returned negative or non-finite forces; expected finite N >= 0")
        return np.where(active, force, 0.0).reshape(n, -1).sum(axis=1)
    try:
        gain = float(calibration)
    except (TypeError, ValueError) as exc:
        raise ValidationError(
            f"calibration must be None, a scalar N per count or a callable counts -> N, got {calibration!r}"
        ) from exc
    if not (np.isfinite(gain) and gain > 0):
        raise ValidationError(f"calibration gain must be a positive finite N per count, got {calibration!r}")
    return gain * np.where(active, counts, 0).reshape(n, -1).sum(axis=1, dtype=np.int64).astype(float)
