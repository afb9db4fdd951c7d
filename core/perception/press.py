"""One press's perception: the raw streams of one press in, its press-phase features and 3/2-power fit out.

No memory is involved here: :func:`perceive_press` is what a run, a replay and a benchmark all do with a press
before a haptic memory judges it.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from palpate.core.errors import FitError
from palpate.core.perception.fit import PressFit, fit_press
from palpate.core.perception.pipeline import DEFAULT_CONFIG, PipelineConfig, synced_presses
from palpate.core.perception.segment import Press
from palpate.core.perception.streams import PressRecording, saturated_in, solver_warning_steps


@dataclass(frozen=True)
class PressResult:
    """What one press was perceived as.

    Attributes:
        target: planned (x, y), m (NaN when the source did not say).
        press: the press phase that was found (samples, location, depth), or None when no press was found.
        fit: its 3/2-power fits, or None when no press could be fitted (reasons in ``rejected``).
        rejected: why contacts were rejected or the fit failed.
        truth_force, truth_indentation: the simulation's ground truth over the recording (N, m), if any.
        frames: taxel frames in the recording; saturated_frames: how many had a sensel at the 8-bit ceiling.
        solver_warning_steps: physics steps on which the simulation's solver warned without invalidating the force
            (from the recording's metadata; 0 for real data).
    """

    target: tuple[float, float]
    press: Press | None
    fit: PressFit | None
    rejected: tuple[str, ...] = ()
    truth_force: np.ndarray | None = None
    truth_indentation: np.ndarray | None = None
    frames: int = 0
    saturated_frames: int = 0
    solver_warning_steps: int = 0

    @property
    def location(self) -> tuple[float, float]:
        """Measured (x, y) of the press phase, m; the planned target when no press was found."""
        return self.target if self.press is None else self.press.location

    @property
    def depth(self) -> float:
        """Largest indentation c_D of the press, m (0 when no press was found)."""
        return 0.0 if self.press is None else float(self.press.depth)

    @property
    def params(self) -> np.ndarray | None:
        """[n1, n2, a1, a2] of the fit, or None when there is none."""
        return None if self.fit is None else self.fit.params

    def at_target(self, target: tuple[float, float]) -> PressResult:
        """The same result with the planned target the caller knows."""
        return replace(self, target=(float(target[0]), float(target[1])))


def press_result(press: Press, *, target: tuple[float, float] | None = None, rejected: tuple[str, ...] = (),
                 truth_force: np.ndarray | None = None, truth_indentation: np.ndarray | None = None,
                 features: str = "both", **counted: int) -> PressResult:
    """Fit one segmented press (``features``: see :class:`PipelineConfig`); a fit that fails gives ``fit=None`` with
    the reason appended to ``rejected``. ``counted``: the recording's ``frames``, ``saturated_frames`` and
    ``solver_warning_steps``."""
    try:
        fit = fit_press(press, features)
    except FitError as exc:
        fit, rejected = None, (*rejected, f"fit failed: {exc}")
    location = (float(press.location[0]), float(press.location[1]))
    return PressResult(location if target is None else target, press, fit, tuple(rejected), truth_force,
                       truth_indentation, **counted)


def perceive_press(recording: PressRecording, pipeline_config: PipelineConfig | None = None) -> PressResult:
    """Turn one press's raw streams into features and a 3/2-power fit.

    Returns a PressResult whose ``fit`` is None (with reasons in ``rejected``) when no usable press was found.
    When noise splits the one press that was made, the deepest part is kept and that is said in ``rejected``.
    """
    config = pipeline_config or DEFAULT_CONFIG
    stream, seg = synced_presses(recording, config)
    planned = (recording.meta or {}).get("target")
    planned = planned if isinstance(planned, dict) else {}
    # The planned target, when the source says it (SimSource does); callers that know it replace it anyway.
    target = (float(planned.get("x", np.nan)), float(planned.get("y", np.nan)))
    reasons = tuple(r.reason for r in seg.rejected)
    truth = recording.truth
    tf = None if truth is None else np.asarray(truth.force)
    ti = None if truth is None else np.asarray(truth.indentation)
    counted = {"frames": len(recording.frames), "saturated_frames": saturated_in(stream.counts),
               "solver_warning_steps": solver_warning_steps(recording.meta)}
    if not seg.presses:
        return PressResult(target, None, None, reasons or ("no press found in the streams",), tf, ti, **counted)
    press = max(seg.presses, key=lambda p: p.depth)
    if len(seg.presses) > 1:
        reasons = (*reasons, f"{len(seg.presses)} presses found where one was made; kept the deepest")
    return press_result(press, target=target, rejected=reasons, truth_force=tf, truth_indentation=ti,
                        features=config.features, **counted)
