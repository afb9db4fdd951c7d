"""A local pool of worker processes that are started once and never outlive the process that started them.

Why not ``concurrent.futures.ProcessPoolExecutor``: a parent killed with SIGKILL left its workers running the
queued variants and then idling forever, holding the caller's stdout (a ``| tee`` never ended). Here:

- each worker is handed one task at a time over its own pipe, so nothing is queued inside a worker;
- a worker ends when its parent does: on Linux the kernel sends it SIGKILL (``PR_SET_PDEATHSIG``), elsewhere a
  watchdog thread sees the parent's pid change; and a worker whose pipe closes exits;
- the parent ends its workers on every way out it can catch (normal end, an exception, Ctrl-C, and SIGTERM or
  SIGHUP, which :func:`terminating_signals` turns into an exception);
- workers are forked where the platform allows, so they start with every module the parent has imported, and
  are started once: a worker runs task after task.

Tasks run in the worker; a task's exception comes back as a :class:`TaskFailure` (type, message, and the
traceback text), never as a crashed pool.
"""

from __future__ import annotations

import contextlib
import ctypes
import multiprocessing as mp
import os
import signal
import sys
import threading
import time
import traceback
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from multiprocessing.connection import wait

from palpate.core.errors import PalpateError, Terminated

#: Seconds between the watchdog's looks at the parent's pid (where the kernel cannot signal the worker).
WATCHDOG_PERIOD = 0.5
#: Seconds a worker is given to end after SIGTERM before it is killed.
TERMINATE_GRACE = 2.0


@dataclass(frozen=True)
class Outcome:
    """What became of one task: its key, whether it succeeded, and its result or :class:`TaskFailure`."""

    key: object
    ok: bool
    value: object


@dataclass(frozen=True)
class TaskFailure:
    """A task that raised (or whose worker died): the exception's type name, message and traceback text."""

    type: str
    message: str
    traceback: str = ""
    palpate_error: bool = False


@contextlib.contextmanager
def terminating_signals():
    """Within the block, SIGTERM and SIGHUP raise :class:`Terminated` in the main thread (elsewhere: no change)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum, _frame):
        raise Terminated(signum, signal.Signals(signum).name)

    wanted = [s for s in (getattr(signal, "SIGTERM", None), getattr(signal, "SIGHUP", None)) if s is not None]
    old = {s: signal.signal(s, handler) for s in wanted}
    try:
        yield
    finally:
        for s, h in old.items():
            signal.signal(s, h)


def _die_with_parent(parent: int) -> None:
    if sys.platform.startswith("linux"):
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
        except (OSError, AttributeError):
            pass
    if os.getppid() != parent:  # the parent died before the line above took effect
        os._exit(1)

    def watchdog():
        while True:
            time.sleep(WATCHDOG_PERIOD)
            if os.getppid() != parent:
                os._exit(1)

    threading.Thread(target=watchdog, name="palpate-parent-watchdog", daemon=True).start()


def _worker(conn, fn: Callable, parent: int) -> None:
    # The parent decides when to stop: Ctrl-C in a terminal reaches the whole process group, and the parent then
    # ends its workers itself. SIGTERM ends a worker at once.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    for name in ("SIGTERM", "SIGHUP"):
        if hasattr(signal, name):
            signal.signal(getattr(signal, name), signal.SIG_DFL)
    _die_with_parent(parent)
    while True:
        try:
            task = conn.recv()
        except (EOFError, OSError):
            os._exit(0)
        if task is None:
            os._exit(0)
        key, args = task
        try:
            reply = Outcome(key, True, fn(*args))
        except BaseException as exc:  # noqa: BLE001 - every failure goes back to the parent, named
            reply = Outcome(key, False, TaskFailure(type(exc).__name__, str(exc), traceback.format_exc(),
                                                    isinstance(exc, PalpateError)))
        try:
            conn.send(reply)
        except (OSError, ValueError):
            os._exit(1)


@dataclass
class _Worker:
    proc: mp.process.BaseProcess
    conn: object
    key: object = None


def _context():
    methods = mp.get_all_start_methods()
    return mp.get_context("fork" if "fork" in methods else "spawn")


def run_tasks(fn: Callable, tasks: Sequence[tuple[object, tuple]], workers: int) -> Iterator[Outcome]:
    """Run ``fn(*args)`` for every ``(key, args)`` of ``tasks`` on up to ``workers`` processes, yielding an
    :class:`Outcome` (the result, or a :class:`TaskFailure`) as each finishes. ``fn`` must be a module-level
    function (it is pickled where processes are spawned). The workers are ended when the iteration ends, however
    it ends."""
    if not tasks:
        return
    ctx = _context()
    parent = os.getpid()
    pending = list(tasks)[::-1]
    pool: list[_Worker] = []

    def start() -> _Worker:
        here, there = ctx.Pipe()
        proc = ctx.Process(target=_worker, args=(there, fn, parent), daemon=True, name="palpate-worker")
        proc.start()
        there.close()
        w = _Worker(proc, here)
        pool.append(w)
        return w

    def give(w: _Worker) -> None:
        key, args = pending.pop()
        w.key = key
        w.conn.send((key, args))

    try:
        for _ in range(min(workers, len(pending))):
            give(start())
        while any(w.key is not None for w in pool):
            busy = [w for w in pool if w.key is not None]
            ready = wait([w.conn for w in busy] + [w.proc.sentinel for w in busy])
            for w in busy:
                if w.conn in ready:
                    try:
                        outcome = w.conn.recv()
                    except (EOFError, OSError):
                        continue  # the worker died; its sentinel says so below
                    w.key = None
                    yield outcome
                    if pending:
                        give(w)
                elif w.proc.sentinel in ready and w.key is not None:
                    key, w.key = w.key, None
                    w.proc.join()
                    pool.remove(w)
                    code = w.proc.exitcode
                    how = f"signal {-code}" if code is not None and code < 0 else f"exit code {code}"
                    yield Outcome(key, False, TaskFailure("WorkerDied", f"the worker process ended ({how})"))
                    if pending:
                        give(start())
    finally:
        _stop(pool)


def _stop(pool: list[_Worker]) -> None:
    for w in pool:
        with contextlib.suppress(OSError, ValueError):
            if w.key is None:
                w.conn.send(None)
            else:
                w.proc.terminate()
    deadline = time.monotonic() + TERMINATE_GRACE
    for w in pool:
        w.proc.join(max(0.0, deadline - time.monotonic()))
        if w.proc.is_alive():
            w.proc.kill()
            w.proc.join()
        with contextlib.suppress(OSError):
            w.conn.close()
