"""Hostile variants of every file kind palpate reads, for tests/test_fuzz.py.

Each kind has a valid base file (made once per session) and a seeded generator of tries: the base mutated the
way a careless or hostile user, a broken disk or a crafted file would (byte flips, truncation, a symlink to
/dev/zero, a folder or a sparse file over the size limit, Latin-1 text, values replaced by NaN, inf, huge
numbers, wrong types, deep nesting, long strings or names that are paths, keys removed or duplicated). A try says
which command (or library call, for the kinds no command reads) to run, which names a clear error must mention,
and where output may be written.
"""

from __future__ import annotations

import copy
import json
import math
import os
import struct
import tomllib
import zipfile
import zlib
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
TINY = REPO / "scenarios" / "sweeps" / "tiny_base.toml"
DATA = Path(__file__).parent / "data"


@dataclass(frozen=True)
class Try:
    """One fuzz try: a command line (``argv``, run with palpate's ``main``) or a library call (``call``), the
    names of which at least one must appear in a clear error, the folder it may write into and the sandbox
    nothing else of which may change."""

    kind: str
    label: str
    root: Path
    names: tuple[str, ...]
    argv: tuple[str, ...] = ()
    call: Callable | None = field(default=None, compare=False)
    out: Path | None = None


# ---- a minimal TOML writer (the standard library only reads TOML) ------------------------------------------

def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf") if math.isinf(v) else repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{json.dumps(k)} = {_toml_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(type(v))


def dump_toml(doc: dict, prefix: str = "") -> str:
    """TOML text for a dictionary of tables, arrays of tables and values (inline where nothing else works)."""
    lines, tables = [], []
    for k, v in doc.items():
        key = json.dumps(k)
        if isinstance(v, dict):
            tables.append((f"[{prefix}{key}]", v, f"{prefix}{key}."))
        elif isinstance(v, list) and v and all(isinstance(x, dict) for x in v):
            for x in v:
                tables.append((f"[[{prefix}{key}]]", x, f"{prefix}{key}."))
        else:
            lines.append(f"{key} = {_toml_value(v)}")
    out = "\n".join(lines) + "\n"
    for head, body, pre in tables:
        out += f"\n{head}\n" + dump_toml(body, pre)
    return out


# ---- generic mutations -----------------------------------------------------------------------------------

def hostile_values(root: Path) -> list:
    """Values a key may be replaced by: non-finite, huge, tiny, negative, wrong types, deep or long, and names
    that are paths (relative and absolute, pointing into the sandbox so that an escape is seen)."""
    deep: list = []
    for _ in range(200):
        deep = [deep]
    return [math.nan, math.inf, -math.inf, 1e300, -1e300, 1e-300, 0, -1, 2.5, 2**63, 10**30, "", "x" * 5000,
            "../../../escaped", "../../../../settings", str(root / "abs_target" / "x"), True, [], {}, [1.5] * 3,
            deep, list(range(100_000))]


def _paths(doc, prefix=()) -> list[tuple]:
    """Every key path of a nested dict/list document (leaves and inner nodes)."""
    out = []
    if isinstance(doc, dict):
        for k, v in doc.items():
            out.append((*prefix, k))
            out += _paths(v, (*prefix, k))
    elif isinstance(doc, list) and len(doc) < 50:
        for i, v in enumerate(doc):
            out.append((*prefix, i))
            out += _paths(v, (*prefix, i))
    return out


def mutate_doc(doc, rng: np.random.Generator, values: list, json_like: bool) -> tuple[object, str]:
    """A copy of ``doc`` with one key's value replaced, removed, or an unknown key added; and what was done."""
    doc = copy.deepcopy(doc)
    paths = _paths(doc)
    path = paths[int(rng.integers(len(paths)))]
    parent = doc
    for p in path[:-1]:
        parent = parent[p]
    action = rng.choice(["replace", "replace", "replace", "remove", "add"])
    if action == "remove":
        if isinstance(parent, dict):
            del parent[path[-1]]
        else:
            parent.pop(path[-1])
        return doc, f"removed {'.'.join(map(str, path))}"
    if action == "add" and isinstance(parent, dict):
        parent["unknown_key"] = 1
        return doc, f"unknown key beside {'.'.join(map(str, path))}"
    value = values[int(rng.integers(len(values)))]
    if not json_like and value == {}:
        value = {"x": 1}
    parent[path[-1]] = value
    shown = repr(value) if len(repr(value)) < 40 else f"{type(value).__name__} of {len(repr(value))} chars"
    return doc, f"{'.'.join(map(str, path))} = {shown}"


