"""The compliant fingertip: its pulp in series with the object, and the contact patch the pad sees.

A human finger is a bone (the nail, where the pose sensor is glued) behind a few millimetres of soft pulp (where the
taxel pad is glued). Pressing, the bone moves D = d + delta(F): the object's indentation d plus the pulp's
compression delta(F) under the contact force F (:meth:`~palpate.sim.realism.profile.FingerPulp.compression`). The
force balance F_object(d) = F_pulp(delta) is solved in force: both depths are monotonic in F, so D(F) is tabulated
once per press and inverted by interpolation (:class:`SeriesLaw`).

The contact mechanics of every fidelity are used as they are: the press profile is planned in bone space (the
person's hand), turned into the object's indentation with a Hertz law through the object's own force-depth point
(:func:`planning_modulus`, from the fidelity's ``depth_for_force``), the physics runs on that, and afterwards the
pose is put back on the bone with the compression the physics' *actual* force gives, and the pad's pressure is
spread over the larger patch of two deforming bodies, a^2 = R (d + area_factor delta), keeping the physics' force
(Hertz's distribution over that patch, more peaked the more of the approach the pulp takes,
:mod:`palpate.sim.realism.patch`; centred where the tilted finger meets the object).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.world.scene import FingertipSpec
from palpate.sim.controller import PressProfile
from palpate.sim.fingertip import sensel_bounds
from palpate.sim.realism.patch import patch_sensel_pressure, press_exponent
from palpate.sim.realism.profile import FingerPulp
from palpate.sim.trace import PhysicsTrace

#: Force samples of the series-law table (a smooth monotonic curve; 400 log-spaced points keep D(F) to < 0.1%).
_TABLE_POINTS = 400
#: Largest force the table may be extended to, N (far beyond any palpation; a bound on a runaway press).
_MAX_TABLE_FORCE = 1e4


def planning_modulus(depth_for_force, radius: float, force: float) -> float:
    """E*, Pa, of the Hertz law F = 4/3 E* sqrt(R) d^1.5 through the object's own point (depth_for_force(F), F).

    On one material this is its E*; on layered or mixed objects it is E*_eff at that depth, which the physics
    refines (the series split only plans the trajectory; the force felt is the physics').
    """
    d = float(depth_for_force(force))
    if not (np.isfinite(d) and d > 0):
        raise ValidationError(f"finger: depth_for_force({force}) gave {d!r}, expected a depth > 0 m")
    return 3.0 * force / (4.0 * np.sqrt(radius) * d**1.5)


@dataclass(frozen=True)
class SeriesLaw:
    """Object and pulp in series, tabulated against the force F (N): indentation d(F), compression delta(F), m."""

    force: np.ndarray
    object_depth: np.ndarray
    compression: np.ndarray

    @property
    def bone_depth(self) -> np.ndarray:
        """D(F) = d(F) + delta(F), m: how far the bone has moved past first contact."""
        return self.object_depth + self.compression

    def bone_depth_for_force(self, force: float) -> float:
        """Bone travel past first contact at which the contact force reaches ``force`` N, m."""
        return float(np.interp(force, self.force, self.bone_depth))

    def object_depth_at(self, bone_depth: np.ndarray) -> np.ndarray:
        """The object's indentation, m, when the bone has moved ``bone_depth`` m past first contact (>= 0)."""
        force = np.interp(np.maximum(bone_depth, 0.0), self.bone_depth, self.force)
        return np.interp(force, self.force, self.object_depth)


def series_law(e_star: float, radius: float, pulp: FingerPulp, stiffness_scale: float,
               reach: float, plateau: float = 0.0, densify: float = 0.0) -> SeriesLaw:
    """Tabulate the series law of a Hertz object (E* Pa, tip radius m) and the pulp up to a bone travel ``reach`` m.

    The force range grows until the bone travel at its top exceeds ``reach`` (a press never needs more).
    ``plateau``: the indentation, m, past which the object's stress stays on a plateau (0: none): beyond it
    F = 4/3 E* sqrt(R) d^1.5 sqrt(plateau / d) (:func:`palpate.sim.realism.material.plateau_factor`).
    ``densify``: the indentation, m (deeper than ``plateau``), past which that force grows by d / densify (0: none;
    :func:`palpate.sim.realism.material.densify_factor`). Both inverted in closed form.
    """
    if not (np.isfinite(e_star) and e_star > 0):
        raise ValidationError(f"finger: the object's modulus must be > 0 Pa, got {e_star!r}")
    f_max = 100.0
    while True:
        force = np.concatenate([[0.0], np.geomspace(1e-6, f_max, _TABLE_POINTS - 1)])
        k = 4.0 * e_star * np.sqrt(radius) / 3.0
        depth = (force / k) ** (2.0 / 3.0)
        if plateau > 0:
            depth = np.where(depth > plateau, force / (k * np.sqrt(plateau)), depth)
        if densify > 0:
            # the force at the onset, then F = F(d) d / densify past it: k sqrt(plateau) d^2 / densify on a plateau,
            # k d^2.5 / densify without one
            if plateau > 0:
                onset, deep = k * np.sqrt(plateau) * densify, np.sqrt(force * densify / (k * np.sqrt(plateau)))
            else:
                onset, deep = k * densify**1.5, (force * densify / k) ** 0.4
            depth = np.where(force > onset, deep, depth)
        law = SeriesLaw(force, depth, pulp.compression(force, stiffness_scale))
        if law.bone_depth[-1] >= reach or f_max >= _MAX_TABLE_FORCE:
            return law
        f_max *= 4.0


def object_profile(profile: PressProfile, law: SeriesLaw) -> PressProfile:
    """The press as the object sees it: the bone's trajectory with the pulp's share of every depth taken out.

    Out of contact (the approach gap) nothing changes; ``meta["depth"]`` becomes the object's deepest indentation
    (what the physics checks its run against) and ``meta["bone_depth"]`` keeps the planned bone travel.
    """
    radius = float(profile.meta["radius"])
    bone = profile.surface_z + radius - profile.z
    depth = np.where(bone > 0, law.object_depth_at(bone), bone)
    meta = dict(profile.meta, depth=float(max(np.max(depth), 1e-9)), bone_depth=float(profile.meta["depth"]))
    return replace(profile, z=profile.surface_z + radius - depth, meta=meta)


def pad_offset(radius: float, tilt: np.ndarray) -> np.ndarray:
    """Where a finger tilted by (pitch, roll) rad meets a flat surface, in the pad plane, m (R sin(tilt))."""
    return radius * np.sin(np.asarray(tilt, dtype=float))


def finger_trace(trace: PhysicsTrace, profile: PressProfile, pulp: FingerPulp, stiffness_scale: float,
                 tip: FingertipSpec, tilt: np.ndarray | None = None, rows: np.ndarray | None = None) -> PhysicsTrace:
    """The physics' trace seen through the finger: the bone's pose and the pad's pressure over the real patch.

    Args:
        trace: the physics' trace of the object-space press (its force is the force the pulp carries).
        profile: that press's profile (normal and radius).
        pulp: the pulp; rigid leaves the pose as it is.
        stiffness_scale: this press's factor on the pulp's stiffness.
        tip: the fingertip (pad geometry).
        tilt: the finger's (pitch, roll) for this press, rad (None: untilted).
        rows: mask (n,) of the rows whose pad pressure is wanted (:func:`palpate.sim.trace.frame_rows`: those the
            pad's frames read); the others are 0. None: every row.

    Returns:
        a new trace: tip_position on the bone (moved by the compression along -normal), sensel_pressure spread
        over the patch a^2 = R (d + area_factor delta) centred at the tilted contact point (its shape:
        :func:`~palpate.sim.realism.patch.press_exponent`), same force and
        indentation (the object's), meta["finger"] saying what was applied.
    """
    radius = tip.radius
    force = np.maximum(trace.force, 0.0)
    delta = pulp.compression(force, stiffness_scale)
    normal = np.asarray(profile.meta.get("normal", (0.0, 0.0, 1.0)), dtype=float)
    position = trace.tip_position - delta[:, None] * normal[None, :]
    centre = -radius * normal[:2] + (pad_offset(radius, tilt) if tilt is not None else 0.0)
    patch = np.maximum(trace.indentation, 0.0) + pulp.area_factor * delta
    pressure = np.zeros_like(trace.sensel_pressure)
    touching = (force > 0) & (patch > 0)
    if rows is not None:
        touching &= np.asarray(rows, dtype=bool)
    if touching.any():
        exponent = press_exponent(pulp.pressure_exponent, trace.indentation[touching], delta[touching])
        pressure[touching] = patch_sensel_pressure(patch[touching], force[touching], exponent, radius,
                                                   sensel_bounds(tip), np.broadcast_to(centre, (2,)))
    meta = dict(trace.meta, finger={"compliant": pulp.compliant, "max_compression_m": float(np.max(delta)),
                                    "stiffness_scale": float(stiffness_scale),
                                    "pad_offset_m": [float(c) for c in np.broadcast_to(centre, (2,))]})
    return replace(trace, tip_position=position, sensel_pressure=pressure, meta=meta)
