"""The local worker pool: results and failures come back named, a dead worker fails only its task, and workers
are started once and reused."""

from __future__ import annotations

import os

import pytest

from palpate.core.errors import ValidationError
from palpate.core.session.worker_pool import TaskFailure, run_tasks


def _task(kind: str, value: int):
    if kind == "palpate":
        raise ValidationError(f"bad value {value}")
    if kind == "bug":
        raise KeyError(value)
    if kind == "die":
        os._exit(3)
    return os.getpid(), value * value


def test_results_failures_and_a_dead_worker_come_back_and_workers_are_reused():
    tasks = [(i, ("ok", i)) for i in range(6)] + [("p", ("palpate", 7)), ("b", ("bug", 8)), ("d", ("die", 9))]
    tasks += [(10 + i, ("ok", i)) for i in range(4)]
    outcomes = {o.key: o for o in run_tasks(_task, tasks, workers=2)}
    assert set(outcomes) == {k for k, _ in tasks}
    ok = [o for o in outcomes.values() if o.ok]
    assert sorted(o.value[1] for o in ok) == sorted([i * i for i in range(6)] + [i * i for i in range(4)])
    pids = {o.value[0] for o in ok}
    assert os.getpid() not in pids and len(pids) <= 3  # two workers, and one started after the first died
    p, b, d = outcomes["p"].value, outcomes["b"].value, outcomes["d"].value
    assert isinstance(p, TaskFailure) and p.palpate_error and p.message == "bad value 7"
    assert b.type == "KeyError" and not b.palpate_error and "Traceback" in b.traceback
    assert d.type == "WorkerDied" and "exit code 3" in d.message


def test_no_task_starts_no_worker():
    assert list(run_tasks(_task, [], workers=4)) == []


@pytest.mark.parametrize("workers", [1, 3])
def test_every_task_runs_once_on_as_many_workers_as_asked(workers):
    outcomes = list(run_tasks(_task, [(i, ("ok", i)) for i in range(7)], workers=workers))
    assert sorted(o.key for o in outcomes) == list(range(7))
    assert len({o.value[0] for o in outcomes}) == workers
