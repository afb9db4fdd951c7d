"""A run's predictive realism check: more simulated training sessions on fresh seeds, and whether the real table
looks like one more of them (:mod:`palpate.core.perception.predictive_check`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from palpate.core.errors import PalpateError
from palpate.core.perception.param_stats import PressTable, table_from_fits
from palpate.core.perception.predictive_check import predictive_check
from palpate.core.session.progress import Progress
from palpate.core.session.training import train_memory
from palpate.core.world.scenario import Scenario

#: Mixed into the seeds of the check's sessions, so they share no seed with the run's own presses.
PREDICTIVE_STREAM = 0x5EED_C4EC


def session_seeds(scenario: Scenario, sessions: int) -> np.ndarray:
    """(sessions, M) the training seeds of each of the check's sessions (one per reference material)."""
    ss = np.random.SeedSequence([PREDICTIVE_STREAM, int(scenario.seed)])
    return np.array([c.generate_state(len(scenario.references)) for c in ss.spawn(sessions)])


@dataclass(frozen=True)
class Sessions:
    """The check's simulated sessions: their tables, (S, M) leave-one-out self posteriors, presses dropped per
    material (fit failed) and the errors of the sessions the simulation could not finish (left out)."""

    tables: tuple[PressTable, ...]
    loo: np.ndarray
    dropped: dict[str, int]
    failed: tuple[str, ...]


def simulate_sessions(scenario: Scenario, make_source, sessions: int, progress: Progress) -> Sessions:
    """``sessions`` training sessions as the run trains (the haptic memory's leave-one-out on each), on
    :func:`session_seeds`."""
    refs = list(scenario.references)
    seeds = session_seeds(scenario, sessions)
    tables, loo, dropped, failed = [], [], dict.fromkeys(refs, 0), []
    progress.start("predictive check sessions", len(seeds))
    for k, s in enumerate(seeds):
        try:
            result = train_memory(scenario, make_source, s, Progress(enabled=False))
        except PalpateError as err:  # e.g. a press the drive cannot follow: said, and the session left out
            failed.append(str(err))
            progress.update(k + 1)
            continue
        tables.append(table_from_fits({name: [r.fit for r in rs] for name, rs in result.presses.items()}))
        loo.append(np.diag(result.crossval.mean_posterior))
        for name, n in result.dropped.items():
            dropped[name] += n
        progress.update(k + 1)
    if failed:
        progress.message(f"predictive check: {len(failed)} of {len(seeds)} sessions failed and are left out "
                         f"(first: {failed[0]})")
    return Sessions(tuple(tables), np.array(loo).reshape(len(tables), len(refs)), dropped, tuple(failed))


def predictive_report(scenario: Scenario, make_source, real: PressTable, progress: Progress) -> dict:
    """Simulate ``scenario.realism.predictive_sessions`` sessions (:func:`simulate_sessions`) and judge ``real``
    against them: the check's ``to_dict()`` with the sessions' ``dropped_presses`` and ``failed_sessions``."""
    sim = simulate_sessions(scenario, make_source, scenario.realism.predictive_sessions, progress)
    check = predictive_check(real, sim.tables, list(scenario.references), session_loo=sim.loo)
    return check.to_dict() | {"dropped_presses": sim.dropped, "failed_sessions": list(sim.failed)}
