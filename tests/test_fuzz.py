"""Fuzz test over every file kind palpate reads: seeded, bounded in time and memory, run in CI.

Each try (tests/fuzz_inputs.py) runs in a forked child process whose address space is limited
(``MEMORY_HEADROOM`` above what the test process already maps) and which is killed as a hang when its processes
(the child and whatever it starts) have used ``TRY_CPU_SECONDS`` of CPU on the try, or no CPU at all for
``STALL_SECONDS`` (blocked): budgets of work done, not of wall-clock time, so a busy machine slows a try without
making it a hang. A command line goes through palpate's ``main`` as a user's would. Every try ends in one outcome:

- ``ok``: the input was still valid and the command succeeded;
- ``clear``: exit code 2 (or a palpate error from a library call) with one line naming the file (or key);
- bad: ``unclear`` (an error that names nothing), ``traceback`` (an internal error: a bug), ``hang``, ``memory``
  (a MemoryError or the child killed), ``outside`` (a file written or changed outside the output folder,
  including the input itself), ``nan`` (NaN or infinity in an output).

``PALPATE_FUZZ_TRIES`` (default 12 per kind) and ``PALPATE_FUZZ_SEED`` change the run; ``PALPATE_FUZZ_TABLE=FILE``
writes the table (kind, tries, clear errors, bad outcomes) as Markdown.
"""

from __future__ import annotations

import contextlib
import io
import json
import multiprocessing as mp
import os
import resource
import signal
import time
from pathlib import Path

import numpy as np
import pytest
from fuzz_inputs import KINDS, Try, make_bases, tries

TRIES = int(os.environ.get("PALPATE_FUZZ_TRIES", "12"))
SEED = int(os.environ.get("PALPATE_FUZZ_SEED", "17"))
#: CPU a try's processes may use, s (the longest valid try, a one-variant sweep, takes ~2 s); more is a hang.
TRY_CPU_SECONDS = 30.0
#: A try whose processes use less than STALL_CPU s of CPU for this long is blocked: a hang.
STALL_SECONDS = 60.0
STALL_CPU = 0.02
#: How often the budgets are looked at, s.
POLL_SECONDS = 0.25
#: Address space a try may add to what the test process maps: a bounded read needs far less.
MEMORY_HEADROOM = 1.5e9
BAD = ("unclear", "traceback", "hang", "memory", "outside", "nan")


def _snapshot(root: Path, skip: Path | None) -> dict[str, tuple]:
    """Every entry under ``root`` except ``skip``'s subtree: kind, size and mtime (symlinks not followed)."""
    out = {}
    for dirpath, dirnames, filenames in os.walk(root):
        d = Path(dirpath)
        if skip is not None and (d == skip or skip in d.parents):
            dirnames[:] = []
            continue
        for name in dirnames + filenames:
            p = d / name
            if skip is not None and p == skip:
                continue
            st = os.lstat(p)
            # a folder's own mtime changes when the output folder appears in it; its entries are compared instead
            folder = p.is_dir() and not p.is_symlink()
            out[str(p.relative_to(root))] = (st.st_mode >> 12, 0 if folder else st.st_size,
                                             0 if folder else st.st_mtime_ns)
    return out


def _has_nan(folder: Path) -> str | None:
    for p in folder.rglob("*"):
        if p.suffix == ".json" and p.is_file():
            def bad(name):
                raise ValueError(name)

            try:
                json.loads(p.read_text(), parse_constant=bad)
            except ValueError as exc:
                return f"{p.name}: {exc}"
        elif p.suffix == ".npz" and p.is_file():
            with np.load(p, allow_pickle=False) as z:
                for k in z.files:
                    a = z[k]
                    if a.dtype.kind == "f" and not np.all(np.isfinite(a)):
                        return f"{p.name}: {k}"
    return None