def mutate_bytes(data: bytes, rng: np.random.Generator, text: bool) -> tuple[bytes, str]:
    """Byte-level damage: truncation, flipped bytes, a zeroed block, inserted garbage, Latin-1 characters."""
    choices = ["truncate", "flip", "zero", "insert"] + (["latin1", "nul"] if text else [])
    how = str(rng.choice(choices))
    n = len(data)
    if how == "truncate":
        cut = int(rng.integers(0, max(1, n)))
        return data[:cut], f"truncated at byte {cut} of {n}"
    buf = bytearray(data)
    if how == "flip":
        k = int(rng.integers(1, 9))
        for i in rng.integers(0, n, k):
            buf[i] ^= int(rng.integers(1, 256))
        return bytes(buf), f"{k} random bytes changed"
    if how == "zero":
        start = int(rng.integers(0, n))
        length = int(rng.integers(1, 64))
        buf[start:start + length] = bytes(min(length, n - start))
        return bytes(buf), f"{length} bytes zeroed at {start}"
    if how == "insert":
        at = int(rng.integers(0, n))
        junk = rng.integers(0, 256, int(rng.integers(1, 32))).astype(np.uint8).tobytes()
        return bytes(buf[:at]) + junk + bytes(buf[at:]), f"{len(junk)} random bytes inserted at {at}"
    if how == "latin1":
        at = int(rng.integers(0, n))
        return bytes(buf[:at]) + "Schaumstoff mit Ö und é".encode("latin-1") + bytes(buf[at:]), "Latin-1 text"
    at = int(rng.integers(0, n))
    return bytes(buf[:at]) + b"\0" * 8 + bytes(buf[at:]), "NUL bytes inserted"


def replace_file(path: Path, rng: np.random.Generator, root: Path) -> str:
    """Replace ``path`` by something that is not a usable file: /dev/zero, a folder, a sparse 200 MB file, a
    FIFO, nothing, or an empty file."""
    how = str(rng.choice(["devzero", "folder", "sparse", "fifo", "missing", "empty"]))
    if path.is_dir() and not path.is_symlink():
        import shutil

        shutil.rmtree(path)
    elif path.exists() or path.is_symlink():
        path.unlink()
    if how == "devzero":
        path.symlink_to("/dev/zero")
    elif how == "folder":
        path.mkdir()
    elif how == "sparse":
        with open(path, "wb") as f:
            f.truncate(200_000_000)
    elif how == "fifo":
        os.mkfifo(path)
    elif how == "empty":
        path.write_bytes(b"")
    return f"file replaced by {how}"


# ---- base files ------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Bases:
    """Valid files of every kind, made once: a tiny run's memory and recording, a layered memory, a map, a
    haptic-material folder."""

    memory: Path
    recording: Path
    layers: Path
    map_npz: Path
    material: Path


def make_bases(folder: Path) -> Bases:
    from palpate.core.cli import main
    from palpate.core.mapping.grids import Grid2D
    from palpate.core.perception.layered_memory import LayeredMemory
    from palpate.core.perception.memory import HapticMemory
    from palpate.core.world.haptic_material import HapticMaterialMap

    run = folder / "run"
    assert main(["run", str(TINY), "--out", str(run), "--record", str(folder / "rec.mcap"), "--quiet"]) == 0
    memory = HapticMemory.load(run / "memory.json")
    LayeredMemory(memory, (memory, memory.materials[0], None), 0.005).save(folder / "layers.json")
    grid = Grid2D(list(memory.materials), (4, 3), origin=(0.0, 0.0), cell_size=0.01)
    grid.save(folder / "map.npz")
    p = np.zeros((2, 3, 2))
    p[..., 0] = 0.75
    p[..., 1] = 0.25
    HapticMaterialMap((0.0, 0.0), 0.01, list(memory.materials), p,
                      {"rate_hardness": np.full((2, 3), 400.0)}).write(folder / "material")
    return Bases(run / "memory.json", folder / "rec.mcap", folder / "layers.json", folder / "map.npz",
                 folder / "material")


