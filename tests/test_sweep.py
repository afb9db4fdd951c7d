"""palpate sweep: grid of scenario variants, validation, resume after an interruption, local pool and Ray."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from palpate.core.errors import ValidationError
from palpate.core.session.sweep import LOCK_FILE, is_finished, load_sweep, run_sweep, set_key

ROOT = Path(__file__).resolve().parents[1]
TINY = ROOT / "scenarios" / "sweeps" / "tiny.toml"


def _sweep_file(tmp_path: Path, body: str) -> Path:
    path = tmp_path / "s.toml"
    path.write_text(f'[sweep]\nname = "t"\nbase = "{(TINY.parent / "tiny_base.toml").as_posix()}"\n{body}')
    return path


def test_grid_is_the_product_of_axes_with_overrides_applied():
    sweep = load_sweep(TINY)
    assert [v.overrides for v in sweep.variants] == [
        {"scenario.seed": s, "objects.Block.material": m} for s in (1, 2) for m in ("soft", "hard")
    ]
    v = sweep.variants[3]
    assert v.raw["scenario"]["seed"] == 2 and v.raw["objects"][0]["material"] == "hard"
    assert len({v.id for v in sweep.variants}) == 4


def test_list_entries_are_addressed_by_name_or_index():
    raw = {"materials": [{"name": "a", "young_kpa": 1.0}, {"name": "b", "young_kpa": 2.0}]}
    set_key(raw, "materials.b.young_kpa", 5.0, "here")
    set_key(raw, "materials.0.poisson", 0.4, "here")
    assert raw["materials"] == [{"name": "a", "young_kpa": 1.0, "poisson": 0.4}, {"name": "b", "young_kpa": 5.0}]
    with pytest.raises(ValidationError, match="no entry named 'c'"):
        set_key(raw, "materials.c.young_kpa", 1.0, "here")
    with pytest.raises(ValidationError, match="has no 'explorashun'"):
        set_key({"exploration": {}}, "explorashun.budget", 3, "here")


@pytest.mark.parametrize("body, message", [
    ('[[axes]]\nkey = "scenario.fidelity"\nvalues = ["analytic", "warp"]\n', "fidelity"),
    ('[[axes]]\nkey = "materials.soft.young_kpa"\nvalues = [-1.0]\n', "young_kpa"),
    ('[[axes]]\nkey = "scenario.seed"\n', "needs exactly 'key'"),
    ('[axes]\nkey = "scenario.seed"\n', "array of tables"),
    ('[sweeep]\n', "unknown top-level"),
])
def test_bad_sweeps_name_the_variant_and_key(tmp_path, body, message):
    with pytest.raises(ValidationError, match=message) as err:
        load_sweep(_sweep_file(tmp_path, body))
    assert "s.toml" in str(err.value)


def test_missing_base_is_named(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text('[sweep]\nname = "t"\nbase = "nowhere.toml"\n')
    with pytest.raises(ValidationError, match="nowhere.toml.*not found"):
        load_sweep(path)


def _precreate_finished(out: Path, variant) -> float:
    """A finished run of ``variant`` that a rerun must keep (its summary carries a marker)."""
    run = out / "runs" / variant.id
    run.mkdir(parents=True)
    (run / "variant.json").write_text(json.dumps({"id": variant.id, "overrides": variant.overrides,
                                                  "digest": variant.digest}))
    (run / "summary.json").write_text(json.dumps({"marker": "kept", "objects": [], "crossval": None}))
    return (run / "summary.json").stat().st_mtime_ns


def test_local_pool_runs_the_rest_and_keeps_a_finished_run(tmp_path):
    sweep = load_sweep(TINY)
    out = tmp_path / "out"
    mtime = _precreate_finished(out, sweep.variants[0])
    # a run of another variant's overrides in the folder is not a finished run of this one
    stale = out / "runs" / sweep.variants[1].id
    stale.mkdir(parents=True)
    (stale / "variant.json").write_text(json.dumps({"overrides": {"scenario.seed": 99}}))
    (stale / "summary.json").write_text("{}")
    rows = run_sweep(sweep, out, workers=2, log=lambda s: None)
    assert [r["variant"] for r in rows] == [v.id for v in sweep.variants]
    assert rows[0]["status"] == "done (earlier)"
    assert all(r["status"] == "done" for r in rows[1:])
    first = out / "runs" / sweep.variants[0].id / "summary.json"
    assert first.stat().st_mtime_ns == mtime and json.loads(first.read_text())["marker"] == "kept"
    assert all(is_finished(out / "runs" / v.id, v) for v in sweep.variants)
    table = (out / "sweep.csv").read_text().splitlines()
    assert table[0].startswith("variant,status,wall_s,crossval_accuracy") and len(table) == 5
    doc = json.loads((out / "sweep.json").read_text())
    assert [r["variant"] for r in doc["rows"]] == [v.id for v in sweep.variants]
    # the hard block is perceived as hard in most cells, the soft one as soft: the variants really differ
    assert all(0.0 <= r["map_accuracy"] <= 1.0 for r in rows[1:])


def _group_alive(pgid: int) -> bool:
    """Whether a thread of a process of group ``pgid`` still runs (zombies do not count: they hold no files).

    Threads, not processes: a killed multi-threaded process's leader can show as a zombie while its other threads
    are still exiting, and they share its open files, so the sweep's lock is held until the last of them is gone
    (on a loaded machine the resumed sweep once found the lock still taken when only leaders were checked)."""
    proc = Path("/proc")
    if not proc.is_dir():
        try:
            os.killpg(pgid, 0)
        except ProcessLookupError:
            return False
        return True
    for stat in proc.glob("[0-9]*/task/[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except (OSError, IndexError):
            continue  # gone meanwhile
        if int(fields[2]) == pgid and fields[0] not in ("Z", "X"):
            return True
    return False


def _wait_group_gone(pgid: int, limit: float = 60.0) -> None:
    """Wait until every process of the killed group is gone: a forked worker shares the sweep's lock file and
    holds its lock until the kernel has torn it down, which on a loaded machine is after the parent's wait."""
    deadline = time.monotonic() + limit
    while _group_alive(pgid):
        if time.monotonic() > deadline:
            raise AssertionError(f"the killed sweep's processes were still there after {limit} s")
        time.sleep(0.05)


