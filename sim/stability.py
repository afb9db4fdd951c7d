"""Divergence detection for MuJoCo presses: warnings, NaN, runaway penetration or speed.

MuJoCo does not stop on a blow-up: after a bad acceleration (BADQACC) it silently resets the state and goes on,
so a run can look finished while its second half is garbage. These checks turn every such sign into
:class:`SimulationDiverged` with the parameter to change.
"""

from __future__ import annotations

import numpy as np

from palpate.core.errors import SimulationDiverged, ValidationError

# warnings that mean the integration itself failed (inertia/contact-buffer warnings are model issues)
_FATAL_WARNINGS = ("mjWARN_BADQPOS", "mjWARN_BADQVEL", "mjWARN_BADQACC", "mjWARN_BADCTRL")


def check_warnings(model, data, *, timestep: float, context: str = "") -> None:
    """Raise SimulationDiverged if MuJoCo raised a state warning (BADQACC, BADQVEL, BADQPOS, BADCTRL)."""
    import mujoco

    for name in _FATAL_WARNINGS:
        w = data.warning[int(getattr(mujoco.mjtWarning, name))]
        if w.number > 0:
            raise SimulationDiverged(
                f"MuJoCo {name[7:]} warning {w.number}x at t={data.time:.4f} s{context}: the state was reset; "
                f"reduce the timestep (now {timestep} s), the contact stiffness (young) or the press speed"
            )


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


def check_resolves_press(profile, timestep: float, context: str = "", min_steps: int = MIN_PRESS_STEPS) -> None:
    """Raise ValidationError if the press phase lasts fewer than ``min_steps`` steps of ``timestep`` (s).

    A step longer than the press itself lets the servo skip the contact: the run "succeeds" with zero force
    (found by the stability matrix: flex at 10 ms, a 1 mm press at 0.2 m/s never touched the block).
    """

    t0, t1 = profile.meta.get("phases", {}).get("press", (0.0, profile.duration))
    steps = (t1 - t0) / timestep
    if steps < min_steps:
        raise ValidationError(
            f"the press phase lasts {t1 - t0:.4f} s, only {steps:.1f} steps of {timestep:g} s{context}; "
            f"use a timestep of at most {(t1 - t0) / min_steps:.2g} s, a slower press or a deeper one"
        )
