"""Sweep files: a grid of scenario variants, each validated and given the digest of what it runs.

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
:func:`palpate.core.world.scenario_file.parse_scenario` before anything runs, and carries the SHA-256 of what its
run reads (:func:`variant_digest`: the scenario dictionary and the files it names), so that a finished run of an
edited base scenario is recognised as stale. Running a sweep: :mod:`palpate.core.session.sweep`.
"""

from __future__ import annotations

import copy
import hashlib
import itertools
import json
import math
import re
from dataclasses import dataclass
from pathlib import Path

from palpate.core import limits
from palpate.core.errors import ValidationError
from palpate.core.files import brief, read_toml
from palpate.core.names import check_name
from palpate.core.session.run import scenario_inputs
from palpate.core.world.scenario import Scenario
from palpate.core.world.scenario_file import parse_scenario
from palpate.core.world.table_reader import resolve_path


@dataclass(frozen=True)
class Variant:
    """One run of the sweep: its id, the overrides that make it, the scenario dictionary they give, and the
    digest of everything the run reads (:func:`variant_digest`)."""

    id: str
    overrides: dict
    raw: dict
    digest: str = ""


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
                          f"(names: {brief(names)}, or a 0-based index below {len(node)})")


def variant_id(index: int, overrides: dict) -> str:
    """A folder-safe id: the grid index, then each axis' last key segment and value (``v003_fidelity-rigid``)."""
    parts = [f"v{index:03d}"]
    for key, value in overrides.items():
        parts.append(f"{key.rsplit('.', 1)[-1]}-{value}")
    return re.sub(r"[^A-Za-z0-9_.=-]+", "_", "_".join(parts))[:120]


def load_sweep(path: str | Path) -> Sweep:
    """Read and validate a sweep file and every variant it makes.

    Raises:
        ValidationError: naming the sweep file, the key and what was expected (or the variant whose scenario
            is invalid, with the scenario's own message).
    """

    file = Path(path)
    doc = read_toml(file, "sweep file")
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
    check_name(name, f"{file}: sweep.name")  # it names the sweep's table and lines: one printable line
    if not isinstance(base, str) or not base:
        raise ValidationError(f"{file}: sweep.base must be the path of the base scenario (TOML)")
    base_path = (file.parent / base).resolve()
    base_raw = read_toml(base_path, f"base scenario, sweep.base in {file}")

    fixed = doc.get("overrides", {})
    if not isinstance(fixed, dict):
        raise ValidationError(f"{file}: [overrides] must be a table of dotted key = value")
    fixed = _flatten(fixed)
    axes = doc.get("axes", [])
    if not isinstance(axes, list) or not all(isinstance(a, dict) for a in axes):
        raise ValidationError(f"{file}: axes must be an array of tables [[axes]] with key and values")
    keys, values = [], []
    limits.check("sweep_variants", f"{file}: axes: variant count",
                 math.prod(len(a["values"]) if isinstance(a.get("values"), list) else 1 for a in axes))
    for i, ax in enumerate(axes):
        where = f"{file}: axes[{i}]"
        if set(ax) != {"key", "values"}:
            raise ValidationError(f"{where}: needs exactly 'key' (dotted scenario key) and 'values' (a list), "
                                  f"got {brief(sorted(ax))}")
        if not isinstance(ax["key"], str) or not isinstance(ax["values"], list) or not ax["values"]:
            raise ValidationError(f"{where}: key must be a string and values a non-empty list")
        if ax["key"] in keys:
            raise ValidationError(f"{where}: key {ax['key']!r} is already an axis")
        keys.append(ax["key"])
        values.append(ax["values"])

    variants = []
    digests: dict[Path, str] = {}
    for index, combo in enumerate(itertools.product(*values)):
        overrides = dict(zip(keys, combo, strict=True))
        vid = variant_id(index, overrides)
        raw = copy.deepcopy(base_raw)
        where = f"{file} (variant {vid})"
        for key, value in {**fixed, **overrides}.items():
            set_key(raw, key, value, where)
        try:
            scenario = parse_scenario(raw, f"{base_path} with {where} overrides", base_dir=base_path.parent)
        except ValidationError as exc:
            raise ValidationError(f"{where}: the variant's scenario is invalid: {exc}") from None
        variants.append(Variant(vid, overrides, raw, variant_digest(raw, scenario, base_path.parent, digests)))
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




def variant_digest(raw: dict, scenario: Scenario, base_dir: Path, cache: dict[Path, str] | None = None) -> str:
    """SHA-256 of what a variant's run reads: its scenario dictionary (the base scenario with the overrides, so an
    edited base gives a new digest) and the content of every file it names (a trained memory, meshes, actuator
    files, haptic-material folders). A finished run whose recorded digest differs is run again."""
    cache = {} if cache is None else cache
    paths = [p for p in scenario_inputs(scenario) if p != scenario.path]  # the scenario: the dictionary below
    for obj in raw.get("objects", []) if isinstance(raw.get("objects"), list) else []:
        if isinstance(obj, dict) and isinstance(obj.get("material_map"), str) and obj["material_map"]:
            paths.append(resolve_path(base_dir, obj["material_map"]))
    h = hashlib.sha256(json.dumps(raw, sort_keys=True, default=str).encode())
    for p in sorted({Path(p) for p in paths}):
        if p not in cache:
            cache[p] = _content_digest(p)
        h.update(f"\n{p}:{cache[p]}".encode())
    return h.hexdigest()


def _content_digest(path: Path) -> str:
    """SHA-256 of a file, or of a folder's regular files (names and contents, not recursive); '' if absent."""
    h = hashlib.sha256()
    members = sorted(path.iterdir()) if path.is_dir() else [path] if path.is_file() else []
    for m in members:
        if m.is_file():
            h.update(m.name.encode() + b"\0")
            with open(m, "rb") as f:
                for chunk in iter(lambda: f.read(1 << 20), b""):
                    h.update(chunk)
    return h.hexdigest() if members else ""
