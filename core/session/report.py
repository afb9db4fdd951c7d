"""The JSON reports of a run and of a replay, built from typed results at the last moment.

Nothing NaN or infinite may reach a report: :func:`assert_finite` refuses it, naming the key.
"""

from __future__ import annotations

import importlib.metadata as md
import platform
from dataclasses import dataclass

import numpy as np

from palpate.core import __version__
from palpate.core.errors import PalpateError
from palpate.core.mapping.accuracy import map_accuracy
from palpate.core.mapping.calibration import calibration_sample, reliability_table
from palpate.core.mapping.regions import map_region_report
from palpate.core.perception.fit import PressFit
from palpate.core.session.explore import ObjectResult, PressStep

SUMMARY_FORMAT = "palpate-run-summary"
SUMMARY_VERSION = 1


def fit_summary(fit: PressFit | None) -> dict | None:
    """The per-press fit as reported: n1, n2, phi_n, a1, a2, phi_a (c_D in mm, c_A in mm^2); None without fit."""
    if fit is None:
        return None
    return {**{k: float(getattr(fit, k)) for k in ("n1", "n2", "phi_n", "a1", "a2", "phi_a")},
            "features": fit.features}


def _posterior(p: np.ndarray | None) -> list[float] | None:
    return None if p is None else [float(v) for v in p]


def step_row(step: PressStep) -> dict:
    """One exploration press as summary.json reports it (cells 1-based, as seed 000's tables)."""
    res = step.result
    return {"k": step.k, "cell": [step.cell[0] + 1, step.cell[1] + 1], "target_m": list(step.target),
            "planned_depth_m": step.planned_depth, "score": step.score, "location_m": list(res.location),
            "depth_m": res.depth, "fit": fit_summary(res.fit), "rejected": list(res.rejected),
            "posterior": _posterior(step.posterior), "mean_entropy": step.mean_entropy,
            "mean_entropy_postprocessed": step.mean_entropy_postprocessed,
            "accuracy_explored": step.accuracy_explored,
            "accuracy_all_cells_postprocessed": step.accuracy_postprocessed,
            "frames": res.frames, "saturated_frames": res.saturated_frames}


#: A run warns when more than this fraction of an object's (or a material's) taxel frames saturate.
SATURATION_WARNING = 0.05


@dataclass(frozen=True)
class SaturationCount:
    """Taxel frames over a set of presses, and how many had a sensel at the 8-bit ceiling."""

    frames: int
    saturated_frames: int

    @property
    def fraction(self) -> float:
        return self.saturated_frames / self.frames if self.frames else 0.0

    def to_dict(self) -> dict:
        """The summary.json entry: frames, saturated_frames, fraction."""
        return {"frames": self.frames, "saturated_frames": self.saturated_frames, "fraction": self.fraction}


def saturation(results) -> SaturationCount:
    """Saturated taxel frames over a set of PressResults."""
    return SaturationCount(frames=sum(r.frames for r in results),
                           saturated_frames=sum(r.saturated_frames for r in results))


def saturation_warning(what: str, counted: SaturationCount) -> str | None:
    """The run's warning when ``counted`` is past SATURATION_WARNING, else None."""
    if counted.fraction <= SATURATION_WARNING:
        return None
    return (f"warning: {what}: {counted.saturated_frames} of {counted.frames} taxel frames "
            f"({counted.fraction:.0%}) have a sensel at the 8-bit ceiling (255): their pressure is clipped; "
            "lower the taxel gain (sensors.taxels.gain_counts_per_kpa) or the press force/depth")


@dataclass(frozen=True)
class SolverWarningCount:
    """Presses over a set, how many had physics steps on which the simulation's solver warned without
    invalidating the force (flex: MuJoCo's M + K solve ran out of iterations), and those steps in all."""

    presses: int
    warned_presses: int
    warned_steps: int

    def to_dict(self) -> dict:
        """The summary.json entry: presses, warned_presses, warned_steps."""
        return {"presses": self.presses, "warned_presses": self.warned_presses, "warned_steps": self.warned_steps}


def solver_warnings(results) -> SolverWarningCount:
    """Solver warnings over a set of PressResults."""
    steps = [r.solver_warning_steps for r in results]
    return SolverWarningCount(presses=len(steps), warned_presses=sum(1 for s in steps if s > 0),
                              warned_steps=sum(steps))


def solver_warning(what: str, counted: SolverWarningCount) -> str | None:
    """The run's warning when any press of ``counted`` had solver warnings, else None."""
    if not counted.warned_presses:
        return None
    return (f"warning: {what}: {counted.warned_presses} of {counted.presses} presses had {counted.warned_steps} "
            "physics steps on which MuJoCo's M + K solve ran out of iterations (mjWARN_INERTIA; the force stands, "
            "see each recording's physics.solver_warnings); to clear it raise the scenario's flex_iterations "
            "(e.g. flex_iterations = 1000 under [scenario]; it costs time) or use fidelity 'rigid' or 'analytic'")


