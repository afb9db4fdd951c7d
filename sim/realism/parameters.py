"""The parameters a realism calibration may fit (:mod:`~palpate.sim.realism.calibrate`): each one's key and search
box, and how a set of values goes into a profile (:func:`with_values`) and into the scenario (:func:`with_scenario`:
the reference materials' moduli and the pad, which are scenario data, not the profile's)."""

from __future__ import annotations

import copy
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.world.scenario import Scenario
from palpate.sim.realism.profile import RealismProfile
from palpate.sim.realism.profile_file import parse_profile, profile_tables


@dataclass(frozen=True)
class FreeParameter:
    """One fitted parameter: its key in the profile file (``section.key``, file units) and its search box.

    ``off``: a value outside the box that turns the parameter off (``press.tail_dof`` = 0); a start there begins
    at the box's end nearest to off (``hi``: the gentlest tail).
    """

    key: str
    lo: float
    hi: float
    log: bool = False
    off: float | None = None

    def value(self, u: float) -> float:
        """The parameter at position u in [0, 1] of its box."""
        u = float(np.clip(u, 0.0, 1.0))
        if self.log:
            return float(np.exp(np.log(self.lo) + u * (np.log(self.hi) - np.log(self.lo))))
        return self.lo + u * (self.hi - self.lo)

    def position(self, v: float) -> float:
        """The position in [0, 1] of the value v (clipped into the box)."""
        if self.off is not None and v == self.off:
            return 1.0
        v = float(np.clip(v, self.lo, self.hi))
        if self.log:
            return float((np.log(v) - np.log(self.lo)) / (np.log(self.hi) - np.log(self.lo)))
        return (v - self.lo) / (self.hi - self.lo)


#: Parameters the command may fit, with their search boxes (physically plausible ranges; docs/realism.md).
FREE_PARAMETERS = {p.key: p for p in (
    FreeParameter("finger.stiffness_n_per_mm", 0.2, 5.0, log=True),
    FreeParameter("finger.stiffening_per_mm", 0.0, 3.0),
    # Up to just below the profile's own bound ([0, 10)): Serina et al. 1998's ~1 cm^2 at 1 N asks ~7.9 (area
    # pi R area_factor delta, R 8 mm, delta 0.51 mm at 1 N on the shipped pulp; docs/realism.md), beyond the
    # old box's 4.
    FreeParameter("finger.area_factor", 1.0, 9.5),
    FreeParameter("finger.stiffness_cv", 0.0, 0.8),
    FreeParameter("finger.pressure_exponent", 0.5, 2.5),
    FreeParameter("press.speed_cv", 0.0, 0.4),
    FreeParameter("press.depth_cv", 0.0, 0.4),
    FreeParameter("press.tilt_deg", 0.0, 12.0),
    FreeParameter("press.slip", 0.0, 0.3),
    FreeParameter("press.tremor_mm", 0.0, 0.3),
    FreeParameter("press.force_scale", 0.05, 1.0, log=True),
    FreeParameter("press.push_force_n", 0.0, 2.0),
    FreeParameter("press.push_depth_scale", 1.0, 4.0),
    FreeParameter("press.push_stiffness_n_per_mm", 0.0, 3.0),
    FreeParameter("press.tail_dof", 1.5, 50.0, log=True, off=0.0),
    FreeParameter("taxels.sensitivity", 0.5, 99.9, log=True),  # the profile refuses 100 ([0.01, 100))
    FreeParameter("taxels.gain_spread", 0.0, 0.3),
    FreeParameter("taxels.gain_drift", 0.0, 0.08),
    FreeParameter("taxels.hysteresis", 0.0, 0.3),
    FreeParameter("taxels.creep", 0.0, 0.2),
    FreeParameter("taxels.nonlinearity", 0.0, 3.0),
    FreeParameter("taxels.activation_kpa", 0.0, 5.0),
    FreeParameter("taxels.activation_cv", 0.0, 1.5),
    FreeParameter("pose.latency_ms", -30.0, 30.0),
    FreeParameter("pose.clock_offset_ms", 0.0, 60.0),
    FreeParameter("pose.clock_wander_ms", 0.0, 60.0),
    FreeParameter("material.relaxation", 0.0, 0.6),
    FreeParameter("material.softening", 0.0, 0.3),
    FreeParameter("material.plateau_strain", 0.02, 0.2),
    FreeParameter("material.densify_strain", 0.1, 0.4),
)}
#: What the command fits unless told otherwise: location (pulp stiffness, pad sensitivity) and spread.
DEFAULT_FREE = ("finger.stiffness_n_per_mm", "finger.stiffening_per_mm", "finger.stiffness_cv", "press.depth_cv",
                "taxels.sensitivity", "taxels.nonlinearity", "taxels.gain_drift", "pose.clock_wander_ms",
                "material.relaxation")