# ---- tries per kind --------------------------------------------------------------------------------------

def _sandbox(root: Path, kind: str, i: int) -> tuple[Path, Path]:
    box = root / f"{kind}_{i:03d}"
    (box / "abs_target").mkdir(parents=True)
    (box / "d1" / "d2" / "d3").mkdir(parents=True)  # the output folder's parents exist: only out/ may appear
    return box, box / "d1" / "d2" / "d3" / "out"


def _damaged(rng, box: Path, name: str, base_text: str, edit, share: float) -> tuple[Path, str]:
    """Write a damaged copy of a text file into ``box``: with probability ``share`` edited by ``edit()`` (which
    returns the new text and a label), else byte-level damage or (1 in 10) the file replaced."""
    path = box / name
    r = rng.random()
    if r < share:
        text, label = edit()
        path.write_text(text)
    elif r < 0.9:
        data, label = mutate_bytes(base_text.encode(), rng, text=True)
        path.write_bytes(data)
    else:
        path.write_text(base_text)
        label = replace_file(path, rng, box)
    return path, label


def _text_try(rng, box: Path, name: str, base_text: str, parse, dump, json_like: bool) -> tuple[Path, str]:
    """A damaged structured file (TOML, JSON): one key's value replaced, the key removed or a key added."""
    def edit():
        doc, label = mutate_doc(parse(base_text), rng, hostile_values(box), json_like)
        return dump(doc), label

    return _damaged(rng, box, name, base_text, edit, 0.55)


def _line_try(rng, box: Path, name: str, base_text: str, edit_line, first: int = 0) -> tuple[Path, str]:
    """A damaged line-based file (CSV, Tekscan export): one line changed by ``edit_line(lines, k)``."""
    def edit():
        lines = base_text.splitlines()
        label = edit_line(lines, int(rng.integers(first, len(lines))))
        return "\n".join(lines) + "\n", label

    return _damaged(rng, box, name, base_text, edit, 0.5)


def _json_dump(doc) -> str:
    return json.dumps(doc)


def tries(kind: str, n: int, root: Path, bases: Bases, seed: int) -> list[Try]:
    """``n`` seeded tries of ``kind`` (see KINDS)."""
    rng = np.random.default_rng([seed, sum(map(ord, kind))])
    out = []
    for i in range(n):
        box, o = _sandbox(root, kind, i)
        out.append(MAKERS[kind](rng, box, o, bases))
    return out


def _scenario(rng, box, out, bases) -> Try:
    path, label = _text_try(rng, box, "scen.toml", TINY.read_text(), tomllib.loads, dump_toml, False)
    return Try("scenario TOML", label, box, (path.name,), ("run", str(path), "--out", str(out), "--quiet"), out=out)


def _sweep(rng, box, out, bases) -> Try:
    base = box / "base.toml"
    base.write_text(TINY.read_text())
    text = ('[sweep]\nname = "fuzz"\nbase = "base.toml"\n[overrides]\n"exploration.budget" = 2\n'
            '[[axes]]\nkey = "scenario.seed"\nvalues = [1]\n')
    if rng.random() < 0.3:  # the base scenario is the damaged file
        path, label = _text_try(rng, box, "base.toml", TINY.read_text(), tomllib.loads, dump_toml, False)
        (box / "sweep.toml").write_text(text)
        label = "base: " + label
    else:
        path, label = _text_try(rng, box, "sweep.toml", text, tomllib.loads, dump_toml, False)
    return Try("sweep TOML", label, box, (path.name, "sweep.toml"),
               ("sweep", str(box / "sweep.toml"), "--out", str(out), "--workers", "1"), out=out)


def _memory(rng, box, out, bases) -> Try:
    path, label = _text_try(rng, box, "mem.json", bases.memory.read_text(), json.loads, _json_dump, True)
    if rng.random() < 0.15 and path.is_file():  # a duplicated key, which JSON parsers resolve silently
        text = path.read_text()
        path.write_text(text.replace('"ddof":', '"ddof": 1, "ddof":', 1))
        label = "duplicate key ddof"
    return Try("memory JSON", label, box, (path.name,), ("memory", "show", str(path)))


