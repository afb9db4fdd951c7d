"""Stability at the extremes: one press per cell of a matrix of moduli, Poisson ratios, timesteps, speeds, depths
and press locations (centre, edge, corner), each classified as

- ``ok``: finite, physically ordered output (force >= 0, no NaN, force growing with indentation while loading);
- ``diverged``: stopped with SimulationDiverged (its message says what to change);
- ``invalid``: stopped with a ValidationError (ditto), including a press over the step budget;
- ``BUG``: anything else (NaN or disordered output that got through, another exception).

A cell never hangs: the press's physics steps are counted before it runs and a press over ``max_steps`` is
refused with a ValidationError naming the timestep and speed to change.
"""

from __future__ import annotations

import itertools
from dataclasses import asdict, dataclass

import numpy as np

from palpate.core.errors import SimulationDiverged, ValidationError
from palpate.core.session.sources import PressTarget
from palpate.core.world.scene import Material, ObjectSpec, Scene
from palpate.sim.analytic import local_material, run_analytic_press
from palpate.sim.controller import press_profile
from palpate.sim.flex import run_flex_press
from palpate.sim.hertz import hertz_depth_for_force
from palpate.sim.rigid import run_rigid_press

#: Block of the matrix: 40 x 40 mm, 10 mm thick, so 80% of its thickness is an 8 mm press.
BLOCK = (0.04, 0.04, 0.01)
#: Largest number of physics steps one press may take.
MAX_STEPS = 200_000
LOCATIONS = {"centre": (0.0, 0.0), "edge": (0.0195, 0.0), "corner": (0.0195, 0.0195)}


@dataclass(frozen=True)
class Cell:
    """One cell: fidelity, Young's modulus Pa, Poisson ratio, timestep s, speed m/s, depth as a fraction of the
    block's thickness, and where on the block (centre, edge, corner)."""

    fidelity: str
    young: float
    poisson: float
    timestep: float
    speed: float
    depth_fraction: float
    location: str = "centre"


@dataclass
class Outcome:
    """What a cell gave: outcome class, the message (for diverged/invalid/BUG) and the peak force, N."""

    cell: Cell
    outcome: str
    message: str = ""
    peak_force: float = float("nan")

    def to_dict(self) -> dict:
        """JSON-ready form."""
        d = asdict(self.cell)
        d.update(outcome=self.outcome, message=self.message,
                 peak_force=None if not np.isfinite(self.peak_force) else float(self.peak_force))
        return d


def physically_ordered(t: np.ndarray, force: np.ndarray, indentation: np.ndarray) -> str:
    """'' if the trace is finite, non-negative and its force grows with indentation while loading, else why not.

    Loading is up to the deepest point; the force may dip by 5% of its peak (servo ripple, a flex contact moving
    across surface vertices) but must rise overall.
    """
    if not (np.all(np.isfinite(force)) and np.all(np.isfinite(indentation)) and np.all(np.isfinite(t))):
        return "non-finite output"
    if np.any(force < 0) or np.any(indentation < 0):
        return "negative force or indentation"
    k = int(np.argmax(indentation))
    d, f = indentation[: k + 1], force[: k + 1]
    if indentation[k] <= 0 or force.max() <= 0:
        return "no contact"
    order = np.argsort(d, kind="stable")
    fs = f[order]
    drop = np.maximum.accumulate(fs) - fs
    if drop.max() > 0.05 * fs.max() + 1e-9:
        return f"force falls by {drop.max():.3g} N while indentation grows"
    if not fs[-1] > fs[0]:
        return "force does not grow with indentation"
    return ""


def run_cell(cell: Cell, *, max_steps: int = MAX_STEPS) -> Outcome:
    """Press the matrix block once at ``cell`` and classify the result (never raises for a sim failure)."""

    try:
        mat = Material("m", cell.young, cell.poisson)
        obj = ObjectSpec("block", "box", BLOCK, (0.0, 0.0), mat)
        scene = Scene((obj,))
        x, y = LOCATIONS[cell.location]
        target = PressTarget(x, y, depth=cell.depth_fraction * BLOCK[2], speed=cell.speed)
        tip = scene.fingertip
        e_star = local_material(obj, x, y, obj.height).effective_modulus
        profile = press_profile(target, obj.height, radius=tip.radius, timestep=min(cell.timestep, 0.002),
                                depth_for_force=lambda f: hertz_depth_for_force(e_star, tip.radius, f))
        steps = int(np.ceil(profile.duration / cell.timestep))
        if cell.fidelity != "analytic" and steps > max_steps:
            raise ValidationError(
                f"press of {profile.duration:.2f} s at timestep {cell.timestep} s needs {steps} steps, over the "
                f"budget of {max_steps}; raise the timestep or the press speed ({cell.speed} m/s)")
        if cell.fidelity == "analytic":
            trace = run_analytic_press(scene, obj, profile)
        elif cell.fidelity == "rigid":
            trace = run_rigid_press(scene, obj, profile, timestep=cell.timestep)
        else:
            trace = run_flex_press(scene, obj, target, profile, timestep=cell.timestep)
    except SimulationDiverged as exc:
        return Outcome(cell, "diverged", str(exc))
    except ValidationError as exc:
        return Outcome(cell, "invalid", str(exc))
    except Exception as exc:  # noqa: BLE001 - anything else is a bug the matrix must show, not hide
        return Outcome(cell, "BUG", f"{type(exc).__name__}: {exc}")
    why = physically_ordered(trace.t, trace.force, trace.indentation)
    if why and why != "no contact":
        return Outcome(cell, "BUG", why, float(np.nanmax(trace.force)))
    if why == "no contact":
        return Outcome(cell, "BUG", "the press never touched the block", 0.0)
    return Outcome(cell, "ok", "", float(trace.force.max()))


def matrix(fidelities=("analytic", "rigid"), youngs=(1e3, 1e5, 1e8), poissons=(0.0, 0.3, 0.49),
           timesteps=(1e-4, 2e-3, 1e-2), speeds=(0.001, 0.01, 0.2), depth_fractions=(0.1, 0.8),
           locations=("centre", "edge", "corner")) -> list[Cell]:
    """The full product of the given axes, as cells."""
    return [Cell(*c) for c in itertools.product(fidelities, youngs, poissons, timesteps, speeds, depth_fractions,
                                                locations)]


def outcome_counts(outcomes: list[Outcome]) -> dict[str, int]:
    """Number of cells per outcome class."""
    out: dict[str, int] = {}
    for o in outcomes:
        out[o.outcome] = out.get(o.outcome, 0) + 1
    return out
