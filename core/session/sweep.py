"""Running a sweep: every variant of a sweep file (:mod:`~palpate.core.session.sweep_file`) on local worker
processes or a Ray cluster, gathered into one table.

Runs go to ``OUT/runs/<variant id>/``. A run is finished when its ``summary.json`` exists and its
``variant.json`` records the same overrides and the same digest of what it ran, so a sweep killed midway resumes
without redoing finished runs, and a run whose base scenario (or any file it read) changed since is run again.
The key metrics of every run are gathered in ``OUT/sweep.csv`` and ``OUT/sweep.json``.

Safety: a lock file (``OUT/.sweep.lock``, held with an OS lock that ends with the process) stops a second sweep
on the same folder; the local workers end with the sweep (:mod:`~palpate.core.session.worker_pool`); ``OUT``
must be new, empty or a palpate sweep of the same name.
"""

from __future__ import annotations

import contextlib
import csv
import io
import json
import math
import os
import shutil
import sys
import time
from collections.abc import Callable
from pathlib import Path

from palpate.core import files
from palpate.core.errors import PalpateError, RecordingError, ValidationError
from palpate.core.names import inside
from palpate.core.session.output_guard import prepare_output_folder
from palpate.core.session.run import run_scenario
from palpate.core.session.sweep_file import Sweep, Variant, load_sweep, set_key, variant_digest, variant_id
from palpate.core.session.worker_pool import Outcome, TaskFailure, run_tasks, terminating_signals
from palpate.core.world.scenario_file import parse_scenario

SWEEP_FORMAT = "palpate-sweep"
VARIANT_FILE = "variant.json"
LOCK_FILE = ".sweep.lock"
#: Columns of the gathered table, in order (per-object accuracies are added after these).
BASE_COLUMNS = ("variant", "status", "wall_s", "crossval_accuracy", "presses", "map_accuracy")

__all__ = ["Sweep", "Variant", "is_finished", "load_sweep", "run_sweep", "run_variant", "set_key", "variant_digest",
           "variant_id", "write_table"]


def _read_json(path: Path):
    try:
        return files.read_json(path, "sweep run record")
    except ValidationError:
        return None


def is_finished(run_dir: Path, variant: Variant) -> bool:
    """True when ``run_dir`` holds a complete run of ``variant``: summary.json written, and variant.json naming
    the same overrides and the same digest of what the run read."""
    meta = _read_json(run_dir / VARIANT_FILE)
    if not (isinstance(meta, dict) and meta.get("overrides") == variant.overrides
            and meta.get("digest") == variant.digest):
        return False
    return isinstance(_read_json(run_dir / "summary.json"), dict)


def run_variant(raw: dict, base_dir: str, run_dir: str, vid: str, overrides: dict, digest: str = "",
                source: str = "") -> dict:
    """Run one variant into ``run_dir`` (the task of both pools); returns its row of key metrics.

    ``source`` names the variant in messages (the base scenario and the sweep file). ``run_dir`` is the sweep's
    own folder of this variant: whatever an unfinished or stale run left there is
    removed first. The variant record (with the digest of what is run) is written before the run and
    summary.json last (by the run), so a killed run is never taken for a finished one.
    """
    out = Path(run_dir)
    if out.is_symlink() or out.is_file():
        out.unlink()
    elif out.exists():
        shutil.rmtree(out)
    prepare_output_folder(out, "run")
    files.write_text(out / VARIANT_FILE, json.dumps({"id": vid, "overrides": overrides, "digest": digest}, indent=1))
    scenario = parse_scenario(raw, source or f"variant {vid}", base_dir=Path(base_dir))
    t0 = time.perf_counter()
    summary = run_scenario(scenario, out, force=True)
    return metrics_row(vid, summary, time.perf_counter() - t0)


