"""Sweeps: a grid of scenario variants run on a process pool or a Ray cluster, gathered into one table.

A sweep file (TOML) names a base scenario and the axes to vary::

    [sweep]
    name = "fidelity_seeds"
    base = "../thesis_ch6.toml"          # relative to the sweep file

    [overrides]                          # applied to every variant (dotted key -> value)
    "outputs.figures" = false

    [[axes]]                             # the grid is the product of every axis' values
    key = "scenario.fidelity"
    values = ["analytic", "rigid"]

    [[axes]]
    key = "materials.Material_2.young_kpa"   # a list of tables is addressed by an entry's name
    values = [100.0, 115.0]

Each variant is the base scenario's TOML dictionary with the overrides applied; every variant is validated with
:func:`palpate.core.world.scenario.parse_scenario` before anything runs. Runs go to ``OUT/runs/<variant id>/`` and a run
is finished when its ``summary.json`` exists and names the same overrides, so a sweep killed midway resumes without
redoing finished runs. The key metrics of every run are gathered in ``OUT/sweep.csv`` and ``OUT/sweep.json``.
"""

from __future__ import annotations

import copy
import csv
import io
import itertools
import json
import math
import re
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from palpate.core.errors import PalpateError, RecordingError, ValidationError
from palpate.core.session.run import run_scenario
from palpate.core.world.scenario_file import parse_scenario

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib  # type: ignore[no-redef]

SWEEP_FORMAT = "palpate-sweep"
VARIANT_FILE = "variant.json"
#: Columns of the gathered table, in order (per-object accuracies are added after these).
BASE_COLUMNS = ("variant", "status", "wall_s", "crossval_accuracy", "presses", "map_accuracy")


@dataclass(frozen=True)
class Variant:
    """One run of the sweep: its id, the overrides that make it, and the scenario dictionary they give."""

    id: str
    overrides: dict
    raw: dict


@dataclass(frozen=True)
class Sweep:
    """A parsed sweep file: name, base scenario path and its folder, and the variants in grid order."""

    name: str
    file: Path
    base: Path
    variants: tuple[Variant, ...]


def set_key(raw: dict, key: str, value, where: str) -> None:
    """Set the dotted ``key`` of a scenario dictionary in place.

    A segment that meets a list of tables picks the entry whose ``name`` equals it (``materials.foam.young_kpa``)
    or the entry at that 0-based index. The last segment may be new (adding an optional key); intermediate
    segments must exist, so a typo is an error, not a silent new table.
    """
    parts = key.split(".")
    if not all(parts):
        raise ValidationError(f"{where}: key {key!r} has an empty segment")
    node = raw
    for i, part in enumerate(parts[:-1]):
        here = ".".join(parts[: i + 1])
        if isinstance(node, dict):
            if part not in node:
                raise ValidationError(f"{where}: key {key!r}: the base scenario has no {here!r}")
            node = node[part]
        elif isinstance(node, list):
            node = _list_entry(node, part, key, here, where)
        else:
            raise ValidationError(f"{where}: key {key!r}: {here!r} is a value, not a table")
    last = parts[-1]
    if isinstance(node, dict):
        node[last] = copy.deepcopy(value)
    elif isinstance(node, list):
        idx = node.index(_list_entry(node, last, key, key, where))
        node[idx] = copy.deepcopy(value)
    else:
        raise ValidationError(f"{where}: key {key!r}: its parent is a value, not a table")


def _list_entry(node: list, part: str, key: str, here: str, where: str):
    for entry in node:
        if isinstance(entry, dict) and entry.get("name") == part:
            return entry
    if part.isdigit() and int(part) < len(node):
        return node[int(part)]
    names = [e.get("name") for e in node if isinstance(e, dict)]
    raise ValidationError(f"{where}: key {key!r}: no entry named {part!r} in {here.rsplit('.', 1)[0]!r} "
                          f"(names: {names}, or a 0-based index below {len(node)})")


