"""The contract between a fidelity level's physics and the sensor models.

Every fidelity level (analytic, rigid, flex) integrates the same press and returns a :class:`PhysicsTrace` at the
physics rate; :mod:`palpate.sim.sensors` then samples it into taxel frames (50 Hz, 8-bit) and pose samples
(~30 Hz, noisy, own clock). Keeping this boundary plain data lets each level be checked against the others.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from palpate.core.errors import SimulationDiverged


@dataclass
class PhysicsTrace:
    """Physics-rate history of one press-and-release.

    Attributes:
        t: simulation time, s, shape (n,), strictly increasing.
        tip_position: fingertip centre-of-sphere position, m, shape (n, 3), world frame.
        tip_quaternion: fingertip orientation (w, x, y, z), shape (n, 4).
        sensel_pressure: mean normal pressure over each sensel's area, Pa, shape (n, rows, cols), >= 0.
        force: total normal contact force on the fingertip, N, shape (n,), >= 0.
        indentation: true indentation of the tip into the undeformed surface, m, shape (n,) (0 when not touching).
        surface_z: height of the undeformed surface under the press, m.
        material: name of the material under the press point (None when mixed or unknown).
        meta: what produced it (fidelity, timestep, solver settings), JSON-serialisable.
    """

    t: np.ndarray
    tip_position: np.ndarray
    tip_quaternion: np.ndarray
    sensel_pressure: np.ndarray
    force: np.ndarray
    indentation: np.ndarray
    surface_z: float
    material: str | None = None
    meta: dict = field(default_factory=dict)

    def check_finite(self) -> None:
        """Raise SimulationDiverged if any array holds NaN or inf (a frame with NaN is never emitted)."""
        for name in ("t", "tip_position", "tip_quaternion", "sensel_pressure", "force", "indentation"):
            arr = getattr(self, name)
            if not np.all(np.isfinite(arr)):
                first = int(np.argmax(~np.isfinite(np.asarray(arr).reshape(len(arr), -1)).any(axis=1)))
                raise SimulationDiverged(
                    f"non-finite {name} at t={self.t[first] if first < len(self.t) else float('nan'):.4f} s "
                    f"({self.meta.get('fidelity', '?')}); reduce the timestep or the press speed, or soften the contact"
                )


def frame_times(t: np.ndarray, rate: float) -> np.ndarray:
    """The simulation times (s) at which a sensor sampling at ``rate`` Hz reads a trace over times ``t`` (s): from
    its first sample, every 1 / rate, up to its last."""
    return t[0] + np.arange(int(np.floor((t[-1] - t[0]) * rate + 1e-9)) + 1) / rate


def bracket(t_query: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(i, w): for each time of ``t_query`` (s), the trace's row i before it and its share w in [0, 1] of the way to
    row i + 1 (times ``t``, s, increasing; clamped at both ends): the linear interpolation the sensors read."""
    idx = np.clip(np.searchsorted(t, t_query, side="right") - 1, 0, len(t) - 2)
    span = t[idx + 1] - t[idx]
    return idx, np.clip((t_query - t[idx]) / np.where(span > 0, span, 1.0), 0.0, 1.0)


def frame_rows(t: np.ndarray, rate: float) -> np.ndarray:
    """Boolean mask (n,) of the rows of a trace over times ``t`` (s) that a sensor at ``rate`` Hz interpolates
    between (:func:`frame_times`, :func:`bracket`): the only rows its readings depend on."""
    rows = np.zeros(len(t), dtype=bool)
    idx, _ = bracket(frame_times(t, rate), t)
    rows[idx] = rows[idx + 1] = True
    return rows