def _wait_lock_released(out: Path, limit: float = 60.0) -> None:
    """Wait until the killed sweep's lock can be taken (what resuming needs), failing after ``limit`` s: the OS
    must release it once every holder is gone, however long a loaded machine takes to tear them down."""
    import fcntl

    deadline = time.monotonic() + limit
    fd = os.open(out / LOCK_FILE, os.O_RDWR)
    try:
        while True:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                if time.monotonic() > deadline:
                    raise AssertionError(f"the killed sweep's lock was still held after {limit} s") from None
                time.sleep(0.05)
                continue
            fcntl.flock(fd, fcntl.LOCK_UN)
            return
    finally:
        os.close(fd)


def test_killed_sweep_resumes_without_redoing_finished_runs(tmp_path):
    out = tmp_path / "out"
    cli = "import sys; from palpate.core.cli import main; sys.exit(main())"
    cmd = [sys.executable, "-c", cli, "sweep", str(TINY), "--out", str(out), "--workers", "1"]
    env = dict(os.environ, MPLBACKEND="Agg")
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env,
                            start_new_session=True)
    deadline = time.monotonic() + 120
    done: list[Path] = []
    while time.monotonic() < deadline and proc.poll() is None:
        done = list(out.glob("runs/*/summary.json"))
        if done:
            break
        time.sleep(0.05)
    assert done, "no run finished within 120 s"
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    _wait_group_gone(proc.pid)
    _wait_lock_released(out)
    finished = {p.parent.name: p.stat().st_mtime_ns for p in out.glob("runs/*/summary.json")}
    assert 1 <= len(finished) < 4, "the kill came too late to interrupt the sweep"
    rows = run_sweep(load_sweep(TINY), out, workers=1, log=lambda s: None)
    assert {r["variant"] for r in rows if r["status"] == "done (earlier)"} == set(finished)
    assert sum(r["status"] == "done" for r in rows) == 4 - len(finished)
    for name, mtime in finished.items():
        assert (out / "runs" / name / "summary.json").stat().st_mtime_ns == mtime


def test_ray_runs_the_sweep_and_resumes(tmp_path):
    ray = pytest.importorskip("ray", reason="Ray is not installed (pip install 'palpate[ray]')")
    sweep = load_sweep(TINY)
    out = tmp_path / "out"
    mtime = _precreate_finished(out, sweep.variants[2])
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        rows = run_sweep(sweep, out, ray="auto", log=lambda s: None)
        assert [r["status"] for r in rows] == ["done", "done", "done (earlier)", "done"]
        again = run_sweep(sweep, out, ray="auto", log=lambda s: None)
        assert all(r["status"] == "done (earlier)" for r in again)
    finally:
        ray.shutdown()
    assert (out / "runs" / sweep.variants[2].id / "summary.json").stat().st_mtime_ns == mtime


