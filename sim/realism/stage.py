"""One source's realism: what is drawn once per session, what is drawn per press, and the order it is applied in.

A :class:`RealismSession` belongs to one :class:`~palpate.sim.source.SimSource` (one session: the pad equilibrated
once, the two computers' clocks synchronised once). For every press it makes a :class:`PressRealism`, which the
source applies around the physics:

1. plan: the press profile is made in bone space with :meth:`PressRealism.bone_depth_for_force` (the person stops
   at a force felt through the pulp and the softened material), then :meth:`PressRealism.object_profile` takes
   the pulp's share out of every depth (:mod:`palpate.sim.realism.finger`);
2. physics: the fidelity runs unchanged on the object's trajectory;
3. :meth:`PressRealism.finish`: a cellular material's stress plateau, softening and relaxation
   (:mod:`~palpate.sim.realism.material`), then the bone's pose, the pad's patch and the finger's lateral slip;
4. sensors: :attr:`PressRealism.taxel_response` (:mod:`~palpate.sim.realism.taxels`) before the 8-bit counts, and
   the tracker's latency and clock offset (:meth:`PressRealism.pose_spec`, :attr:`PressRealism.latency`).

Session draws come from their own seed stream and per-press draws from a fourth child of the press's seed, so a
profile never changes the draws of the press, taxel and pose models (``ideal`` replays the simulation exactly).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from palpate.core.world.scene import FingertipSpec, PoseSensorSpec, TaxelSensorSpec
from palpate.sim.controller import PressProfile
from palpate.sim.realism.finger import SeriesLaw, finger_trace, object_profile, planning_modulus, series_law
from palpate.sim.realism.material import cellular_depth_for_force, material_trace, plateau_depth
from palpate.sim.realism.profile import RealismProfile
from palpate.sim.realism.taxels import TaxelResponse, activation_map, gain_map, lognormal
from palpate.sim.trace import PhysicsTrace

#: spawn_key of a session's seed stream (the presses' streams are SeedSequence([seed, press index])).
SESSION_STREAM = 0x5E55
#: Force at which the object's planning law is taken, N (a typical palpation force; the law is Hertz in shape).
PLANNING_FORCE = 5.0
#: A press counts as "at the same spot" as an earlier one within this many tip radii (for softening).
SAME_SPOT_RADII = 1.0


@dataclass(frozen=True)
class PressRealism:
    """Everything one press's realism needs (drawn by :meth:`RealismSession.press`).

    Attributes:
        profile: the realism profile.
        law: the object-pulp series law of this press (None with a rigid finger).
        depth_for_force: the object's own force -> depth law (the fidelity's), softened.
        stiffness_scale: this press's factor on the pulp's stiffness.
        softening: this press's factor on the material's stiffness.
        plateau: the indentation, m, past which this press's material is on its stress plateau (0: none).
        densify: the indentation, m, past which it densifies (0: none).
        taxel_response: the pad's response for this press (None when the pad is ideal).
        clock_offset: residual offset of the tracker's clock for this press, s.
        tip: the fingertip.
    """

    profile: RealismProfile
    law: SeriesLaw | None
    depth_for_force: object
    stiffness_scale: float
    softening: float
    plateau: float
    densify: float
    taxel_response: TaxelResponse | None
    clock_offset: float
    tip: FingertipSpec

    def bone_depth_for_force(self, force: float) -> float:
        """Bone travel past first contact, m, at which the contact force reaches ``force`` N."""
        if self.law is None:
            return cellular_depth_for_force(self.depth_for_force, force, self.plateau, self.densify)
        return self.law.bone_depth_for_force(force)

    def object_profile(self, profile: PressProfile) -> PressProfile:
        """The trajectory the object sees (the bone's, less the pulp's compression)."""
        return profile if self.law is None else object_profile(profile, self.law)

    def draws_image(self, profile: PressProfile) -> bool:
        """Whether :meth:`finish` draws the pad's image anew (a compliant or tilted finger): then the physics'
        own sensel pressures are never read."""
        return self.profile.finger.compliant or profile.meta.get("tilt") is not None

    def finish(self, trace: PhysicsTrace, profile: PressProfile, rows: np.ndarray | None = None) -> PhysicsTrace:
        """The physics' trace with the material, the finger and the slip applied (``profile``: the bone's press;
        ``rows``: the rows whose pad image is wanted, as :func:`~palpate.sim.realism.finger.finger_trace`'s)."""
        m = self.profile.material
        if m.relaxation > 0 or self.softening != 1.0 or self.plateau > 0 or self.densify > 0:
            trace = material_trace(trace, m, self.softening, self.plateau, self.densify)
        if self.draws_image(profile):
            tilt = profile.meta.get("tilt")
            trace = finger_trace(trace, profile, self.profile.finger, self.stiffness_scale, self.tip,
                                 None if tilt is None else np.asarray(tilt), rows)
        slip = profile.meta.get("slip")
        if slip is not None:
            # the bone slides sideways in proportion to how far it has travelled into the contact
            normal = np.asarray(profile.meta.get("normal", (0.0, 0.0, 1.0)), dtype=float)
            gap = float(profile.meta.get("approach_gap", 0.0))
            travel = np.maximum((trace.tip_position[0] - trace.tip_position) @ normal - gap, 0.0)
            position = trace.tip_position.copy()
            position[:, :2] += travel[:, None] * np.asarray(slip, dtype=float)[None, :]
            trace = replace(trace, tip_position=position)
        return trace

    def pose_spec(self, spec: PoseSensorSpec) -> PoseSensorSpec:
        """The tracker as it is for this press: its clock off by the residual offset."""
        if self.clock_offset == 0:
            return spec
        return replace(spec, clock_offset=spec.clock_offset + self.clock_offset)

    @property
    def latency(self) -> float:
        """The tracker's latency, s."""
        return self.profile.pose.latency

    def meta(self) -> dict:
        """What this press's realism drew, for the recording's metadata."""
        return {"profile": self.profile.name, "pulp_stiffness_scale": self.stiffness_scale,
                "softening_factor": self.softening, "pose_clock_offset_s": self.clock_offset,
                "pose_latency_s": self.latency}