def _classify_cli(t: Try) -> tuple[str, str]:
    from palpate.core.cli import main

    err, out = io.StringIO(), io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
        try:
            code = main(list(t.argv))
        except SystemExit as exc:  # argparse
            code = exc.code
    text = err.getvalue()
    errors = [line for line in text.splitlines() if line.startswith("palpate: ")]
    if code == 0:
        return "ok", ""
    variants = [line for line in text.splitlines() if ": failed: " in line]
    if code == 1 and t.argv[0] == "sweep" and variants:  # a sweep whose variants failed, each line saying why
        named = all(any(n in line for n in t.names) and "traceback in" not in line for line in variants)
        return ("clear" if named else "unclear" if all("traceback in" not in v for v in variants)
                else "traceback"), variants[0][:300]
    if "out of memory" in text:
        return "memory", text.strip()[-200:]
    if code == 2 and len(errors) == 1 and errors[0].startswith("palpate: error: ") and "Traceback" not in text:
        line = errors[0]
        return ("clear" if any(n in line for n in t.names) else "unclear"), line[:300]
    return "traceback", (errors[-1] if errors else text.strip()[-300:])


def _classify_call(t: Try) -> tuple[str, str]:
    from palpate.core.errors import PalpateError

    try:
        t.call()
    except PalpateError as exc:
        line = str(exc)
        one = "\n" not in line.strip()
        return ("clear" if one and any(n in line for n in t.names) else "unclear"), line[:300]
    except MemoryError:
        return "memory", "MemoryError"
    except Exception as exc:  # noqa: BLE001 - any other exception is the bad outcome being counted
        return "traceback", f"{type(exc).__name__}: {str(exc)[:200]}"
    return "ok", ""


def _run_try(t: Try) -> tuple[str, str]:
    before = _snapshot(t.root, t.out)
    outcome, detail = _classify_cli(t) if t.argv else _classify_call(t)
    after = _snapshot(t.root, t.out)
    if after != before:
        changed = sorted(set(after.items()) ^ set(before.items()))
        return "outside", f"changed: {changed[0][0]}"
    if outcome == "ok" and t.out is not None and t.out.is_dir():
        nan = _has_nan(t.out)
        if nan:
            return "nan", nan
    return outcome, detail


def _child(conn, all_tries: list[Try], start: int, limit: int) -> None:
    resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    for i in range(start, len(all_tries)):
        conn.send(("start", i))
        conn.send(("done", i, _run_try(all_tries[i])))
    conn.send(("end",))


def _vm_size() -> int:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmSize:"):
            return int(line.split()[1]) * 1024
    return 0


def _tree_cpu(pid: int) -> float:
    """CPU time used by process ``pid``, its threads, its live descendants and the children it has reaped, s."""
    tick = os.sysconf("SC_CLK_TCK")
    total, todo, seen = 0, [pid], set()
    while todo:
        p = todo.pop()
        if p in seen:
            continue
        seen.add(p)
        try:
            fields = Path(f"/proc/{p}/stat").read_text().rsplit(")", 1)[1].split()
            tasks = os.listdir(f"/proc/{p}/task")
        except OSError:  # ended meanwhile: a parent's reaped-children time holds it once it is waited for
            continue
        total += sum(int(v) for v in fields[11:15])  # utime, stime, cutime, cstime
        for tid in tasks:
            try:
                todo += [int(c) for c in Path(f"/proc/{p}/task/{tid}/children").read_text().split()]
            except OSError:
                pass
    return total / tick


def run_tries(all_tries: list[Try], cpu_seconds: float = TRY_CPU_SECONDS,
              stall_seconds: float = STALL_SECONDS) -> list[tuple[str, str]]:
    """Outcome and detail of every try, each in a forked child bounded in CPU time (``cpu_seconds`` per try, and
    ``stall_seconds`` without using any) and memory."""
    ctx = mp.get_context("fork")
    limit = int(_vm_size() + MEMORY_HEADROOM)
    results: list[tuple[str, str] | None] = [None] * len(all_tries)
    i = 0
    while i < len(all_tries):
        here, there = ctx.Pipe()
        proc = ctx.Process(target=_child, args=(there, all_tries, i, limit))  # not daemonic: a sweep forks
        proc.start()
        there.close()
        current = i
        start_cpu = last_cpu = _tree_cpu(proc.pid)
        last_progress = time.monotonic()
        while True:
            if not here.poll(POLL_SECONDS):
                cpu, now = _tree_cpu(proc.pid), time.monotonic()
                if cpu - last_cpu >= STALL_CPU:
                    last_cpu, last_progress = cpu, now
                why = (f"used {cpu - start_cpu:.0f} s of CPU" if cpu - start_cpu > cpu_seconds
                       else f"blocked: no CPU used for {now - last_progress:.0f} s"
                       if now - last_progress > stall_seconds else None)
                if why is None:
                    continue
                proc.kill()
                proc.join()
                results[current] = ("hang", why)
                i = current + 1
                break
            try:
                msg = here.recv()
            except EOFError:
                proc.join()
                code = proc.exitcode
                results[current] = ("memory" if code in (-signal.SIGKILL, 1) else "traceback",
                                    f"the try's process ended (exit code {code})")
                i = current + 1
                break
            if msg[0] == "start":
                current = msg[1]
                start_cpu = last_cpu = _tree_cpu(proc.pid)
                last_progress = time.monotonic()
            elif msg[0] == "done":
                results[msg[1]] = msg[2]
                i = msg[1] + 1
            else:
                i = len(all_tries)
                proc.join()
                break
        here.close()
    return results  # type: ignore[return-value]