def _layers(rng, box, out, bases) -> Try:
    path, label = _text_try(rng, box, "layers.json", bases.layers.read_text(), json.loads, _json_dump, True)
    return Try("layered memory JSON", label, box, (path.name,),
               ("replay", str(bases.recording), "--memory", str(bases.memory), "--memory-layers", str(path),
                "--out", str(out), "--quiet", "--no-figures"), out=out)


def _map(rng, box, out, bases) -> Try:
    from palpate.core.mapping.grids import Grid2D

    npz, sidecar = box / "map.npz", box / "map.json"
    npz.write_bytes(bases.map_npz.read_bytes())
    sidecar.write_text(bases.map_npz.with_suffix(".json").read_text())
    r = rng.random()
    if r < 0.35:
        _, label = _text_try(rng, box, "map.json", sidecar.read_text(), json.loads, _json_dump, True)
    elif r < 0.6:
        data, label = mutate_bytes(npz.read_bytes(), rng, text=False)
        npz.write_bytes(data)
    elif r < 0.9:
        label = _craft_npz(npz, rng)
    else:
        label = replace_file(npz, rng, box)
    return Try("map NPZ + JSON", label, box, ("map.npz", "map.json"), call=lambda: Grid2D.load(npz))


def _craft_npz(npz: Path, rng) -> str:
    """An NPZ with arrays of the wrong dtype, shape or values, or a header declaring a huge array."""
    how = str(rng.choice(["huge_header", "nan", "dtype", "shape", "object", "extra"]))
    p = np.full((3, 4, 2), 0.5)
    e = np.zeros((3, 4), bool)
    arrays = {"probabilities": p, "explored": e}
    if how == "nan":
        p[0, 0, 0] = np.nan
    elif how == "dtype":
        arrays["explored"] = e.astype(np.int64)
    elif how == "shape":
        arrays["probabilities"] = np.full((5, 4, 2), 0.5)
    elif how == "object":
        arrays["probabilities"] = np.array([None] * 24, dtype=object).reshape(3, 4, 2)
    elif how == "extra":
        arrays["other"] = np.zeros(3)
    if how == "object":
        np.savez(npz, allow_pickle=True, **arrays)
    elif how == "huge_header":
        import io

        with zipfile.ZipFile(npz, "w") as zf:
            buf = io.BytesIO()
            np.lib.format.write_array_header_1_0(buf, {"descr": "<f8", "fortran_order": False,
                                                       "shape": (60000, 60000, 2)})
            zf.writestr("probabilities.npy", buf.getvalue() + b"\0" * 4096, compress_type=zipfile.ZIP_DEFLATED)
            buf = io.BytesIO()
            np.save(buf, e)
            zf.writestr("explored.npy", buf.getvalue())
    else:
        np.savez(npz, **arrays)
    return f"crafted NPZ: {how}"


def _material(rng, box, out, bases) -> Try:
    folder = box / "material"
    folder.mkdir()
    for p in bases.material.iterdir():
        (folder / p.name).write_bytes(p.read_bytes())
    r = rng.random()
    manifest = folder / "manifest.json"
    if r < 0.4:
        _, label = _text_try(rng, folder, "manifest.json", manifest.read_text(), json.loads, _json_dump, True)
    elif r < 0.65:
        png = folder / str(rng.choice(sorted(p.name for p in folder.glob("*.png"))))
        data, label = mutate_bytes(png.read_bytes(), rng, text=False)
        png.write_bytes(data)
        label = f"{png.name}: {label}"
    elif r < 0.8:
        png = folder / "measured.png"
        w, h = (int(v) for v in rng.choice([[9000, 9000], [3, 2], [100000, 1], [0, 0]]))
        ihdr = struct.pack(">IIBBBBB", w, h, 8, 0, 0, 0, 0)
        chunk = struct.pack(">I", 13) + b"IHDR" + ihdr + struct.pack(">I", zlib.crc32(b"IHDR" + ihdr))
        data = png.read_bytes()
        png.write_bytes(data[:8] + chunk + data[33:])
        label = f"measured.png header declares {w} x {h}"
    else:
        secret = box / "secret.png"
        secret.write_bytes((folder / "measured.png").read_bytes())
        doc = json.loads(manifest.read_text())
        how = str(rng.choice(["absolute", "dotdot", "symlink"]))
        if how == "symlink":
            (folder / "link.png").symlink_to(secret)
            doc["measured_mask"] = "link.png"
        else:
            doc["measured_mask"] = str(secret) if how == "absolute" else "../secret.png"
        manifest.write_text(json.dumps(doc))
        label = f"map file outside the folder ({how})"
    scen = tomllib.loads(TINY.read_text())
    scen["objects"][0]["material_map"] = str(folder)
    scen["outputs"]["haptic_material"] = False
    (box / "scen.toml").write_text(dump_toml(scen))
    return Try("haptic-material folder", label, box, ("material",),
               ("run", str(box / "scen.toml"), "--out", str(out), "--quiet"), out=out)


