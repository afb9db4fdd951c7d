"""Stability at the extremes: one press per cell of a matrix of moduli, Poisson ratios, timesteps, speeds, depths,
press locations (centre, edge, corner) and targets (a depth, or a 10 N force), each run the way a user runs it
(:class:`~palpate.sim.source.SimSource`, taxels included) and classified as

- ``ok``: finite, physically ordered output (force >= 0, force growing with indentation while loading) that reached
  its commanded depth within 2% (and, for analytic and rigid, its force target);
- ``diverged``: stopped with SimulationDiverged or PressShortfall (its message says what to change);
- ``invalid``: stopped with a ValidationError (ditto), including a press over the step budget or deeper than 0.75
  tip radii;
- ``BUG``: anything else: NaN, disordered output, a press that missed its target without saying so (a *silent
  miss*), a force more than WRONG off the contact law at the centre (a *silent wrong answer*), another exception.

Cells may set the block's thickness and a soft top layer (a skin, a tenth of the block's modulus): what a press over
a thin base or a thin layer is checked on. The contact law of the press point (the layered solution: within 1.2% of
the FE reference on the validity table's thickness and skin families and on skins down to 0.05 mm) is the
reference of rigid and flex at the centre, where the block is laterally uniform within reach.

A cell never hangs: the step budget refuses a press that would take more than ``max_steps`` steps before it runs.
Each ok cell also reports how many of its taxel frames saturated (counted from the frames).
"""

from __future__ import annotations

import itertools
from dataclasses import asdict, dataclass, replace

import numpy as np

from palpate.core.errors import SimulationDiverged, ValidationError
from palpate.core.perception.streams import saturated_frames
from palpate.core.session.sources import PressTarget
from palpate.core.world.scene import Layer, Material, ObjectSpec, Scene
from palpate.sim.contact.stack import object_law
from palpate.sim.source import SimSource
from palpate.sim.stability import MAX_DEPTH_OVER_RADIUS, MAX_STEPS, REACH_TOLERANCE

#: Block of the matrix: 40 x 40 mm, 10 mm thick, so 80% of its thickness is an 8 mm press.
BLOCK = (0.04, 0.04, 0.01)
LOCATIONS = {"centre": (0.0, 0.0), "edge": (0.0195, 0.0), "corner": (0.0195, 0.0195)}
#: The force target of ``target="force"`` cells, N.
FORCE_TARGET = 10.0
#: A centre press whose peak force is off the contact law by more than this is a silent wrong answer: over the
#: largest error the validity table records for any rung where it holds a press (18%, flex on a lump at 0.2 mm).
WRONG = 0.25
#: A skin's modulus, as a share of the block's.
SKIN_SOFTNESS = 0.1


@dataclass(frozen=True)
class Cell:
    """One cell: fidelity, Young's modulus Pa, Poisson ratio, timestep s, speed m/s, depth as a fraction of the
    block's thickness (the depth limit of a force target), where on the block (centre, edge, corner), and the
    target ("depth" or "force")."""

    fidelity: str
    young: float
    poisson: float
    timestep: float
    speed: float
    depth_fraction: float
    location: str = "centre"
    target: str = "depth"
    thickness: float = BLOCK[2]
    skin: float = 0.0

    def block(self) -> ObjectSpec:
        """The pressed block: BLOCK's sides, the cell's thickness (m), and a skin of ``skin`` m (a tenth of the
        block's modulus, nu 0.3) when > 0."""
        mat = Material("m", self.young, self.poisson)
        layers = (Layer(Material("skin", SKIN_SOFTNESS * self.young, 0.3), self.skin),) if self.skin > 0 else ()
        return ObjectSpec("block", "box", (BLOCK[0], BLOCK[1], self.thickness), (0.0, 0.0), mat, layers=layers)


