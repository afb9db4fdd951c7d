"""Many presses of simulated sources at once, equal to pressing them one at a time.

Each press is planned by its source in the order given (:meth:`SimSource._plan`: its seeds, trajectory, contact
law and realism draws, exactly as one press plans them, so the source's state moves as in a loop); the analytic
presses' physics then runs as one batch on the chosen backend; the other rungs (bem, rigid, flex) run one at a
time, as :meth:`SimSource.press` runs them; every press is then sensed and recorded as one press is.
"""

from __future__ import annotations

import gc
from collections.abc import Sequence
from contextlib import contextmanager

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.perception.streams import PressRecording
from palpate.core.session.sources import PressTarget
from palpate.sim.batch.analytic import AnalyticJob
from palpate.sim.batch.backends import DEFAULT_BACKEND, resolve_backend
from palpate.sim.batch.sensors import Sensing, sense_many
from palpate.sim.planned import PlannedPress

#: The rungs whose physics a batch backend takes; the others run press by press.
BATCHED_FIDELITIES = ("analytic",)


def press_batch(source, targets: Sequence[PressTarget],
                backend: str = DEFAULT_BACKEND) -> list[PressRecording]:
    """``[source.press(t) for t in targets]``, with the analytic presses' physics batched on ``backend``.

    Args:
        source: the simulated source (its n-th press draws from (seed, n), as in a loop).
        targets: the presses, in order.
        backend: ``"cpu"`` (numpy, the default) or a registered backend (:mod:`palpate.sim.batch.backends`).

    Returns:
        one PressRecording per target, equal to the loop's.

    Raises:
        ValidationError: an unknown backend (before any press is planned), a target that is not a PressTarget, or
            what :meth:`SimSource.press` raises for a press; the source has then planned every press up to the
            failing one (a loop would also have run their physics).
    """
    return press_across([(source, t) for t in targets], backend)


def press_across(pairs: Sequence[tuple[object, PressTarget]],
                 backend: str = DEFAULT_BACKEND) -> list[PressRecording]:
    """``[source.press(target) for source, target in pairs]``: presses of several sources (the environments of a
    vector, the variants of a sweep) in one batch, each source's presses in the order given (see
    :func:`press_batch`)."""
    physics = resolve_backend(backend)
    pairs = list(pairs)
    for k, pair in enumerate(pairs):
        # a SimSource by what it does (this module is what SimSource.press_many calls: no import of it here)
        if not (isinstance(pair, tuple) and len(pair) == 2 and callable(getattr(pair[0], "_plan", None))):
            raise ValidationError(f"press_across: item {k} must be a (SimSource, PressTarget) pair, got "
                                  f"{type(pair).__name__}")
        if not isinstance(pair[1], PressTarget):
            raise ValidationError(f"batched presses: target {k} must be a PressTarget, got {type(pair[1]).__name__}")
    return run_planned([(source, source._plan(t)) for source, t in pairs], physics)


@contextmanager
def _collector_paused():
    """The cyclic garbage collector paused (when it runs) while a batch builds its recordings: some 80 small objects
    a press, none of them garbage, that a loop would hand out one press at a time but a batch keeps until the end,
    so the collector would walk the growing heap of them again and again for nothing."""
    was = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was:
            gc.enable()


def run_planned(planned: Sequence[tuple[object, PlannedPress]], physics) -> list[PressRecording]:
    """Run the physics of planned presses (analytic ones as one call of ``physics``, the rest one by one) and
    record each with its own source."""
    with _collector_paused():
        return _run_planned(planned, physics)


def _run_planned(planned: Sequence[tuple[object, PlannedPress]], physics) -> list[PressRecording]:
    traces: list = [None] * len(planned)
    batched = [i for i, (_, plan) in enumerate(planned) if plan.choice.fidelity in BATCHED_FIDELITIES]
    if batched:
        jobs = [AnalyticJob(planned[i][0].scene, planned[i][1].obj, planned[i][1].physics_profile, planned[i][1].law,
                            planned[i][0]._pads) for i in batched]
        got = list(physics(jobs))
        if len(got) != len(jobs):
            raise ValidationError(f"batch backend returned {len(got)} traces for {len(jobs)} presses; it must return "
                                  "one per press, in order")
        for i, trace in zip(batched, got, strict=True):
            traces[i] = trace
    sensed = []
    for k, ((source, plan), trace) in enumerate(zip(planned, traces, strict=True)):
        if trace is None:
            traces[k] = trace = source._physics(plan)
        sensed.append(source._sense(plan, trace))
    streams = sense_many([Sensing(trace, source.scene.taxels, source.scene.fingertip,
                                  np.random.default_rng(plan.s_taxel), response, pose,
                                  np.random.default_rng(plan.s_pose), latency)
                          for (source, plan), (trace, pose, latency, response) in zip(planned, sensed, strict=True)])
    return [source._record(plan, *seen, frames=frames, poses=poses)
            for (source, plan), seen, (frames, poses) in zip(planned, sensed, streams, strict=True)]
