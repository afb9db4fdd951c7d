"""Batched :func:`palpate.sim.api.simulate_press`: N presses on blocks of N materials, depths and seeds at once."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.perception.streams import PressRecording
from palpate.sim.api import check_press_arguments, press_setup
from palpate.sim.batch.backends import DEFAULT_BACKEND, resolve_backend
from palpate.sim.batch.press import run_planned


@dataclass(frozen=True)
class PressSpec:
    """One press of :func:`simulate_presses`: the arguments of :func:`palpate.sim.api.simulate_press` (SI units).

    Attributes:
        young: Young's modulus, Pa.  poisson: Poisson ratio.
        fidelity: "analytic", "bem", "rigid", "flex" or "auto" (only analytic presses are batched).
        depth: indentation to reach, m (None when pressing to ``options["force"]``).
        speed: press speed, m/s.  seed: seed of press variability and sensor noise.
        options: simulate_press's scene options (size, thickness, force, variability, fingertip, ...).
    """

    young: float
    poisson: float = 0.3
    fidelity: str = "rigid"
    depth: float | None = 0.004
    speed: float = 0.01
    seed: int = 0
    options: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        check_press_arguments(self.young, self.poisson, self.depth, self.speed, self.seed, "PressSpec")
        if not isinstance(self.options, dict):
            raise ValidationError(f"PressSpec.options must be a dict of simulate_press's scene options, got "
                                  f"{type(self.options).__name__}")


def simulate_presses(specs: Sequence[PressSpec], backend: str = DEFAULT_BACKEND) -> list[PressRecording]:
    """``[simulate_press(...) for spec in specs]`` with the analytic presses' physics batched on ``backend``.

    Each spec gets its own fresh source, as :func:`~palpate.sim.api.simulate_press` makes one; specs that differ
    only in their seed and press as a robot (whose press does not depend on its seed) share their contact law, which
    each would solve alike. Presses of other rungs run one at a time, as simulate_press runs them.

    Raises:
        ValidationError: an unknown backend or a spec that is not a PressSpec (before any work), or what
            simulate_press raises for a spec.
    """
    physics = resolve_backend(backend)
    specs = list(specs)
    for k, s in enumerate(specs):
        if not isinstance(s, PressSpec):
            raise ValidationError(f"simulate_presses: spec {k} must be a PressSpec, got {type(s).__name__}")
    laws: dict = {}
    memos: dict = {}
    pads: dict = {}
    planned = []
    blas = None
    for k, s in enumerate(specs):
        group = _law_group(s, k)
        source, target = press_setup(s.young, s.poisson, s.fidelity, s.depth, s.speed, s.seed,
                                     laws=laws.setdefault(group, {}), **s.options)
        # what fresh sources would each find alike, found once: the process's BLAS libraries (a file read), the
        # pad's footprints (keyed on fingertip and contact centre), and, within a law group, the laws a press point
        # was last given (kept only while the group's law cache is unchanged, see SimSource._law)
        blas = source._blas = blas if blas is not None else source._blas_controller()
        source._pads = pads
        source._law_memo = memos.setdefault(group, {})
        planned.append((source, source._plan(target)))
    return run_planned(planned, physics)


def _law_group(spec: PressSpec, index: int):
    """Specs with one key solve one contact law (a robot's press is the same whatever its seed); a spec with
    options that cannot be compared has a key of its own."""
    robot = spec.options.get("variability", "robot") == "robot"
    if not all(np.isfinite(v) for v in (spec.young, spec.poisson, spec.speed)):
        return ("own", index)  # simulate_press refuses it, with its own message
    try:
        key = (spec.young, spec.poisson, spec.fidelity, spec.depth, spec.speed, None if robot else spec.seed,
               tuple(sorted(spec.options.items())))
        hash(key)
    except TypeError:
        return ("own", index)
    return key