def metrics_row(vid: str, summary: dict, wall: float | None) -> dict:
    """Key metrics of one run's summary: LOO accuracy, presses, mean map accuracy, per-object accuracy."""
    row: dict = {"variant": vid, "status": "done", "wall_s": None if wall is None else round(wall, 3)}
    cv = summary.get("crossval")
    accs = list((cv or {}).get("accuracy", {}).values())
    row["crossval_accuracy"] = sum(accs) / len(accs) if accs else None
    objects = summary.get("objects", [])
    row["presses"] = sum(int(o.get("presses", 0)) for o in objects)
    per = {}
    for o in objects:
        acc = (o.get("accuracy") or {})
        val = acc.get("all_cells_after_postprocessing", acc.get("all_cells_before_postprocessing"))
        per[f"accuracy_{o.get('name')}"] = val
    vals = [v for v in per.values() if isinstance(v, (int, float)) and math.isfinite(v)]
    row["map_accuracy"] = sum(vals) / len(vals) if vals else None
    row.update(per)
    return row


@contextlib.contextmanager
def sweep_lock(out: Path):
    """Hold ``OUT/.sweep.lock`` for the block; ValidationError when another sweep holds it. The OS releases the
    lock when the holder ends, however it ends (a killed sweep leaves no stale lock)."""
    path = out / LOCK_FILE
    try:  # never through a symlink: truncating the lock file must not truncate a file elsewhere
        fd = os.open(path, os.O_RDWR | os.O_CREAT | getattr(os, "O_NOFOLLOW", 0), 0o644)
    except OSError as exc:
        raise ValidationError(f"--out {out}: cannot use {path} as the sweep's lock file "
                              f"({exc.strerror or exc})") from None
    try:
        try:
            _lock(fd)
        except OSError:
            holder = os.read(fd, 64).decode(errors="replace").strip() or "another process"
            raise ValidationError(f"--out {out}: another palpate sweep ({holder}) is running on this folder; wait "
                                  "for it to end or give another --out") from None
        os.ftruncate(fd, 0)
        os.write(fd, f"pid {os.getpid()}".encode())
        yield
    finally:
        os.close(fd)


def _lock(fd: int) -> None:
    try:
        import fcntl
    except ImportError:  # Windows
        import msvcrt

        msvcrt.locking(fd, msvcrt.LK_NBLCK, 1)
        return
    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)


def _check_sweep_folder(out: Path, sweep: Sweep) -> None:
    doc = _read_json(out / "sweep.json")
    if isinstance(doc, dict) and doc.get("name") not in (None, sweep.name):
        raise ValidationError(f"--out {out}: holds the results of sweep {files.brief(doc.get('name'))}, not "
                              f"{sweep.name!r}; give another folder")


#: Most local worker processes (or CPUs of a local Ray instance) one sweep may ask for.
MAX_WORKERS = 256


def run_sweep(sweep: Sweep, out_dir: str | Path, *, workers: int = 2, ray: str | None = None,
              log: Callable[[str], None] | None = None) -> list[dict]:
    """Run every unfinished variant of ``sweep`` and gather the table (OUT/sweep.csv, OUT/sweep.json).

    Args:
        workers: processes of the local pool (or CPUs of a local Ray instance started for ``ray="auto"``).
        ray: None for the local process pool; "auto" (an existing cluster, else a local instance) or a Ray
            address ("ray://host:10001", "host:6379") to run on Ray.
        log: called with one line per event (default: stderr).

    Returns the rows in variant order. A failed variant gives a row with status "failed: ..." and the sweep
    goes on; its run is redone on the next call.
    """
    log = log or (lambda s: print(s, file=sys.stderr, flush=True))
    if not 1 <= workers <= MAX_WORKERS:
        raise ValidationError(f"sweep: --workers must be 1..{MAX_WORKERS} (processes, or a local Ray instance's "
                              f"CPUs; this machine has {os.cpu_count() or 1}), got {workers}")
    out = Path(out_dir)
    if out.is_dir():
        _check_sweep_folder(out, sweep)
    prepare_output_folder(out, "sweep")
    with sweep_lock(out), terminating_signals():
        try:
            (out / "runs").mkdir(exist_ok=True)
        except OSError as exc:
            raise RecordingError(f"sweep: cannot create {out / 'runs'}: {exc}") from exc
        rows: dict[str, dict] = {}
        todo = []
        stale = 0
        for v in sweep.variants:
            run_dir = inside(out, out / "runs" / v.id)
            if is_finished(run_dir, v):
                rows[v.id] = metrics_row(v.id, _read_json(run_dir / "summary.json"), None)
                rows[v.id]["status"] = "done (earlier)"
            else:
                stale += (run_dir / "summary.json").exists()
                todo.append(v)
        log(f"sweep {sweep.name}: {len(sweep.variants)} variants, {len(rows)} already finished, {len(todo)} to run"
            + (f" ({stale} finished earlier from another base scenario or input files: rerun)" if stale else "")
            + f" on {'Ray (' + ray + ')' if ray else f'{workers} local process(es)'}")
        tasks = [(v.id, (v.raw, str(sweep.base.parent), str(out / "runs" / v.id), v.id, v.overrides, v.digest,
                         f"{sweep.base} with {sweep.file} (variant {v.id})")) for v in todo]
        outcomes = _run_ray(tasks, workers, ray) if ray else run_tasks(run_variant, tasks, workers)
        for o in outcomes:
            rows[o.key] = o.value if o.ok else _failed(o.key, o.value, out / "runs" / o.key)
            log(f"  {o.key}: {rows[o.key]['status']}")
        ordered = [rows[v.id] for v in sweep.variants if v.id in rows]
        write_table(ordered, out, sweep)
    return ordered