@pytest.fixture(scope="module")
def fuzz_root(tmp_path_factory):
    return tmp_path_factory.mktemp("fuzz")


@pytest.fixture(scope="module")
def bases(fuzz_root):
    return make_bases(fuzz_root / "bases")


@pytest.fixture(scope="module")
def table():
    rows: dict[str, dict] = {}
    yield rows
    lines = ["| input kind | tries | valid (ran) | clear errors | bad outcomes |", "|---|---|---|---|---|"]
    for kind in KINDS:
        if kind in rows:
            r = rows[kind]
            bad = ", ".join(f"{n} {k}" for k, n in r["bad"].items()) or "0"
            lines.append(f"| {r['label']} | {r['tries']} | {r['ok']} | {r['clear']} | {bad} |")
    text = "\n".join(lines)
    print(f"\nfuzz: seed {SEED}, {TRIES} tries per kind\n{text}")
    if os.environ.get("PALPATE_FUZZ_TABLE"):
        Path(os.environ["PALPATE_FUZZ_TABLE"]).write_text(text + "\n")


@pytest.mark.skipif(not Path("/proc/self/status").exists() or "fork" not in mp.get_all_start_methods(),
                    reason="the fuzz harness forks a child per batch and reads /proc (Linux)")
@pytest.mark.parametrize("kind", KINDS)
def test_fuzz_every_file_kind(kind, fuzz_root, bases, table):
    all_tries = tries(kind, TRIES, fuzz_root / kind, bases, SEED)
    results = run_tries(all_tries)
    counts: dict[str, int] = {}
    for outcome, _ in results:
        counts[outcome] = counts.get(outcome, 0) + 1
    bad = {k: counts[k] for k in BAD if counts.get(k)}
    table[kind] = {"label": all_tries[0].kind, "tries": len(results), "ok": counts.get("ok", 0),
                   "clear": counts.get("clear", 0), "bad": bad}
    failures = [f"{t.label}: {o}: {d}" for t, (o, d) in zip(all_tries, results, strict=True) if o in BAD]
    assert not failures, "\n".join(failures)


def _spin() -> None:
    while True:
        pass


def _block() -> None:
    read_end, _ = os.pipe()
    os.read(read_end, 1)


@pytest.mark.skipif(not Path("/proc/self/status").exists() or "fork" not in mp.get_all_start_methods(),
                    reason="the fuzz harness forks a child per batch and reads /proc (Linux)")
def test_the_harness_calls_a_try_that_spins_or_blocks_a_hang_and_runs_the_next(tmp_path):
    done = tmp_path / "done"
    tries_ = [Try("harness", "spins", tmp_path, ("x",), call=_spin),
              Try("harness", "blocks", tmp_path, ("x",), call=_block),
              Try("harness", "works", tmp_path, ("x",), call=lambda: sum(range(10**6))),
              Try("harness", "writes", tmp_path, ("x",), call=lambda: done.write_text("x"))]
    results = run_tries(tries_, cpu_seconds=1.0, stall_seconds=2.0)
    assert [o for o, _ in results] == ["hang", "hang", "ok", "outside"], results
    assert "CPU" in results[0][1] and "blocked" in results[1][1]
