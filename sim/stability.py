"""Divergence detection for MuJoCo presses: warnings, NaN, runaway penetration or speed.

MuJoCo does not stop on a blow-up: after a bad acceleration (BADQACC) it silently resets the state and goes on,
so a run can look finished while its second half is garbage. These checks turn every such sign into
:class:`SimulationDiverged` with the parameter to change.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from palpate.core.errors import PressShortfall, SimulationDiverged, ValidationError

# warnings that mean the integration itself failed (inertia/contact-buffer warnings are model issues)
_FATAL_WARNINGS = ("mjWARN_BADQPOS", "mjWARN_BADQVEL", "mjWARN_BADQACC", "mjWARN_BADCTRL")


def _raised(data, names: tuple[str, ...]) -> tuple[str, int] | None:
    """The first of MuJoCo's warnings ``names`` (mjWARN_*) raised on ``data``: its short name and count, else None."""
    import mujoco

    for name in names:
        number = int(data.warning[int(getattr(mujoco.mjtWarning, name))].number)
        if number > 0:
            return name.removeprefix("mjWARN_"), number
    return None


def check_warnings(model, data, *, timestep: float, context: str = "") -> None:
    """Raise SimulationDiverged if MuJoCo raised a state warning (BADQACC, BADQVEL, BADQPOS, BADCTRL)."""
    raised = _raised(data, _FATAL_WARNINGS)
    if raised is not None:
        name, number = raised
        raise SimulationDiverged(
            f"MuJoCo {name} warning {number}x at t={data.time:.4f} s{context}: the state was reset; "
            f"reduce the timestep (now {timestep} s), the contact stiffness (young) or the press speed"
        )


#: Warnings after which a step's force is not the model's either: a buffer overflowed, so contacts or constraint
#: rows were dropped (the flex press raises them beside the state warnings).
DROPPED_WARNINGS = ("mjWARN_CONTACTFULL", "mjWARN_CNSTRFULL")


def check_dropped(data, *, timestep: float, context: str = "") -> None:
    """Raise SimulationDiverged if MuJoCo dropped contacts or constraint rows (CONTACTFULL, CNSTRFULL)."""
    raised = _raised(data, DROPPED_WARNINGS)
    if raised is not None:
        name, number = raised
        raise SimulationDiverged(
            f"MuJoCo {name} warning {number}x at t={data.time:.4f} s{context}: contacts or constraints "
            "were dropped, so the force is not the model's; press less deep (fewer contacts) or use fidelity "
            f"'analytic' or 'rigid' (timestep {timestep} s)"
        )


def inertia_warnings(data) -> int:
    """How many times MuJoCo raised mjWARN_INERTIA on ``data`` since its last reset."""
    import mujoco

    return int(data.warning[int(mujoco.mjtWarning.mjWARN_INERTIA)].number)


@dataclass(frozen=True)
class SolverWarnings:
    """The MuJoCo warnings of one press that leave its force valid, counted so that none is silent.

    Attributes:
        steps: physics steps the press ran.
        inertia_steps: steps that raised mjWARN_INERTIA. Under the discrete integrator it means MuJoCo's iterative
            solve of the effective inertia M + h D + h^2 K (preconditioned by 3x3 blocks per vertex) ran out of
            ``iterations`` (a stiff thin layer over a soft base conditions it badly). That solve only gives the
            constraint solver a starting point; the force is the constraint solver's. A higher ``iterations``
            (``run_flex_press(iterations=1000)``, a scenario's ``flex_iterations``) clears it; a run warns with that
            advice
            (:func:`palpate.core.session.report.solver_warning`).
        iterations: the iteration limit both solves ran with (MuJoCo's opt.iterations).
    """

    steps: int
    inertia_steps: int
    iterations: int

    def to_dict(self) -> dict:
        """The trace's (and recording's) metadata entry."""
        return {"steps": self.steps, "inertia_steps": self.inertia_steps, "iterations": self.iterations}


def check_run(
    *, t: np.ndarray, indentation: np.ndarray, velocity: np.ndarray, max_depth: float, speed: float,
    timestep: float, young: float, context: str = "",
) -> None:
    """Check a finished (or aborted) run for NaN, runaway penetration and runaway speed.

    Args:
        t: times, s; indentation: tip penetration, m; velocity: tip speed along the press axis, m/s.
        max_depth: commanded indentation, m (penetration beyond ~2x it plus 2 mm is a blow-up).
        speed: commanded press speed, m/s (a tip moving 20x faster plus 0.1 m/s is a blow-up).
        timestep: physics timestep, s; young: contact modulus, Pa (named in the message).
    """
    bad = ~(np.isfinite(indentation) & np.isfinite(velocity))
    if bad.any():
        i = int(np.argmax(bad))
        raise SimulationDiverged(
            f"NaN in the tip state at t={t[i]:.4f} s{context}; reduce the timestep (now {timestep} s) or the "
            f"contact stiffness (young={young:g} Pa)"
        )
    limit_speed = 20.0 * speed + 0.1
    fast = np.abs(velocity) > limit_speed
    if fast.any():
        i = int(np.argmax(fast))
        raise SimulationDiverged(
            f"runaway tip speed {abs(velocity[i]):.3g} m/s (commanded {speed} m/s) at t={t[i]:.4f} s{context}: "
            f"energy is being injected by the contact; reduce the timestep (now {timestep} s) or the contact "
            f"stiffness (young={young:g} Pa)"
        )
    limit_depth = 2.0 * max_depth + 0.002
    over = indentation > limit_depth
    if over.any():
        i = int(np.argmax(over))
        raise SimulationDiverged(
            f"runaway penetration {indentation[i] * 1e3:.2f} mm (commanded {max_depth * 1e3:.2f} mm) at "
            f"t={t[i]:.4f} s{context}; reduce the timestep (now {timestep} s), the contact stiffness "
            f"(young={young:g} Pa) or the press speed ({speed} m/s)"
        )