def _failed(vid: str, failure: TaskFailure, run_dir: Path) -> dict:
    """The row of a failed variant; a failure that is not a palpate error (a bug) leaves its traceback in the
    variant's folder."""
    status = f"failed: {failure.type}: {failure.message}"
    if not failure.palpate_error and failure.traceback:
        with contextlib.suppress(OSError):
            run_dir.mkdir(parents=True, exist_ok=True)
            files.write_text(run_dir / "traceback.txt", failure.traceback)
            status += f" (traceback in {run_dir / 'traceback.txt'})"
    return {"variant": vid, "status": " ".join(status.split())[:300]}


def _run_ray(tasks: list[tuple], workers: int, address: str):
    try:
        import ray
    except ImportError as exc:
        raise ValidationError(f"sweep --ray {address}: Ray is not installed ({exc}); install it with "
                              "pip install 'palpate[ray]', or drop --ray to use the local process pool") from None
    if not ray.is_initialized():
        if address == "auto":
            try:
                ray.init(address="auto")
            except ConnectionError:  # no cluster running: start one on this machine
                ray.init(num_cpus=workers, include_dashboard=False)
        else:
            ray.init(address=address)
    if not tasks:
        return
    remote = ray.remote(num_cpus=1, max_retries=0)(run_variant)
    refs = {remote.remote(*args): key for key, args in tasks}
    pending = list(refs)
    try:
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            vid = refs[done[0]]
            try:
                yield Outcome(vid, True, ray.get(done[0]))
            except ray.exceptions.RayTaskError as exc:
                cause = exc.cause if getattr(exc, "cause", None) else exc
                yield Outcome(vid, False, TaskFailure(type(cause).__name__, str(cause), "",
                                                      isinstance(cause, PalpateError)))
    finally:
        for ref in pending:  # the sweep is ending early: do not leave its tasks running on the cluster
            with contextlib.suppress(Exception):
                ray.cancel(ref, force=True)


def write_table(rows: list[dict], out: Path, sweep: Sweep) -> None:
    """Write the gathered rows as sweep.csv and sweep.json (columns: BASE_COLUMNS, then per-object accuracy)."""
    columns = list(BASE_COLUMNS)
    for r in rows:
        columns += [k for k in r if k not in columns]
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=columns, extrasaction="ignore")
    w.writeheader()
    for r in rows:
        w.writerow({k: "" if r.get(k) is None else r.get(k) for k in columns})
    doc = {"format": SWEEP_FORMAT, "version": 1, "name": sweep.name, "file": str(sweep.file),
           "base": str(sweep.base), "columns": columns,
           "variants": {v.id: v.overrides for v in sweep.variants},
           "digests": {v.id: v.digest for v in sweep.variants}, "rows": rows}
    try:
        files.write_text(out / "sweep.csv", buf.getvalue())
        files.write_text(out / "sweep.json", json.dumps(doc, indent=1, allow_nan=False))
    except OSError as exc:
        raise RecordingError(f"sweep: cannot write the table into {out}: {exc}") from exc