def calibration_of(obj: ObjectResult, bins: int = 10) -> dict | None:
    """Calibration of the post-processed map's most probable material against ground truth (ECE and the
    reliability table, see :func:`palpate.core.mapping.calibration.reliability_table`); None without truth."""
    if not (np.asarray(obj.truth) >= 0).any():
        return None
    conf, right, undecided = calibration_sample(obj.post.probabilities, obj.truth)
    return reliability_table(conf, right, bins=bins, undecided=undecided).to_dict()


def run_calibration(objects: list[ObjectResult], bins: int = 10) -> dict | None:
    """Calibration pooled over every object with ground truth (the run's ECE); None when none has truth."""
    samples = [calibration_sample(o.post.probabilities, o.truth) for o in objects if (np.asarray(o.truth) >= 0).any()]
    if not samples:
        return None
    conf, right, undecided = zip(*samples, strict=True)
    return reliability_table(np.concatenate(conf), np.concatenate(right), bins=bins,
                             undecided=int(sum(undecided))).to_dict()


def object_summary(obj: ObjectResult) -> dict:
    """One explored object as summary.json reports it."""
    rows = [step_row(s) for s in obj.steps]
    return {
        "name": obj.name,
        "map": obj.geometry.kind,
        "grid": {"origin_m": list(obj.geometry.origin), "cell_size_m": obj.geometry.cell_size,
                 "shape": list(obj.grid.probabilities.shape[:-1])},
        "presses": len(rows),
        "policy": obj.policy,
        "stop_reason": obj.stop_reason,
        "per_press": rows,
        "regions": [[c + 1, r + 1] for c, r in obj.regions],
        "material_regions": map_region_report(obj.geometry, obj.post.probabilities),
        "posterior_per_cycle": [[list(row) for row in cycle] for cycle in obj.cycle_posteriors],
        "accuracy": {"explored_before_postprocessing": map_accuracy(obj.grid.probabilities, obj.truth,
                                                                    obj.grid.explored),
                     "all_cells_before_postprocessing": map_accuracy(obj.grid.probabilities, obj.truth),
                     "all_cells_after_postprocessing": map_accuracy(obj.post.probabilities, obj.truth),
                     "by_walls_after_postprocessing": accuracy_by_walls(obj)},
        "mean_entropy_after_each_press": [r["mean_entropy"] for r in rows],
        "mean_entropy_after_postprocessing": float(obj.post.mean_entropy()),
        "true_materials": list(obj.true_materials),
        "saturation": saturation([s.result for s in obj.steps]).to_dict(),
        "solver_warnings": solver_warnings([s.result for s in obj.steps]).to_dict(),
        # the map's posteriors came from the memory's kinesthetic and cutaneous models, or (a finger without a pad,
        # c_P from its joint currents) from the kinesthetic one alone
        "features": sorted({r["fit"]["features"] for r in rows if r["fit"] is not None}),
        "calibration": calibration_of(obj),
    }


def accuracy_by_walls(obj: ObjectResult) -> dict | None:
    """summary.json's split of the post-processed accuracy into the cells a press reads without feeling a second
    material (``clear``) and the cells with a wall within its contact radius (``near``): a press there feels both
    sides, so those cells bound what any policy can reach. None for voxel maps or without ground truth."""
    mask = obj.clear_of_walls
    truth = np.asarray(obj.truth)
    if mask is None or not (truth >= 0).any():
        return None
    p = obj.post.probabilities
    return {"clear": {"cells": int(np.count_nonzero(mask & (truth >= 0))), "accuracy": map_accuracy(p, truth, mask)},
            "near": {"cells": int(np.count_nonzero(~mask & (truth >= 0))), "accuracy": map_accuracy(p, truth, ~mask)}}


def versions() -> dict[str, str]:
    """Versions of palpate, Python and the libraries whose numbers a result depends on."""
    out = {"palpate": __version__, "python": platform.python_version()}
    for pkg in ("numpy", "scipy", "mujoco", "matplotlib"):
        try:
            out[pkg] = md.version(pkg)
        except md.PackageNotFoundError:
            pass
    return out


def assert_finite(obj, path: str = "summary") -> None:
    """No NaN or infinity may reach a report: PalpateError naming the first bad key."""
    if isinstance(obj, float) and not np.isfinite(obj):
        raise PalpateError(f"{path} is not finite ({obj}); refusing to write a report with NaN")
    if isinstance(obj, dict):
        for k, v in obj.items():
            assert_finite(v, f"{path}.{k}")
    elif isinstance(obj, (list, tuple)):
        for i, v in enumerate(obj):
            assert_finite(v, f"{path}[{i}]")