#: Search box of a factor on a reference material's modulus (``young.<material>``): the scenario's moduli are
#: taken as right to within a factor of 3 (a foam is not a steel; an unbounded factor lets a modulus stand in for
#: whatever the other parameters cannot reproduce).
MODULUS_FACTOR_BOX = (1.0 / 3.0, 3.0)


#: The pad's geometry, which seed 000 does not give: its sensel pitch (mm; 4x4 pads on a fingertip, ~1.8-3.2 mm)
#: and the share of it a sensel's side covers (the scenario's [fingertip] pitch_mm and sensel_mm).
PAD_PARAMETERS = {p.key: p for p in (FreeParameter("pad.pitch_mm", 1.8, 3.2), FreeParameter("pad.fill", 0.5, 1.0))}


def free_parameters(keys: Sequence[str], references: Sequence[str] = ()) -> tuple[FreeParameter, ...]:
    """The free parameters named by ``keys`` (``young.<material>`` for one of ``references``, ``pad.*`` of
    :data:`PAD_PARAMETERS`); ValidationError naming the unknown ones and the known."""
    moduli = {f"young.{m}": FreeParameter(f"young.{m}", *MODULUS_FACTOR_BOX, log=True) for m in references}
    known = {**FREE_PARAMETERS, **PAD_PARAMETERS, **moduli}
    unknown = [k for k in keys if k not in known]
    if unknown or not keys:
        raise ValidationError(f"unknown free parameter(s) {unknown or '(none given)'}; known: {', '.join(known)}")
    if len(set(keys)) != len(keys):
        raise ValidationError(f"free parameters repeat: {list(keys)}")
    return tuple(known[k] for k in keys)


def _scenario_key(key: str) -> bool:
    """Whether a free parameter is the scenario's (a modulus factor, the pad) rather than the profile's."""
    return key.startswith(("young.", "pad."))


def _pad_values(tip) -> dict[str, float]:
    """A fingertip's pad as :data:`PAD_PARAMETERS` values: its pitch (mm) and its sensel side over the pitch."""
    return {"pad.pitch_mm": tip.pitch * 1e3, "pad.fill": tip.sensel_size / tip.pitch}


def with_scenario(scenario: Scenario, free: Sequence[FreeParameter], values: Sequence[float]) -> Scenario:
    """The scenario with each ``young.<material>`` factor applied to that material's modulus and the pad's
    ``pad.pitch_mm`` and ``pad.fill`` (sensel side over pitch) set."""
    materials = dict(scenario.materials)
    tip = scenario.fingertip
    pad = _pad_values(tip)
    for p, v in zip(free, values, strict=True):
        if p.key.startswith("young."):
            entry = materials[p.key[6:]]
            materials[p.key[6:]] = replace(entry, material=replace(entry.material, young=entry.material.young * v))
        elif p.key in pad:
            pad[p.key] = float(v)
    if any(p.key in pad for p in free):
        pitch = pad["pad.pitch_mm"] * 1e-3
        tip = replace(tip, pitch=pitch, sensel_size=pad["pad.fill"] * pitch)
    return replace(scenario, materials=materials, fingertip=tip)


def with_values(profile: RealismProfile, free: Sequence[FreeParameter], values: Sequence[float],
                name: str | None = None) -> RealismProfile:
    """The profile with each free parameter set to its value (file units), validated as a file would be."""
    tables = copy.deepcopy(profile_tables(profile))
    for p, v in zip(free, values, strict=True):
        section, key = p.key.split(".", 1)
        if _scenario_key(p.key):
            continue  # the scenario's, not the profile's (with_scenario)
        tables.setdefault(section, {})[key] = float(v)
    if name is not None:
        tables["profile"]["name"] = name
    tables.pop("provenance", None)
    return parse_profile(tables, "<calibration>", profile.name)


def current_values(profile: RealismProfile, free: Sequence[FreeParameter],
                   scenario: Scenario | None = None) -> list[float]:
    """The free parameters' values in ``profile`` (file units): a modulus factor is 1, the pad's are
    ``scenario``'s (ValidationError without it)."""
    tables = profile_tables(profile)
    out = []
    for p in free:
        if p.key.startswith("young."):
            out.append(1.0)
        elif p.key.startswith("pad."):
            if scenario is None:
                raise ValidationError(f"{p.key} is the scenario's pad: its value needs the scenario")
            out.append(_pad_values(scenario.fingertip)[p.key])
        else:
            out.append(float(tables[p.key.split(".")[0]][p.key.split(".")[1]]))
    return out
