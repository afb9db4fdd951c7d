"""The press controller: the setpoint trajectory of one press-and-release.

Phases: approach from a small gap above the surface, press to a target depth (or to the depth a target force
needs) at a given speed, optional hold, release back to the start height. A robot follows the target exactly;
a human-like press varies speed and depth from press to press, shifts the press point by a small lateral jitter,
and moves with a bell-shaped (minimum-jerk) velocity instead of constant speed; a realism profile
(:mod:`palpate.sim.realism`) may add physiological tremor on the press axis and draw the finger's tilt and lateral
slip, which the realism stage applies to the pad and the pose. Every draw comes from a seeded generator, so the
same seed gives the same press.

The trajectory is a :class:`PressProfile`; every fidelity level (analytic, rigid, flex) consumes it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.special import gammaincinv

from palpate.core.errors import ValidationError
from palpate.core.session.sources import PressTarget

#: Largest tilt of the finger, rad: beyond it the pad leaves the contact (a careless press's tilt is clipped to it,
#: a careful press's spread must stay below it).
MAX_TILT = float(np.deg2rad(30.0))


@dataclass
class PressProfile:
    """Setpoint trajectory of one press-and-release (contract shared by every fidelity level).

    Attributes:
        t: time, s, shape (n,), strictly increasing from 0, sampled at the physics timestep or finer
            (consumers interpolate).
        z: tip-sphere-centre height setpoint, m, world frame, shape (n,).
        x, y: tip-sphere-centre horizontal position, m (constant during the press; lateral jitter of a
            human-like press is already included).
        surface_z: height of the undeformed surface under the press point, m; first contact is at
            z = surface_z + tip radius.
        meta: provenance, JSON-serialisable: "radius" (m), "depth" (commanded indentation, m), "speed" (m/s),
            "hold" (s), "phases" (name -> [t_start, t_end] s), "normal" (unit surface normal, (0, 0, 1) on flat
            tops; for a tilted normal use :meth:`centres`, the press then runs along the normal), "mode"
            ("robot" or "human"), "force_target" (N or None).
    """

    t: np.ndarray
    z: np.ndarray
    x: float
    y: float
    surface_z: float
    meta: dict = field(default_factory=dict)

    @property
    def duration(self) -> float:
        """Length of the whole press-and-release, s."""
        return float(self.t[-1] - self.t[0])

    def indentation(self) -> np.ndarray:
        """Commanded indentation of the sphere into the undeformed surface, m, >= 0, shape (n,)."""
        return np.maximum(self.surface_z + self.meta.get("radius", 0.0) - self.z, 0.0)

    def centres(self) -> np.ndarray:
        """Tip-sphere-centre setpoints (n, 3), m, pressing along meta["normal"] through the contact point.

        On a flat top this is (x, y, z). On a tilted surface the sphere centre moves along the normal of the
        contact point (x, y, surface_z), by the same signed distance as z moves relative to first contact.
        """
        n = np.asarray(self.meta.get("normal", (0.0, 0.0, 1.0)), dtype=float)
        contact = np.array([self.x, self.y, self.surface_z])
        return contact[None, :] + n[None, :] * (self.z - self.surface_z)[:, None]

    def step_times(self, timestep: float) -> np.ndarray:
        """Times, s, of a physics run at ``timestep`` s over this profile: a uniform grid laid so that one step
        falls on the deepest setpoint, starting within one step after t[0].

        A grid from t[0] steps over the deepest point whenever the profile's sampling is not a multiple of the
        step, and the servo then turns round up to half a step's travel short of the commanded depth (found by
        the stability matrix: flex, 5 mm at 0.2 m/s in 2 ms steps, reached 4.72 mm).
        """
        t0, t1 = float(self.t[0]), float(self.t[-1])
        deep = float(self.t[int(np.argmin(self.z))])
        start = deep - timestep * np.floor((deep - t0) / timestep + 1e-9)
        n = int(np.floor((t1 - start) / timestep + 1e-9)) + 1
        return start + timestep * np.arange(n)

    def at(self, t: float | np.ndarray) -> np.ndarray:
        """Height setpoint at time(s) t, s, linearly interpolated, m."""
        return np.interp(t, self.t, self.z)


@dataclass(frozen=True)
class Variability:
    """How much a human-like press varies from the target (all draws seeded).

    Attributes:
        speed_cv: coefficient of variation of the press and release speeds.
        depth_cv: coefficient of variation of the reached depth (or force).
        lateral_std: standard deviation of the press point's offset in x and y, m.
        hold_std: standard deviation added to the hold time, s (clipped at 0).
        smooth: use a bell-shaped (minimum-jerk) velocity in each phase, as human reaching does.
        tilt_std: standard deviation of the finger's pitch and roll away from the press axis, rad; the contact
            then meets the pad R sin(tilt) off its centre (applied by :mod:`palpate.sim.realism.finger`).
        slip_std: standard deviation of the lateral slip of the finger (bone and nail, where the pose sensor
            sits) per metre of indentation, m/m, in a random direction; the skin stays stuck to the object.
        tremor: amplitude of physiological tremor along the press axis, m (8-12 Hz; ~0.05-0.2 mm for a finger
            held against a light load, Elble & Koller 1990). 0 for none.
        force_scale: the force a person actually stops at, relative to the instructed limit (people palpating
            soft objects press far more lightly than a stated "up to 10 N"; 1 for a robot).
        push_force: a press to a depth goes on past it until the object pushes back with at least this force,
            N, as a person pressing a sponge does (0: stop at the depth, as a robot does); the force limit still
            stops it first.
        push_depth_scale: how far past the depth that may go, as a multiple of the press's depth (>= 1).
        push_stiffness: a press to a depth goes on past it until the object, felt through the finger, is at least
            this stiff, N/m: dF/dD of the force against the travel (0: off). A person feels a sponge give (its
            plateau keeps it soft) and presses on; a rubber or a hard foam pushes back at once. With
            ``push_force`` too, the press goes on until both are reached, within the same cap.
        tail_dof: degrees of freedom of a careless press (0: off, every press as careful as the others). Each
            press draws one scale w = sqrt(nu / chi2_nu) (at most :data:`TAIL_SCALE_MAX`) that multiplies its
            deviations of where and how deep it goes (depth or force, press point, tilt, slip; the realism stage
            also the pulp's stiffness; not its pace: speeds and hold): those deviations are then Student-t with
            ``tail_dof`` degrees of freedom, a scale mixture of normals, so most presses are tight and a few are
            far off (docs/realism.md). >= 1 when on.
    """

    speed_cv: float = 0.15
    depth_cv: float = 0.10
    lateral_std: float = 3.0e-4
    hold_std: float = 0.02
    smooth: bool = True
    tilt_std: float = 0.0
    slip_std: float = 0.0
    tremor: float = 0.0
    force_scale: float = 1.0
    push_force: float = 0.0
    push_depth_scale: float = 2.0
    push_stiffness: float = 0.0
    tail_dof: float = 0.0

    def __post_init__(self) -> None:
        for name in ("speed_cv", "depth_cv", "lateral_std", "hold_std", "tilt_std", "slip_std", "tremor"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise ValidationError(f"Variability.{name} must be a finite value >= 0, got {v!r}")
        if self.speed_cv >= 0.5 or self.depth_cv >= 0.5:
            raise ValidationError("Variability.speed_cv and depth_cv must stay below 0.5 (a press cannot reverse)")
        if not (np.isfinite(self.force_scale) and 0.01 <= self.force_scale <= 10.0):
            raise ValidationError(f"Variability.force_scale must be in [0.01, 10], got {self.force_scale!r}")
        if not (np.isfinite(self.push_force) and self.push_force >= 0):
            raise ValidationError(f"Variability.push_force must be a finite force >= 0 N, got {self.push_force!r}")
        if not (np.isfinite(self.push_stiffness) and self.push_stiffness >= 0):
            raise ValidationError(f"Variability.push_stiffness must be a finite stiffness >= 0 N/m, "
                                  f"got {self.push_stiffness!r}")
        if not (np.isfinite(self.push_depth_scale) and self.push_depth_scale >= 1.0):
            raise ValidationError(f"Variability.push_depth_scale must be >= 1, got {self.push_depth_scale!r}")
        if not (np.isfinite(self.tail_dof) and (self.tail_dof == 0 or self.tail_dof >= 1.0)):
            raise ValidationError(f"Variability.tail_dof must be 0 (off) or a finite value >= 1, got {self.tail_dof!r}")
        if self.tilt_std >= MAX_TILT:
            raise ValidationError("Variability.tilt_std must stay below 30 deg (the pad would leave the contact)")


#: Most samples a press's trajectory may take (10 million: 5.5 hours at 2 ms), refused before it is built.
MAX_SAMPLES = 10_000_000
#: Frequency band of physiological finger tremor, Hz (Elble & Koller 1990: 8-12 Hz).
TREMOR_BAND_HZ = (8.0, 12.0)

#: spawn_key of a press's careless-press stream (its own, so the press's other draws stay as they were).
TAIL_STREAM = 0x7A11
#: Largest careless-press scale: a person's worst press is at most this many times as far off as a usual one
#: (the Student-t's far tail would otherwise put a press off the object or reverse it).
TAIL_SCALE_MAX = 4.0

#: An exact robot press: no variability, constant speed.
ROBOT = Variability(speed_cv=0.0, depth_cv=0.0, lateral_std=0.0, hold_std=0.0, smooth=False)
#: A human-like press with the default variability.
HUMAN = Variability()


def tail_scale(dof: float, seed: int) -> float:
    """A press's careless-press scale w = sqrt(nu / chi2_nu) for ``dof`` = nu (1 when 0: off), <= TAIL_SCALE_MAX.

    Drawn by inverting chi2's distribution at one uniform of the press's own stream (``seed``), so a fit that
    changes ``dof`` moves each press's scale smoothly (common random numbers), and w -> 1 as nu grows.
    """
    if dof <= 0:
        return 1.0
    u = np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=(TAIL_STREAM,))).uniform()
    # chi2's quantile as scipy.stats computes it (2 P^-1(nu / 2, u)), without importing scipy.stats (~0.3 s)
    return float(min(np.sqrt(dof / (2.0 * gammaincinv(dof / 2.0, u))), TAIL_SCALE_MAX))


#: Forces, N, at which :func:`stiff_depth` samples a force -> depth law (log-spaced, ~4% apart).
_STIFFNESS_FORCES = np.geomspace(1e-3, 1e3, 361)


def stiff_depth(depth_for_force, stiffness: float) -> float:
    """The shallowest depth, m, at which the law ``depth_for_force`` (N -> m) is at least ``stiffness`` N/m stiff.

    The stiffness dF/dD is taken between neighbouring samples of :data:`_STIFFNESS_FORCES` and interpolated in
    log force, so the answer moves smoothly with the law (a calibration varies it); inf when the law never gets
    that stiff in the sampled range (the press goes to its cap).
    """
    depth = np.array([float(depth_for_force(f)) for f in _STIFFNESS_FORCES])
    if not np.all(np.isfinite(depth)):
        return float("inf")
    mid = np.sqrt(_STIFFNESS_FORCES[1:] * _STIFFNESS_FORCES[:-1])
    slope = np.diff(_STIFFNESS_FORCES) / np.maximum(np.diff(depth), 1e-15)
    above = np.flatnonzero(slope >= stiffness)
    if above.size == 0:
        return float("inf")
    i = int(above[0])
    if i == 0:
        return float(depth_for_force(mid[0]))
    # where between the two samples' midpoints the slope crosses the threshold (log force, log slope)
    frac = np.log(stiffness / slope[i - 1]) / np.log(slope[i] / slope[i - 1])
    return float(depth_for_force(float(np.exp(np.log(mid[i - 1]) + frac * np.log(mid[i] / mid[i - 1])))))


def _ramp(n: int, smooth: bool) -> np.ndarray:
    """Normalised position 0 -> 1 over n samples: linear (robot) or minimum-jerk (human)."""
    s = np.linspace(0.0, 1.0, n)
    if not smooth:
        return s
    return s**3 * (10.0 - 15.0 * s + 6.0 * s**2)


#: The minimum-jerk ramp sampled once (2001 points, read-only) for :func:`_inverse_ramp`: sampled anew for each of
#: a human profile's two lookups, it took a quarter of the profile's time.
_SMOOTH_TIME = np.linspace(0.0, 1.0, 2001)
_SMOOTH_RAMP = _ramp(2001, True)
_SMOOTH_TIME.flags.writeable = False
_SMOOTH_RAMP.flags.writeable = False


def press_profile(
    target: PressTarget,
    surface_z: float,
    *,
    radius: float,
    timestep: float,
    variability: Variability = ROBOT,
    seed: int = 0,
    depth_for_force=None,
    approach_gap: float = 0.002,
    normal: tuple[float, float, float] = (0.0, 0.0, 1.0),
    max_depth: float | None = None,
) -> PressProfile:
    """Setpoint trajectory of one press-and-release at ``target``.

    Args:
        target: where and how to press (x, y m; depth m or force N; speed m/s; hold s).
        surface_z: height of the undeformed surface at (x, y), m.
        radius: tip sphere radius, m.
        timestep: sampling step of the trajectory, s (the physics step or finer).
        variability: :data:`ROBOT` for an exact press, :data:`HUMAN` (or a custom one) for a human-like press.
        seed: seed of the variability draws.
        depth_for_force: function force (N) -> indentation (m) used for force targets (e.g. the Hertz
            estimate for the local material); required when ``target.force`` is set.
        approach_gap: gap between tip and surface at the start and end, m.
        normal: unit surface normal at the press point (pressing runs along it).
        max_depth: the deepest a press to a depth goes, m (None: no limit): a press drawn deeper (its depth's
            variation, a push past it, a force limit beyond it) stops there, its force target unreached; the press's
            draws are the same, and its meta keeps the depth it was drawn to as ``depth_limited_from``.

    Returns:
        a :class:`PressProfile` sampled every ``timestep`` s.
    """
    if not (np.isfinite(timestep) and timestep > 0):
        raise ValidationError(f"press_profile: timestep must be > 0 s, got {timestep!r}")
    if not (np.isfinite(radius) and radius > 0):
        raise ValidationError(f"press_profile: radius must be > 0 m, got {radius!r}")
    if not (np.isfinite(approach_gap) and approach_gap >= 0):
        raise ValidationError(f"press_profile: approach_gap must be >= 0 m, got {approach_gap!r}")
    nrm = np.asarray(normal, dtype=float)
    if nrm.shape != (3,) or not np.all(np.isfinite(nrm)) or np.linalg.norm(nrm) < 1e-9:
        raise ValidationError(f"press_profile: normal must be a non-zero 3-vector, got {normal!r}")
    nrm = nrm / np.linalg.norm(nrm)
    rng = np.random.default_rng(seed)
    v = variability
    w = tail_scale(v.tail_dof, seed)

    def normal(size=None):
        # a careless press's deviations are w times a careful one's (w is exactly 1 when off: the same draws)
        return w * rng.standard_normal(size)

    if max_depth is not None and not (np.isfinite(max_depth) and max_depth > 0):
        raise ValidationError(f"press_profile: max_depth must be > 0 m, got {max_depth!r}")
    limited_from = None
    if target.depth is not None:
        depth = target.depth * max(1.0 + v.depth_cv * normal(), 0.2)
        force_target = None
        if (v.push_force > 0 or v.push_stiffness > 0) and depth_for_force is not None:
            # on past the depth until the object pushes back (a soft one is pressed deeper), within a cap
            pushed = float(depth_for_force(v.push_force)) if v.push_force > 0 else 0.0
            if v.push_stiffness > 0:
                pushed = max(pushed, stiff_depth(depth_for_force, v.push_stiffness))
            if np.isfinite(pushed) and pushed > depth:
                depth = min(pushed, v.push_depth_scale * depth)
        if target.force is not None and depth_for_force is not None:
            # Depth and force limit: stop at whichever comes first, as a person pressing a hard sample does.
            force_limit = float(target.force) * v.force_scale * max(1.0 + v.depth_cv * normal(), 0.2)
            depth_at_limit = float(depth_for_force(force_limit))
            if np.isfinite(depth_at_limit) and 0 < depth_at_limit < depth:
                depth, force_target = depth_at_limit, force_limit
        if max_depth is not None and depth > max_depth:
            # no finger presses past what it can: it stops there, short of a force limit further on
            limited_from, depth, force_target = depth, float(max_depth), None
    else:
        if depth_for_force is None:
            raise ValidationError("press_profile: a force target needs depth_for_force (force N -> depth m)")
        force_target = float(target.force) * v.force_scale * max(1.0 + v.depth_cv * normal(), 0.2)
        depth = float(depth_for_force(force_target))
        if not (np.isfinite(depth) and depth > 0):
            raise ValidationError(f"press_profile: depth_for_force({force_target}) gave {depth!r}, expected > 0 m")
    # a careless press lands elsewhere, deeper and tilted, but keeps the person's pace (speed and hold): the rigid
    # drive could not follow a hard foam's ~15 um indentation at twice the speed either (PressShortfall)
    speed_in = target.speed * max(1.0 + v.speed_cv * rng.standard_normal(), 0.2)
    speed_out = target.speed * max(1.0 + v.speed_cv * rng.standard_normal(), 0.2)
    hold = max(target.hold + v.hold_std * rng.standard_normal(), 0.0) if v.hold_std > 0 else target.hold
    dx, dy = (v.lateral_std * normal(2)) if v.lateral_std > 0 else (0.0, 0.0)
    # drawn after the others, and only when asked for, so a press without them replays exactly as before
    tilt = v.tilt_std * normal(2) if v.tilt_std > 0 else None
    if tilt is not None and w != 1.0:
        tilt = np.clip(tilt, -MAX_TILT, MAX_TILT)  # a careless press still keeps the pad on the contact
    slip = v.slip_std * normal(2) if v.slip_std > 0 else None
    tremor = (rng.uniform(*TREMOR_BAND_HZ), rng.uniform(0.0, 2.0 * np.pi)) if v.tremor > 0 else None

    # a minimum-jerk move peaks at 1.875x its mean speed; scale its duration so the peak matches the command
    peak = 1.875 if v.smooth else 1.0
    travel = approach_gap + depth
    t_in = peak * travel / speed_in
    t_out = peak * travel / speed_out
    duration = t_in + hold + t_out
    if not duration / timestep <= MAX_SAMPLES:  # NaN too: a speed of 1e-300 m/s would ask for 1e300 samples
        raise ValidationError(f"press_profile: a press of {duration:.3g} s sampled every {timestep:g} s needs over "
                              f"{MAX_SAMPLES:g} samples: raise the speed (now {target.speed:g} m/s) or shorten the "
                              "hold")
    n_in = max(int(np.ceil(t_in / timestep)), 2) + 1
    n_hold = int(np.ceil(hold / timestep)) if hold > 0 else 0
    n_out = max(int(np.ceil(t_out / timestep)), 2) + 1

    z_top = surface_z + radius + approach_gap
    z_bottom = surface_z + radius - depth
    t = np.concatenate([
        np.linspace(0.0, t_in, n_in),
        t_in + np.linspace(0.0, hold, n_hold + 1)[1:],
        t_in + hold + np.linspace(0.0, t_out, n_out)[1:],
    ])
    z = np.concatenate([
        z_top + (z_bottom - z_top) * _ramp(n_in, v.smooth),
        np.full(n_hold, z_bottom),
        (z_bottom + (z_top - z_bottom) * _ramp(n_out, v.smooth))[1:],
    ])
    if tremor is not None:
        # faded in and out over the whole movement, so the press still starts and ends at rest at z_top
        window = np.sin(np.pi * t / t[-1]) ** 2
        z = z + v.tremor * window * np.sin(2.0 * np.pi * tremor[0] * t + tremor[1])
    t_contact = t_in * _inverse_ramp(approach_gap / travel, v.smooth)
    t_lift = t_in + hold + t_out * _inverse_ramp(depth / travel, v.smooth)
    meta = {
        "radius": float(radius),
        "depth": float(depth),
        "speed": float(target.speed),
        "speed_in": float(speed_in),
        "speed_out": float(speed_out),
        "hold": float(hold),
        "approach_gap": float(approach_gap),
        "normal": [float(c) for c in nrm],
        "mode": "robot" if v == ROBOT else "human",
        "force_target": force_target,
        "seed": int(seed),
        "phases": {
            "approach": [0.0, float(t_contact)],
            "press": [float(t_contact), float(t_in)],
            "hold": [float(t_in), float(t_in + hold)],
            "release": [float(t_in + hold), float(t_lift)],
            "retract": [float(t_lift), float(t[-1])],
        },
    }
    if limited_from is not None:
        meta["depth_limited_from"] = float(limited_from)
    if v.tail_dof > 0:
        meta["tail_scale"] = w
    if tilt is not None:
        meta["tilt"] = [float(a) for a in tilt]
    if slip is not None:
        meta["slip"] = [float(a) for a in slip]
    if tremor is not None:
        meta["tremor"] = {"amplitude": float(v.tremor), "frequency": float(tremor[0]), "phase": float(tremor[1])}
    return PressProfile(t=t, z=z, x=float(target.x + dx), y=float(target.y + dy), surface_z=float(surface_z),
                        meta=meta)


def _inverse_ramp(fraction: float, smooth: bool) -> float:
    """Normalised time at which the ramp reaches ``fraction`` of its travel."""
    if not smooth:
        return fraction
    return float(np.interp(fraction, _SMOOTH_RAMP, _SMOOTH_TIME))