def _params(rng, box, out, bases) -> Try:
    def edit(lines: list[str], k: int) -> str:
        cells = lines[k].split(",")
        j = int(rng.integers(len(cells)))
        cells[j] = str(rng.choice(["nan", "inf", "-1e400", "1e300", "", "x" * 200000, '"unterminated', "1,2",
                                   "../../x", "9" * 5000]))
        lines[k] = ",".join(cells)
        if rng.random() < 0.2:
            lines.insert(k, lines[0])  # a repeated header line in the middle
        return f"line {k + 1} column {j + 1} = {cells[j][:20]!r}"

    path, label = _line_try(rng, box, "params.csv", (DATA / "thesis_ch6_params.csv").read_text(), edit, first=1)
    cmd = str(rng.choice(["train", "crossval"]))
    argv = ("memory", "train", str(path), "-o", str(out / "m.json")) if cmd == "train" else \
        ("memory", "crossval", str(path))
    if cmd == "train":
        out.mkdir(parents=True, exist_ok=True)
    return Try("params CSV", f"{cmd}: {label}", box, (path.name,), argv, out=out if cmd == "train" else None)


def _finger(rng, box, out, bases) -> Try:
    from palpate.hardware.dynamixel.finger import load_finger

    base = (REPO / "models" / "fingers" / "planar2.toml").read_text()
    path, label = _text_try(rng, box, "finger.toml", base, tomllib.loads, dump_toml, False)
    return Try("finger TOML", label, box, (path.name,), call=lambda: load_finger(path))


def _mcap(rng, box, out, bases) -> Try:
    path = box / "rec.mcap"
    data = bases.recording.read_bytes()
    r = rng.random()
    if r < 0.8:
        data, label = mutate_bytes(data, rng, text=False)
        path.write_bytes(data)
    else:
        path.write_bytes(data)
        label = replace_file(path, rng, box)
    return Try("MCAP recording", label, box, (path.name,),
               ("replay", str(path), "--memory", str(bases.memory), "--out", str(out), "--quiet", "--no-figures"),
               out=out)


def _tekscan(rng, box, out, bases) -> Try:
    def edit(lines: list[str], k: int) -> str:
        head = lines[k].split(" ")[0] if " " in lines[k] else lines[k][:8]
        value = str(rng.choice(["nan", "inf", "-1", "0", "1e300", "99999999999999999999", "x" * 5000, "",
                                "9999-12-31T23:59:59Z", "1e-300"]))
        lines[k] = f"{head} {value}" if " " in lines[k] else value
        return f"line {k + 1} = {lines[k][:30]!r}"

    path, label = _line_try(rng, box, "export.csv", (DATA / "tekscan_press.csv").read_text(), edit)
    out.mkdir(parents=True, exist_ok=True)
    return Try("Tekscan export", label, box, (path.name,), ("import", "tekscan", str(path), "--out",
                                                             str(out / "rec.mcap")), out=out)


MAKERS = {"scenario": _scenario, "sweep": _sweep, "memory": _memory, "layers": _layers, "map": _map,
          "material": _material, "params": _params, "finger": _finger, "mcap": _mcap, "tekscan": _tekscan}
KINDS = tuple(MAKERS)