#: Fewest physics steps the press phase (first contact to deepest point) may span.
MIN_PRESS_STEPS = 10
#: Most physics steps one press may take by default (a press over it is refused before it runs).
MAX_STEPS = 200_000


def check_iterations(iterations, name: str) -> int:
    """``iterations`` (MuJoCo's opt.iterations for a flex press) as an int; ValidationError naming ``name`` unless
    it is an integer >= 1."""
    if isinstance(iterations, bool) or not isinstance(iterations, (int, np.integer)) or iterations < 1:
        raise ValidationError(f"{name} must be an integer >= 1, got {iterations!r}")
    return int(iterations)


def check_step_budget(duration: float, timestep: float, max_steps: int, context: str = "") -> int:
    """Number of steps of ``timestep`` (s) a press of ``duration`` (s) takes; ValidationError over ``max_steps``
    (nothing runs for minutes without saying so), naming the timestep and the speed to change."""
    steps = int(np.ceil(duration / timestep)) + 1
    if steps > max_steps:
        raise ValidationError(
            f"the press of {duration:.2f} s needs {steps} steps of {timestep:g} s{context}, over the budget of "
            f"{max_steps}; use a longer timestep or a faster press (or raise max_steps)"
        )
    return steps


def check_resolves_press(profile, timestep: float, context: str = "", min_steps: int = MIN_PRESS_STEPS,
                         knobs: str = "") -> None:
    """Raise ValidationError if the press phase lasts fewer than ``min_steps`` steps of ``timestep`` (s).

    A step longer than the press itself lets the servo skip the contact: the run "succeeds" with zero force
    (found by the stability matrix: flex at 10 ms, a 1 mm press at 0.2 m/s never touched the block).
    ``knobs`` names what the caller can change (default: the timestep, the speed, the depth).
    """

    t0, t1 = profile.meta.get("phases", {}).get("press", (0.0, profile.duration))
    steps = (t1 - t0) / timestep
    if steps < min_steps:
        advice = knobs or (f"a timestep of at most {(t1 - t0) / min_steps:.2g} s, a slower press or a deeper one")
        raise ValidationError(
            f"the press phase lasts {t1 - t0:.4f} s, only {steps:.1f} steps of {timestep:g} s{context}; use {advice}"
        )


#: Deepest press any fidelity accepts, in tip radii: beyond it the contact nears the sphere's equator, where the
#: small-strain contact mechanics of every level (and of the FE reference) no longer describe a press.
MAX_DEPTH_OVER_RADIUS = 0.75
#: A press must reach its commanded depth (and force, where the fidelity's force model set the depth) within this.
REACH_TOLERANCE = 0.02


def check_depth(profile, radius: float, context: str = "") -> None:
    """Refuse (ValidationError) a press deeper than MAX_DEPTH_OVER_RADIUS tip radii of ``radius`` m."""
    depth = float(profile.meta.get("depth", 0.0))
    # a press scaled to stop exactly at the limit may land a rounding error past it
    if depth > MAX_DEPTH_OVER_RADIUS * radius * (1.0 + 1e-9):
        raise ValidationError(
            f"indentation {depth * 1e3:.2f} mm is over {MAX_DEPTH_OVER_RADIUS} tip radii ({radius * 1e3:.1f} mm "
            f"tip){context}: the contact would reach the sphere's equator; press at most "
            f"{MAX_DEPTH_OVER_RADIUS * radius * 1e3:.2f} mm deep (or a lower force target), or use a larger tip radius"
        )


def law_depth(profile) -> float:
    """Deepest indentation (m) a press's contact law must cover: the commanded depth with room for overshoot."""
    depth = float(profile.meta.get("depth", 0.0))
    radius = float(profile.meta.get("radius", 0.008))
    return float(min(MAX_DEPTH_OVER_RADIUS * radius, max(1.25 * depth, depth + 2e-4)))


def check_reached(reached: float, peak_force: float, profile, context: str = "", *, knobs: str = "",
                  check_force: bool = True) -> None:
    """Raise PressShortfall if the press missed its commanded depth, or its force target, by over 2%.

    Args:
        reached: the depth the tip reached along the press axis, m (commanded depth + how far the tip went past
            its deepest setpoint).
        peak_force: the largest contact force, N.
        profile: the press profile (meta "depth", "force_target").
        knobs: what the caller can change, named in the message.
        check_force: compare the peak force with a force target (only where the fidelity's own force model set
            the commanded depth).
    """
    depth = float(profile.meta.get("depth", 0.0))
    target = profile.meta.get("force_target")
    advice = knobs or "slow the press or stiffen the drive"
    if depth > 0 and abs(reached / depth - 1.0) > REACH_TOLERANCE and abs(reached - depth) > 1e-6:
        raise PressShortfall(
            f"the press reached {reached * 1e3:.3f} mm of the commanded {depth * 1e3:.3f} mm "
            f"({100 * (reached / depth - 1):+.1f}%){context}; {advice}"
        )
    if check_force and target and abs(peak_force / float(target) - 1.0) > REACH_TOLERANCE:
        raise PressShortfall(
            f"the press reached {peak_force:.3g} N of the {float(target):.3g} N target "
            f"({100 * (peak_force / float(target) - 1):+.1f}%){context}; {advice}"
        )