@dataclass
class Outcome:
    """What a cell gave: outcome class, the message (for diverged/invalid/BUG), the peak force (N), the fraction
    of its taxel frames that saturated, the rung that pressed (``auto``'s choice), its signed force error against
    the contact law (centre presses of rigid and flex; NaN elsewhere) and the physics steps with a solver warning."""

    cell: Cell
    outcome: str
    message: str = ""
    peak_force: float = float("nan")
    saturated: float = 0.0
    fidelity: str = ""
    error: float = float("nan")
    solver_warning_steps: int = 0

    def to_dict(self) -> dict:
        """JSON-ready form."""
        d = asdict(self.cell)
        d.update(outcome=self.outcome, message=self.message, saturated=float(self.saturated),
                 peak_force=None if not np.isfinite(self.peak_force) else float(self.peak_force),
                 fidelity=self.fidelity, error=None if not np.isfinite(self.error) else float(self.error),
                 solver_warning_steps=int(self.solver_warning_steps))
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


def silent_miss(rec) -> str:
    """'' if the press reached what it was commanded (depth within 2%, and a force target within 2% where the
    fidelity's force model set the depth), else what it missed: the rung should have raised and did not."""
    prof = rec.meta.get("profile", {})
    depth = float(prof.get("depth", 0.0))
    reached = float(np.max(rec.truth.indentation))
    if depth > 0 and abs(reached / depth - 1.0) > REACH_TOLERANCE + 0.005 and abs(reached - depth) > 2e-6:
        return f"silent miss: reached {reached * 1e3:.3f} mm of {depth * 1e3:.3f} mm"
    target = prof.get("force_target")
    if target and rec.meta.get("fidelity") in ("analytic", "rigid"):
        peak = float(np.max(rec.truth.force))
        if abs(peak / target - 1.0) > REACH_TOLERANCE + 0.005:
            return f"silent miss: reached {peak:.3g} N of the {target:.3g} N target"
    return ""


def law_error(rec, obj: ObjectSpec, radius: float) -> float:
    """Signed relative error of a centre press's peak force against the contact law at its deepest indentation."""
    reached = float(np.max(rec.truth.indentation))
    law = object_law(obj, 0.0, 0.0, obj.height, radius, min(max(1.25 * reached, reached + 2e-4),
                                                            MAX_DEPTH_OVER_RADIUS * radius))
    return float(np.max(rec.truth.force) / float(law.force_at(reached)) - 1.0)


def run_cell(cell: Cell, *, max_steps: int = MAX_STEPS) -> Outcome:
    """Press the matrix block once at ``cell`` and classify the result (never raises for a sim failure)."""
    try:
        obj = cell.block()
        x, y = LOCATIONS[cell.location]
        depth = cell.depth_fraction * cell.thickness
        force = FORCE_TARGET if cell.target == "force" else None
        source = SimSource(Scene((obj,)), fidelity=cell.fidelity, timestep=cell.timestep, max_steps=max_steps)
        rec = source.press(PressTarget(x, y, depth=depth, force=force, speed=cell.speed))
    except SimulationDiverged as exc:
        return Outcome(cell, "diverged", str(exc))
    except ValidationError as exc:
        return Outcome(cell, "invalid", str(exc))
    except Exception as exc:  # noqa: BLE001 - anything else is a bug the matrix must show, not hide
        return Outcome(cell, "BUG", f"{type(exc).__name__}: {exc}")
    truth = rec.truth
    peak = float(np.nanmax(truth.force))
    sat = saturated_frames(rec.frames) / max(len(rec.frames), 1)
    rung = str(rec.meta.get("fidelity", cell.fidelity))
    warned = int(rec.meta.get("solver_warning_steps", 0))
    why = physically_ordered(truth.t, truth.force, truth.indentation) or silent_miss(rec)
    if why == "no contact":
        return Outcome(cell, "BUG", "the press never touched the block", 0.0, sat, rung, solver_warning_steps=warned)
    if why:
        return Outcome(cell, "BUG", why, peak, sat, rung, solver_warning_steps=warned)
    error = float("nan")
    if cell.location == "centre" and rung in ("bem", "rigid", "flex"):
        error = law_error(rec, obj, source.scene.fingertip.radius)
        if abs(error) > WRONG:
            return Outcome(cell, "BUG", f"silent wrong answer: {rung}'s force is {error:+.0%} off the contact law",
                           peak, sat, rung, error, warned)
    return Outcome(cell, "ok", "", peak, sat, rung, error, warned)