def variant_id(index: int, overrides: dict) -> str:
    """A folder-safe id: the grid index, then each axis' last key segment and value (``v003_fidelity-rigid``)."""
    parts = [f"v{index:03d}"]
    for key, value in overrides.items():
        parts.append(f"{key.rsplit('.', 1)[-1]}-{value}")
    return re.sub(r"[^A-Za-z0-9_.=-]+", "_", "_".join(parts))[:120]


def _read_toml(path: Path, what: str) -> dict:
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ValidationError(f"{path}: {what} file not found") from None
    except tomllib.TOMLDecodeError as exc:
        raise ValidationError(f"{path}: not valid TOML: {exc}") from None
    except UnicodeDecodeError:
        raise ValidationError(f"{path}: not a UTF-8 text file") from None


def load_sweep(path: str | Path) -> Sweep:
    """Read and validate a sweep file and every variant it makes.

    Raises:
        ValidationError: naming the sweep file, the key and what was expected (or the variant whose scenario
            is invalid, with the scenario's own message).
    """

    file = Path(path)
    doc = _read_toml(file, "sweep")
    unknown = sorted(set(doc) - {"sweep", "overrides", "axes"})
    if unknown:
        raise ValidationError(f"{file}: unknown top-level key(s) {unknown}; expected [sweep], [overrides], [[axes]]")
    head = doc.get("sweep")
    if not isinstance(head, dict):
        raise ValidationError(f"{file}: a [sweep] table with name and base is required")
    bad = sorted(set(head) - {"name", "base", "description"})
    if bad:
        raise ValidationError(f"{file}: [sweep]: unknown key(s) {bad}; expected name, base, description")
    name, base = head.get("name"), head.get("base")
    if not isinstance(name, str) or not name:
        raise ValidationError(f"{file}: sweep.name must be a non-empty string")
    if not isinstance(base, str) or not base:
        raise ValidationError(f"{file}: sweep.base must be the path of the base scenario (TOML)")
    base_path = (file.parent / base).resolve()
    base_raw = _read_toml(base_path, f"base scenario (sweep.base in {file})")

    fixed = doc.get("overrides", {})
    if not isinstance(fixed, dict):
        raise ValidationError(f"{file}: [overrides] must be a table of dotted key = value")
    fixed = _flatten(fixed)
    axes = doc.get("axes", [])
    if not isinstance(axes, list) or not all(isinstance(a, dict) for a in axes):
        raise ValidationError(f"{file}: axes must be an array of tables [[axes]] with key and values")
    keys, values = [], []
    for i, ax in enumerate(axes):
        where = f"{file}: axes[{i}]"
        if set(ax) != {"key", "values"}:
            raise ValidationError(f"{where}: needs exactly 'key' (dotted scenario key) and 'values' (a list), "
                                  f"got {sorted(ax)}")
        if not isinstance(ax["key"], str) or not isinstance(ax["values"], list) or not ax["values"]:
            raise ValidationError(f"{where}: key must be a string and values a non-empty list")
        if ax["key"] in keys:
            raise ValidationError(f"{where}: key {ax['key']!r} is already an axis")
        keys.append(ax["key"])
        values.append(ax["values"])

    variants = []
    for index, combo in enumerate(itertools.product(*values)):
        overrides = dict(zip(keys, combo, strict=True))
        vid = variant_id(index, overrides)
        raw = copy.deepcopy(base_raw)
        where = f"{file} (variant {vid})"
        for key, value in {**fixed, **overrides}.items():
            set_key(raw, key, value, where)
        try:
            parse_scenario(raw, f"{base_path} with {where} overrides", base_dir=base_path.parent)
        except ValidationError as exc:
            raise ValidationError(f"{where}: the variant's scenario is invalid: {exc}") from None
        variants.append(Variant(vid, overrides, raw))
    return Sweep(name, file, base_path, tuple(variants))


def _flatten(table: dict, prefix: str = "") -> dict:
    """Dotted keys of a (possibly nested) overrides table; quoted dotted keys stay as they are."""
    out = {}
    for k, v in table.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            out.update(_flatten(v, key + "."))
        else:
            out[key] = v
    return out


