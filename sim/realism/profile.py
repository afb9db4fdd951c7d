"""Realism profiles: every way a real press departs from an ideal one, as plain validated data.

A :class:`RealismProfile` groups the sources of variability of a press by a human finger carrying a Tekscan-like pad
and a Polhemus-like tracker (see docs/realism.md for each parameter's physics and source):

- :class:`FingerPulp`: the compliant fingertip pulp between the bone (where the tracker sits) and the object;
- the press itself: a :class:`~palpate.sim.controller.Variability` (speed, depth/force, hold, contact point, tilt,
  lateral slip, tremor);
- :class:`TaxelRealism`: per-sensel gain spread left after equilibration, gain drift between presses, creep,
  hysteresis, crosstalk and non-linearity (8-bit quantisation, noise, threshold and saturation stay in the
  scenario's ``[sensors.taxels]``);
- :class:`PoseRealism`: tracker latency and the clock offset NTP leaves between the two computers (noise, rate
  and jitter stay in ``[sensors.pose]``);
- :class:`MaterialRealism`: viscoelastic relaxation, softening on repeated presses, and a cellular material's stress
  plateau.

Presets (:data:`PRESETS`) go from ``ideal`` (the simulation as it was: default human-like press, rigid finger,
ideal sensors, elastic materials; for debugging algorithms) through ``sensors`` (real sensors only) to ``lab``
(everything, literature values). Profiles are also files: :mod:`palpate.sim.realism.profile_file`.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields, replace

import numpy as np

from palpate.core.errors import ValidationError
from palpate.sim.controller import HUMAN, Variability


def _check(owner: str, values: dict[str, tuple[float, float, float]]) -> None:
    """Each value finite and in [lo, hi); raise ValidationError naming ``owner.field``."""
    for name, (v, lo, hi) in values.items():
        if not (np.isfinite(v) and lo <= v < hi):
            raise ValidationError(f"{owner}.{name} must be a finite value in [{lo:g}, {hi:g}), got {v!r}")


@dataclass(frozen=True)
class FingerPulp:
    """The fingertip pulp in series with the object (Serina et al. 1997's exponential law).

    The pulp carries the contact force F with compression delta = ln(1 + m F / b) / m (F = b/m (e^{m delta} - 1)),
    so the bone, where the pose sensor sits, moves d_object + delta: the stiffer the object, the larger the share
    of the movement the finger takes. The contact patch grows with both: a^2 = R (d_object + area_factor delta).

    Attributes:
        compliant: False for a rigid fingertip (a robot's, or the ideal simulation).
        stiffness: b, the pulp's stiffness at zero load, N/m (Serina et al. 1997: ~0.2-1 N/mm).
        stiffening: m, how fast the pulp stiffens with compression, 1/m (Serina: ~0.5-2.5 /mm).
        area_factor: contact-radius growth with pulp compression relative to Hertz (1: Hertz; 2: geometric
            flattening of a soft shell over bone; fingertip areas of ~1 cm^2 at 1 N, Serina et al. 1998, give 2-3).
        stiffness_cv: press-to-press coefficient of variation of b (finger pitch and which part of the pulp
            touches; Serina: stiffness depends on the contact angle).
        pressure_exponent: k of the pad's pressure p ~ (1 - r^2/a^2)^k when the pulp takes the whole approach
            (a stiff object): 1/2 is Hertz's half-space, 1 a thin compressible layer, 2 a thin incompressible
            layer bonded to bone (Johnson 1985, section 5.9); a press's exponent goes from 1/2 towards it with the
            pulp's share of the approach (:mod:`palpate.sim.realism.patch`). 1/2: Hertz's on every object.
    """

    compliant: bool = False
    stiffness: float = 500.0
    stiffening: float = 1000.0
    area_factor: float = 2.0
    stiffness_cv: float = 0.0
    pressure_exponent: float = 0.5

    def __post_init__(self) -> None:
        _check("FingerPulp", {"stiffness": (self.stiffness, 1.0, 1e6), "stiffening": (self.stiffening, 0.0, 1e5),
                              "area_factor": (self.area_factor, 0.0, 10.0),
                              "stiffness_cv": (self.stiffness_cv, 0.0, 2.0),
                              "pressure_exponent": (self.pressure_exponent, 0.5, 3.0)})

    def compression(self, force: np.ndarray, stiffness_scale: float = 1.0) -> np.ndarray:
        """Pulp compression delta, m, under contact force F (N, clipped at 0); 0 everywhere when rigid."""
        f = np.maximum(np.asarray(force, dtype=float), 0.0)
        if not self.compliant:
            return np.zeros_like(f)
        b = self.stiffness * stiffness_scale
        if self.stiffening <= 0:
            return f / b
        return np.log1p(self.stiffening * f / b) / self.stiffening


@dataclass(frozen=True)
class TaxelRealism:
    """Non-idealities of a resistive taxel pad (order of Tekscan's published specifications).

    Attributes:
        sensitivity: the real pad's gain relative to the scenario's ``gain_counts_per_kpa`` (Tekscan's sensitivity
            setting and the pad's own response; what a calibration to recorded counts finds). 1: as the scenario.
        gain_spread: coefficient of variation of the sensels' gains left after equilibration, drawn once per
            session (Tekscan equilibrates to a few percent).
        gain_drift: press-to-press random walk of the whole pad's gain, relative (temperature, shear of the pad
            on the finger).
        hysteresis: how much higher the output reads on unloading than on loading at the same pressure, as a
            fraction of the output (Tekscan: < 4.5%).
        creep: output rise per decade of time a sensel stays loaded, relative (Tekscan: < 3-5% per log time).
        nonlinearity: compression of the response at full scale: raw / (1 + nonlinearity raw / 255) (the ink's
            conductance grows sub-linearly with load).
        crosstalk: fraction of each sensel's output that reads on each of its four neighbours (row/column
            ghosting of the matrix scan).
        activation: mean pressure a sensel needs before its ink conducts, Pa: below it the sensel reads nothing,
            above it its whole pressure (resistive sensors have a turn-on pressure; a soft object's low rim pressure
            leaves sensels silent that the patch covers, so the active area lags the patch most on soft materials).
        activation_cv: coefficient of variation of the turn-on pressure across sensels (log-normal, mean
            ``activation``), drawn once per session: ink thickness and local pre-load differ from sensel to sensel,
            so the number of active sensels grows gradually with pressure instead of all at one pressure. 0: one
            turn-on pressure for the whole pad.
    """

    sensitivity: float = 1.0
    gain_spread: float = 0.0
    gain_drift: float = 0.0
    hysteresis: float = 0.0
    creep: float = 0.0
    nonlinearity: float = 0.0
    crosstalk: float = 0.0
    activation: float = 0.0
    activation_cv: float = 0.0

    def __post_init__(self) -> None:
        _check("TaxelRealism", {"sensitivity": (self.sensitivity, 0.01, 100.0),
                                "activation": (self.activation, 0.0, 1e5),
                                "activation_cv": (self.activation_cv, 0.0, 3.0),
                                "gain_spread": (self.gain_spread, 0.0, 0.5), "gain_drift": (self.gain_drift, 0.0, 0.5),
                                "hysteresis": (self.hysteresis, 0.0, 0.5), "creep": (self.creep, 0.0, 0.5),
                                "nonlinearity": (self.nonlinearity, 0.0, 5.0),
                                "crosstalk": (self.crosstalk, 0.0, 0.2)})

    @property
    def active(self) -> bool:
        """True when any non-ideality is on."""
        # a spread of the turn-on pressure changes nothing without a turn-on pressure
        return self.sensitivity != 1.0 or any(getattr(self, f.name) > 0 for f in fields(self)
                                              if f.name not in ("sensitivity", "activation_cv"))


@dataclass(frozen=True)
class PoseRealism:
    """Timing errors of the pose stream relative to the taxel stream.

    Attributes:
        latency: the tracker's latency, s: a sample stamped t shows the finger at t - latency (Polhemus Liberty:
            ~3.5 ms).
        clock_offset_std: standard deviation of the offset NTP leaves between the two acquisition computers,
            drawn once per session, s (LAN NTP: ~1-10 ms; Windows' w32time of the seed's era: tens of ms).
        clock_wander: press-to-press standard deviation of that offset, s (the NTP loop keeps correcting it).
    """

    latency: float = 0.0
    clock_offset_std: float = 0.0
    clock_wander: float = 0.0

    def __post_init__(self) -> None:
        _check("PoseRealism", {"latency": (self.latency, -0.5, 0.5), "clock_offset_std": (self.clock_offset_std, 0, 1),
                               "clock_wander": (self.clock_wander, 0.0, 1.0)})

    @property
    def active(self) -> bool:
        """True when any timing error is on."""
        return any(getattr(self, f.name) != 0 for f in fields(self))


@dataclass(frozen=True)
class MaterialRealism:
    """What real foams and rubbers add to the elastic law of the contact mechanics.

    Attributes:
        relaxation: fraction of the instantaneous (elastic) force that relaxes away under a held indentation
            (standard linear solid, one Prony term; polyurethane foams: 0.2-0.4).
        relaxation_time: its time constant, s (foams: 0.1-1 s).
        softening: stiffness lost after many presses at one spot, relative (Mullins effect, foam cell-wall
            buckling; recovers over minutes, i.e. not within a session).
        softening_presses: presses over which most of it appears (1 - e^{-k / softening_presses} of it after k).
        plateau_strain: the strain at which a cellular material's cell walls buckle and its stress stops rising
            (open-cell elastomeric foams: ~0.05, Gibson & Ashby, Cellular Solids, ch. 5); past it, under a sphere,
            the mean contact pressure stays at the plateau's and the force grows as the contact area
            (:func:`palpate.sim.realism.material.plateau_factor`). 0: linear-elastic (off).
        plateau_materials: the names of the materials that have the plateau (cellular ones: a sponge, not a
            rubber); the others stay linear-elastic.
        densify_strain: the mean contact strain at which those materials' collapsed cells start to touch and their
            stress rises again (densification; Gibson & Ashby, ch. 5): past it the force grows by d / d_d, d_d
            the indentation at which a sphere's contact reaches it (:func:`palpate.sim.realism.material.
            densify_factor`), so a deep press on a sponge keeps stiffening. 0: none (off); above plateau_strain.
    """

    relaxation: float = 0.0
    relaxation_time: float = 0.5
    softening: float = 0.0
    softening_presses: float = 3.0
    plateau_strain: float = 0.0
    plateau_materials: tuple[str, ...] = ()
    densify_strain: float = 0.0

    def __post_init__(self) -> None:
        _check("MaterialRealism", {"relaxation": (self.relaxation, 0.0, 0.95),
                                   "relaxation_time": (self.relaxation_time, 1e-3, 1e3),
                                   "softening": (self.softening, 0.0, 0.9),
                                   "softening_presses": (self.softening_presses, 0.1, 1e4),
                                   "plateau_strain": (self.plateau_strain, 0.0, 0.5),
                                   "densify_strain": (self.densify_strain, 0.0, 0.6)})
        if not all(isinstance(m, str) and m for m in self.plateau_materials):
            raise ValidationError(f"MaterialRealism.plateau_materials must be material names, "
                                  f"got {self.plateau_materials!r}")
        if (self.plateau_strain > 0 or self.densify_strain > 0) and not self.plateau_materials:
            raise ValidationError("MaterialRealism.plateau_strain or densify_strain > 0 needs plateau_materials: the "
                                  "cellular materials that have them (a rubber has none)")
        if 0 < self.densify_strain <= self.plateau_strain:
            raise ValidationError(f"MaterialRealism.densify_strain ({self.densify_strain}) must exceed plateau_strain "
                                  f"({self.plateau_strain}): cells touch after they buckle")

    def plateau_of(self, material: str | None) -> float:
        """The plateau strain of ``material`` (0: it has none)."""
        return self.plateau_strain if material in self.plateau_materials else 0.0

    def densify_of(self, material: str | None) -> float:
        """The densification strain of ``material`` (0: it has none)."""
        return self.densify_strain if material in self.plateau_materials else 0.0

    def softening_factor(self, earlier_presses: int) -> float:
        """Stiffness left after ``earlier_presses`` presses at the same spot (1 for none)."""
        if self.softening <= 0:
            return 1.0
        return float(1.0 - self.softening * (1.0 - np.exp(-earlier_presses / self.softening_presses)))


@dataclass(frozen=True)
class RealismProfile:
    """Every source of variability of a simulated press (see the module docstring).

    Attributes:
        name: the profile's name (a preset's, or the file stem).
        description: one line on what it is for.
        finger, press, taxels, pose, material: the sources.
        provenance: where the values come from (a preset's references, or the calibration's record: table,
            seeds, objective, statistics); JSON-like, kept as read.
    """

    name: str
    description: str = ""
    finger: FingerPulp = field(default_factory=FingerPulp)
    press: Variability = HUMAN
    taxels: TaxelRealism = field(default_factory=TaxelRealism)
    pose: PoseRealism = field(default_factory=PoseRealism)
    material: MaterialRealism = field(default_factory=MaterialRealism)
    provenance: dict = field(default_factory=dict, compare=False)

    @property
    def is_ideal(self) -> bool:
        """True when the profile changes nothing the simulation did before profiles existed."""
        return (not self.finger.compliant and self.press == HUMAN and not self.taxels.active
                and not self.pose.active and self.material.relaxation == 0 and self.material.softening == 0
                and self.material.plateau_strain == 0 and self.material.densify_strain == 0)


IDEAL = RealismProfile("ideal", "the simulation without profiles: default human-like press, rigid finger, ideal "
                       "sensors and elastic materials (for debugging algorithms)")
SENSORS = RealismProfile(
    "sensors", "ideal finger, press and materials; the pad's and the tracker's non-idealities at typical values",
    taxels=TaxelRealism(gain_spread=0.05, gain_drift=0.03, hysteresis=0.04, creep=0.03, nonlinearity=0.1,
                        crosstalk=0.01),
    pose=PoseRealism(latency=0.0035, clock_offset_std=0.005, clock_wander=0.002),
)
LAB = replace(
    SENSORS, name="lab",
    description="a human finger in a lab: compliant pulp, tilt, slip and tremor, real sensors, viscoelastic "
    "materials; literature values, not fitted",
    finger=FingerPulp(compliant=True, stiffness=500.0, stiffening=1000.0, area_factor=2.0, stiffness_cv=0.2),
    press=replace(HUMAN, tilt_std=float(np.deg2rad(5.0)), slip_std=0.05, tremor=5e-5),
    material=MaterialRealism(relaxation=0.2, relaxation_time=0.5, softening=0.05, softening_presses=3.0),
)
#: The presets, from the ideal simulation to a lab with a human finger.
PRESETS = {p.name: p for p in (IDEAL, SENSORS, LAB)}