def matrix(fidelities=("analytic", "rigid"), youngs=(1e3, 1e5, 1e8), poissons=(0.0, 0.3, 0.49),
           timesteps=(1e-4, 2e-3, 1e-2), speeds=(0.001, 0.01, 0.2), depth_fractions=(0.1, 0.5),
           locations=("centre", "edge", "corner"), targets=("depth",)) -> list[Cell]:
    """The full product of the given axes, as cells."""
    return [Cell(*c) for c in itertools.product(fidelities, youngs, poissons, timesteps, speeds, depth_fractions,
                                                locations, targets)]


def fuzz_cells(n: int, seed: int = 0, fidelities=("analytic", "rigid", "flex"), stacks: bool = False) -> list[Cell]:
    """``n`` random cells (seeded): E 1 kPa-100 MPa and speed 0.5-300 mm/s log-uniform, nu 0-0.499, depth 0.05-10
    mm, a depth or a 10 N force target, any location, the fidelity's default timestep. ``stacks``: also the
    block's thickness (1-20 mm, log-uniform), a skin on a third of them (0.01-2 mm, log-uniform), nu up to 0.4999 and
    depths to 1.5 thicknesses (drawn after the others, so the cells without them are as they were)."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        cell = Cell(
            fidelity=str(rng.choice(fidelities)), young=float(10 ** rng.uniform(3, 8)),
            poisson=float(rng.uniform(0.0, 0.499)), timestep=float(rng.choice([5e-4, 2e-3, 5e-3])),
            speed=float(10 ** rng.uniform(np.log10(5e-4), np.log10(0.3))),
            depth_fraction=float(rng.uniform(0.005, 1.0)), location=str(rng.choice(list(LOCATIONS))),
            target=str(rng.choice(["depth", "force"])))
        if stacks:
            skin = float(10 ** rng.uniform(-5, np.log10(2e-3))) if rng.uniform() < 1 / 3 else 0.0
            cell = replace(cell, thickness=float(10 ** rng.uniform(-3, np.log10(0.02))), skin=skin,
                           poisson=float(rng.choice([cell.poisson, rng.uniform(0.49, 0.4999)])),
                           depth_fraction=float(cell.depth_fraction * 1.5))
            if cell.skin >= cell.thickness:
                cell = replace(cell, skin=0.5 * cell.thickness)
        out.append(cell)
    return out


def audit_cells() -> list[Cell]:
    """The cells of silent wrong answers found by an audit, each now refused (naming its limit) or answered right:
    a press deeper than the material over the base (4 mm into 2 mm) on every rung; soft skins of 0.02-0.5 mm under
    flex, analytic and auto; a 2 mm block pressed 1-1.8 mm under flex; nu 0.495-0.4999."""
    out = [Cell(f, 5e4, 0.3, 5e-3, 0.01, 2.0, thickness=0.002) for f in ("auto", "analytic", "rigid", "flex")]
    out += [Cell(f, 2e5, 0.45, 5e-3, 0.01, frac, skin=skin)
            for f in ("flex", "analytic", "auto") for skin in (2e-5, 2e-4, 5e-4, 1e-3) for frac in (0.1, 0.2)]
    out += [Cell(f, 2e5, 0.45, 5e-3, 0.01, frac, thickness=0.002) for f in ("flex", "auto")
            for frac in (0.5, 0.75, 0.9)]
    out += [Cell(f, 2e5, nu, 5e-3, 0.01, 0.2) for f in ("flex", "analytic", "rigid", "auto")
            for nu in (0.49, 0.495, 0.499, 0.49995)]
    return out


def outcome_counts(outcomes: list[Outcome]) -> dict[str, int]:
    """Number of cells per outcome class."""
    out: dict[str, int] = {}
    for o in outcomes:
        out[o.outcome] = out.get(o.outcome, 0) + 1
    return out