def is_finished(run_dir: Path, variant: Variant) -> bool:
    """True when ``run_dir`` holds a complete run of ``variant`` (summary.json written, same overrides)."""
    try:
        summary = json.loads((run_dir / "summary.json").read_text())
        meta = json.loads((run_dir / VARIANT_FILE).read_text())
    except (OSError, ValueError):
        return False
    return isinstance(summary, dict) and isinstance(meta, dict) and meta.get("overrides") == variant.overrides


def run_variant(raw: dict, base_dir: str, run_dir: str, vid: str, overrides: dict) -> dict:
    """Run one variant into ``run_dir`` (the worker of both pools); returns its row of key metrics.

    The variant record is written first and summary.json last (by the run job), so a killed run is never taken
    for a finished one.
    """

    out = Path(run_dir)
    out.mkdir(parents=True, exist_ok=True)
    (out / "summary.json").unlink(missing_ok=True)
    (out / VARIANT_FILE).write_text(json.dumps({"id": vid, "overrides": overrides}, indent=1))
    scenario = parse_scenario(raw, f"variant {vid}", base_dir=Path(base_dir))
    t0 = time.perf_counter()
    summary = run_scenario(scenario, out)
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
    if workers < 1:
        raise ValidationError(f"sweep: --workers must be >= 1, got {workers}")
    out = Path(out_dir)
    try:
        (out / "runs").mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise RecordingError(f"sweep: cannot create {out / 'runs'}: {exc}") from exc
    rows: dict[str, dict] = {}
    todo = []
    for v in sweep.variants:
        run_dir = out / "runs" / v.id
        if is_finished(run_dir, v):
            rows[v.id] = metrics_row(v.id, json.loads((run_dir / "summary.json").read_text()), None)
            rows[v.id]["status"] = "done (earlier)"
        else:
            todo.append(v)
    log(f"sweep {sweep.name}: {len(sweep.variants)} variants, {len(rows)} already finished, {len(todo)} to run "
        f"on {'Ray (' + ray + ')' if ray else f'{workers} local process(es)'}")
    args = [(v.raw, str(sweep.base.parent), str(out / "runs" / v.id), v.id, v.overrides) for v in todo]
    runner = _run_ray if ray else _run_pool
    for vid, row in runner(args, workers, ray):
        rows[vid] = row
        log(f"  {vid}: {row['status']}")
    ordered = [rows[v.id] for v in sweep.variants if v.id in rows]
    write_table(ordered, out, sweep)
    return ordered


def _failed(vid: str, exc: BaseException) -> dict:
    return {"variant": vid, "status": f"failed: {type(exc).__name__}: {exc}"[:300]}


def _run_pool(args: list[tuple], workers: int, _ray):
    from concurrent.futures import ProcessPoolExecutor, as_completed

    if not args:
        return
    with ProcessPoolExecutor(max_workers=min(workers, len(args))) as pool:
        futures = {pool.submit(run_variant, *a): a[3] for a in args}
        for fut in as_completed(futures):
            vid = futures[fut]
            try:
                yield vid, fut.result()
            except (PalpateError, OSError) as exc:
                yield vid, _failed(vid, exc)


def _run_ray(args: list[tuple], workers: int, address: str):
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
    if not args:
        return
    remote = ray.remote(num_cpus=1, max_retries=0)(run_variant)
    refs = {remote.remote(*a): a[3] for a in args}
    pending = list(refs)
    while pending:
        done, pending = ray.wait(pending, num_returns=1)
        vid = refs[done[0]]
        try:
            yield vid, ray.get(done[0])
        except ray.exceptions.RayTaskError as exc:
            yield vid, _failed(vid, exc.cause if getattr(exc, "cause", None) else exc)


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
           "variants": {v.id: v.overrides for v in sweep.variants}, "rows": rows}
    try:
        (out / "sweep.csv").write_text(buf.getvalue())
        (out / "sweep.json").write_text(json.dumps(doc, indent=1, allow_nan=False))
    except OSError as exc:
        raise RecordingError(f"sweep: cannot write the table into {out}: {exc}") from exc