class RealismSession:
    """The realism of one source: session-long draws and the spots pressed so far.

    Args:
        profile: the realism profile (not ideal: an ideal source needs no session).
        tip: the fingertip (pad shape).
        taxels: the pad's sensor model (its gain sets the full scale of the non-linearity).
        seed: the source's seed.
    """

    def __init__(self, profile: RealismProfile, tip: FingertipSpec, taxels: TaxelSensorSpec, seed: int):
        rng = np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=(SESSION_STREAM,)))
        self.profile = profile
        self.tip = tip
        self.full_scale = 255.0 / taxels.gain
        self.gains = gain_map(profile.taxels, (tip.rows, tip.cols), rng)
        self.clock_offset = profile.pose.clock_offset_std * float(rng.standard_normal())
        # drawn after the older session draws, so a profile without a spread keeps its draws
        self.activation = activation_map(profile.taxels, (tip.rows, tip.cols), rng)
        self.drift = 1.0
        self.spots: list[tuple[str, float, float]] = []

    def earlier_presses(self, obj_name: str, x: float, y: float) -> int:
        """Presses made so far on ``obj_name`` within :data:`SAME_SPOT_RADII` tip radii of (x, y)."""
        r = SAME_SPOT_RADII * self.tip.radius
        return sum(1 for name, px, py in self.spots if name == obj_name and np.hypot(px - x, py - y) <= r)

    def press(self, obj_name: str, x: float, y: float, depth_for_force, reach: float,
              rng: np.random.Generator, tail_scale: float = 1.0, material: str | None = None) -> PressRealism:
        """Draw one press's realism at (x, y) m on ``obj_name``.

        Args:
            obj_name, x, y: where the press is made (for softening).
            depth_for_force: the object's force (N) -> indentation (m) law (the fidelity's).
            reach: the deepest bone travel the press may plan, m (the series law is tabulated up to it).
            rng: this press's realism stream.
            tail_scale: this press's careless-press scale (the press profile's ``meta["tail_scale"]``, drawn by
                :func:`palpate.sim.controller.tail_scale`): it widens the pulp's stiffness draw as it widens the
                press's own deviations (which part of the pulp touches is part of how the person presses).
            material: the name of the material under the press point (whether it has a stress plateau).
        """
        p = self.profile
        softening = p.material.softening_factor(self.earlier_presses(obj_name, x, y))
        self.spots.append((obj_name, float(x), float(y)))
        stiffness_scale = float(lognormal(rng, p.finger.stiffness_cv, spread=tail_scale))
        if p.taxels.gain_drift > 0:
            self.drift *= float(lognormal(rng, p.taxels.gain_drift))
        clock = self.clock_offset + (p.pose.clock_wander * float(rng.standard_normal()) if p.pose.clock_wander
                                     else 0.0)

        def softened(force: float) -> float:
            return float(depth_for_force(force / softening))

        plateau = plateau_depth(p.material.plateau_of(material), self.tip.radius)
        densify = plateau_depth(p.material.densify_of(material), self.tip.radius)
        law = None
        if p.finger.compliant:
            # the planning modulus is the elastic one: the series law adds the plateau itself
            e_star = planning_modulus(softened, self.tip.radius, PLANNING_FORCE)
            law = series_law(e_star, self.tip.radius, p.finger, stiffness_scale, reach, plateau, densify)
        response = (TaxelResponse(p.taxels, self.gains * self.drift, self.full_scale, self.activation)
                    if p.taxels.active else None)
        return PressRealism(p, law, softened, stiffness_scale, softening, plateau, densify, response, clock, self.tip)