def test_missing_ray_is_a_clear_error(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray now raises ImportError
    with pytest.raises(ValidationError, match="Ray is not installed"):
        run_sweep(load_sweep(TINY), tmp_path, ray="auto", log=lambda s: None)


# ---- safety: stale results, a second sweep, killed sweeps ------------------------------------------------

def _own_sweep(tmp_path: Path, seeds=(1, 2)) -> Path:
    """A two-variant sweep over a private copy of the tiny base scenario (so the test may edit the base)."""
    base = tmp_path / "base.toml"
    base.write_text((TINY.parent / "tiny_base.toml").read_text())
    path = tmp_path / "sweep.toml"
    path.write_text('[sweep]\nname = "own"\nbase = "base.toml"\n'
                    f'[[axes]]\nkey = "scenario.seed"\nvalues = {list(seeds)}\n')
    return path


def test_a_changed_base_scenario_is_rerun_not_reused(tmp_path):
    path = _own_sweep(tmp_path)
    out = tmp_path / "out"
    first = run_sweep(load_sweep(path), out, workers=1, log=lambda s: None)
    assert [r["status"] for r in first] == ["done", "done"]
    assert [r["status"] for r in run_sweep(load_sweep(path), out, workers=1, log=lambda s: None)] == \
        ["done (earlier)", "done (earlier)"]
    base = tmp_path / "base.toml"
    base.write_text(base.read_text().replace("budget = 3", "budget = 2"))
    lines: list[str] = []
    again = run_sweep(load_sweep(path), out, workers=1, log=lines.append)
    assert [r["status"] for r in again] == ["done", "done"]
    assert "2 finished earlier from another base scenario or input files: rerun" in lines[0]
    assert [r["presses"] for r in again] == [2, 2] and [r["presses"] for r in first] == [3, 3]
    record = json.loads((out / "runs" / again[0]["variant"] / "variant.json").read_text())
    assert record["digest"] == load_sweep(path).variants[0].digest != ""


def test_a_second_sweep_on_the_same_folder_is_refused(tmp_path):
    from palpate.core.session.sweep import sweep_lock

    path = _own_sweep(tmp_path)
    out = tmp_path / "out"
    out.mkdir()
    with sweep_lock(out), pytest.raises(ValidationError, match=r"another palpate sweep \(pid \d+\) is running"):
        run_sweep(load_sweep(path), out, workers=1, log=lambda s: None)
    assert not (out / "runs").exists()
    assert [r["status"] for r in run_sweep(load_sweep(path), out, workers=1, log=lambda s: None)] == ["done", "done"]


def test_a_folder_of_another_sweep_or_not_a_sweep_is_refused(tmp_path):
    path = _own_sweep(tmp_path)
    out = tmp_path / "out"
    run_sweep(load_sweep(path), out, workers=1, log=lambda s: None)
    with pytest.raises(ValidationError, match="holds the results of sweep 'own', not 't'"):
        run_sweep(load_sweep(_sweep_file(tmp_path, "")), out, workers=1, log=lambda s: None)
    other = tmp_path / "other"
    other.mkdir()
    (other / "thesis.pdf").write_bytes(b"%PDF")
    with pytest.raises(ValidationError, match="not empty and holds no palpate output"):
        run_sweep(load_sweep(path), other, workers=1, log=lambda s: None)


def _children(pid: int) -> set[int]:
    out = set()
    for task in Path(f"/proc/{pid}/task").glob("*/children"):
        out.update(int(p) for p in task.read_text().split())
    return out


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


@pytest.mark.skipif(not Path("/proc/self/task").exists(), reason="reads worker pids from /proc (Linux)")
@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGTERM])
def test_workers_end_with_a_killed_sweep_and_release_its_stdout(tmp_path, sig):
    path = _own_sweep(tmp_path, seeds=list(range(1, 9)))
    out = tmp_path / "out"
    cli = "import sys; from palpate.core.cli import main; sys.exit(main())"
    proc = subprocess.Popen([sys.executable, "-c", cli, "sweep", str(path), "--out", str(out), "--workers", "2"],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, start_new_session=True,
                            env=dict(os.environ, MPLBACKEND="Agg"))
    deadline = time.monotonic() + 120
    workers: set[int] = set()
    while time.monotonic() < deadline and proc.poll() is None:
        workers = _children(proc.pid)
        if len(workers) == 2 and len(list(out.glob("runs/*/variant.json"))) >= 2:
            break
        time.sleep(0.02)
    assert len(workers) == 2, "the sweep did not start two workers"
    os.kill(proc.pid, sig)  # the parent only: not its process group
    # the pipe reaches its end only when no worker holds it any more (a `| tee` would otherwise hang)
    output, _ = proc.communicate(timeout=60)
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline and any(_alive(w) for w in workers):
        time.sleep(0.05)
    assert not any(_alive(w) for w in workers), "a worker outlived its sweep"
    finished = set(out.glob("runs/*/summary.json"))
    time.sleep(1.0)
    assert set(out.glob("runs/*/summary.json")) == finished, "a run finished after its sweep was killed"
    assert len(finished) < 8
    if sig == signal.SIGTERM:
        assert proc.returncode == 128 + signal.SIGTERM
        assert b"Traceback" not in output and output.strip().endswith(b"palpate: terminated by SIGTERM")
    # the lock died with the sweep: the next one resumes and runs only what is missing
    rows = run_sweep(load_sweep(path), out, workers=2, log=lambda s: None)
    assert sum(r["status"] == "done (earlier)" for r in rows) == len(finished)
    assert all(r["status"].startswith("done") for r in rows)


def test_the_digest_follows_the_files_a_variant_reads(tmp_path):
    path = _own_sweep(tmp_path)
    base = tmp_path / "base.toml"
    base.write_text(base.read_text().replace("[training]", '[training]\nmemory = "mem.json"'))
    (tmp_path / "mem.json").write_text('{"a": 1}')
    first = load_sweep(path).variants
    assert first[0].digest != first[1].digest  # the seeds differ
    assert [v.digest for v in load_sweep(path).variants] == [v.digest for v in first]
    (tmp_path / "mem.json").write_text('{"a": 2}')
    assert all(a.digest != b.digest for a, b in zip(first, load_sweep(path).variants, strict=True))
