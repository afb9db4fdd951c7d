"""Safe under hostile input: names never become paths, bounded reads, outputs never destroy inputs or old results,
and every error a user can cause is one line naming the file or key, with exit code 2."""

from __future__ import annotations

import json
import os
import tomllib
from pathlib import Path

import numpy as np
import pytest

from palpate.core import limits
from palpate.core.cli import main
from palpate.core.errors import ValidationError
from palpate.core.files import parse_json, read_json, read_text, read_toml, write_text
from palpate.core.io.mcap_reader import read_recording
from palpate.core.io.mcap_writer import RecordingWriter
from palpate.core.mapping.grids import Grid2D
from palpate.core.names import check_name, file_stem, inside
from palpate.core.world.haptic_material import HapticMaterialMap
from palpate.core.world.scenario_file import load_scenario, parse_scenario

REPO = Path(__file__).resolve().parent.parent
SEED_TABLE = REPO / "models" / "realism" / "seed000_tables_6_3_to_6_5.csv"
TINY = REPO / "scenarios" / "sweeps" / "tiny_base.toml"


def _tiny_raw() -> dict:
    return tomllib.loads(TINY.read_text())


def _cli(argv, capsys) -> tuple[int, str, str]:
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def _one_line_error(err: str, *names: str) -> str:
    """The error line of stderr: the last line, the only one of its kind, naming ``names`` (progress lines may
    come before it)."""
    lines = err.strip().splitlines()
    errors = [line for line in lines if line.startswith("palpate: ") and "error" in line.split(":")[1]]
    assert len(errors) == 1 and lines[-1] == errors[0] and "Traceback" not in err, err
    assert errors[0].startswith("palpate: error: "), err
    for name in names:
        assert name in errors[0], (name, err)
    return errors[0]


# ---- names ------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("name", ["../../x", "/abs/path/x", "a/b", "..", ".hidden", "tab\there", "nul\0", "", " x",
                                  "x" * 101, "back\\slash"])
def test_names_that_could_be_paths_are_refused_with_the_key(name):
    for where in ("objects", "materials", "scenario"):
        raw = _tiny_raw()
        if where == "objects":
            raw["objects"][0]["name"] = name
        elif where == "materials":
            raw["materials"][0]["name"] = name
            raw["objects"][0]["material"] = name
        else:
            raw["scenario"]["name"] = name
        with pytest.raises(ValidationError, match=rf"s.toml: {where}(\[0\])?\.name"):
            parse_scenario(raw, "s.toml", base_dir=TINY.parent)


def test_file_stems_are_safe_and_paths_outside_the_output_are_refused(tmp_path):
    for name in ("../../x", "/abs/x", "..", ".", "a b/c", "…settings", ""):
        stem = file_stem(name)
        assert stem and "/" not in stem and "\\" not in stem and not stem.startswith(".")
        assert (tmp_path / f"{stem}.npz").resolve().parent == tmp_path.resolve()
    assert check_name("Object 1 (left)", "k") == "Object 1 (left)"
    assert inside(tmp_path, tmp_path / "maps" / "a.npz") == tmp_path / "maps" / "a.npz"
    with pytest.raises(ValidationError, match="outside the output folder"):
        inside(tmp_path / "out", tmp_path / "out" / ".." / "x.npz")
    (tmp_path / "out").mkdir()
    (tmp_path / "elsewhere").mkdir()
    (tmp_path / "out" / "maps").symlink_to(tmp_path / "elsewhere")
    with pytest.raises(ValidationError, match="outside the output folder"):
        inside(tmp_path / "out", tmp_path / "out" / "maps" / "x.npz")


def test_two_names_with_one_file_stem_are_refused():
    raw = _tiny_raw()
    raw["objects"].append({**raw["objects"][0], "name": "Block?"})
    raw["objects"][0]["name"] = "Block!"
    with pytest.raises(ValidationError, match="'Block!' and 'Block\\?' would both be written as 'Block_'"):
        parse_scenario(raw, "s.toml", base_dir=TINY.parent)


def _hostile_recording(src: Path, dst: Path, name: str, annotation_fields: dict | None = None) -> None:
    """``src`` rewritten with its object renamed ``name`` in the metadata and in every press annotation."""
    rec = read_recording(src)
    meta = dict(rec.metadata)
    (old,) = meta["maps"]
    meta["maps"] = {name: meta["maps"][old]}
    with RecordingWriter(dst, meta) as w:
        for a in rec.annotations:
            data = dict(a.data)
            if a.kind == "press" and data.get("object") == old:
                data["object"] = name
                data.update(annotation_fields or {})
            w.write_annotation(a.t, a.kind, data)
        for f in rec.frames:
            w.write_taxel(f)
        for p in rec.poses:
            w.write_pose(p)


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    """The tiny scenario run once with a recording: (run folder, recording, memory)."""
    root = tmp_path_factory.mktemp("tiny")
    assert main(["run", str(TINY), "--out", str(root / "run"), "--record", str(root / "rec.mcap"), "--quiet"]) == 0
    return root / "run", root / "rec.mcap", root / "run" / "memory.json"


@pytest.mark.parametrize("name", ["../../evil", "/tmp/palpate_evil_abs/x", "../settings"])
def test_replay_writes_names_from_a_recording_inside_the_output(tiny_run, tmp_path, capsys, name):
    _, rec, memory = tiny_run
    hostile = tmp_path / "hostile.mcap"
    _hostile_recording(rec, hostile, name)
    out = tmp_path / "a" / "b" / "out"
    before = {p for p in tmp_path.rglob("*")}
    code, _, err = _cli(["replay", hostile, "--memory", memory, "--out", out, "--quiet"], capsys)
    assert code == 0, err
    new = {p for p in tmp_path.rglob("*")} - before
    assert new and all(out in p.parents or p == out or p in out.parents for p in new)
    assert not Path("/tmp/palpate_evil_abs").exists()
    stems = sorted(p.name for p in (out / "maps").iterdir())
    assert stems == [f"{file_stem(name)}{s}" for s in (".json", ".npz", "_fine.npz", "_postprocessed.json",
                                                       "_postprocessed.npz")]
    assert json.loads((out / "summary.json").read_text())["objects"][0]["name"] == name


@pytest.mark.parametrize("fields, key", [({"t_start": "soon"}, "t_start"), ({"t_end": None}, "t_end"),
                                         ({"target_m": "here"}, "target_m"), ({"k": [1]}, "'k'"),
                                         ({"object": 7}, "'object'")])
def test_replay_names_a_press_annotation_field_of_the_wrong_type(tiny_run, tmp_path, capsys, fields, key):
    _, rec, memory = tiny_run
    hostile = tmp_path / "bad.mcap"
    _hostile_recording(rec, hostile, "Block", fields)
    code, _, err = _cli(["replay", hostile, "--memory", memory, "--out", tmp_path / "out", "--quiet"], capsys)
    assert code == 2
    _one_line_error(err, "bad.mcap: annotation", key)
    assert not (tmp_path / "out").exists()


# ---- output hygiene ---------------------------------------------------------------------------------------

def test_run_output_folder_rules(tiny_run, tmp_path, capsys):
    run, _, _ = tiny_run
    # an earlier run needs --force, and --force removes exactly its files first
    out = tmp_path / "run"
    assert main(["run", str(TINY), "--out", str(out), "--quiet"]) == 0
    (out / "maps" / "old_object.npz").write_bytes(b"stale")
    (out / "notes.txt").write_text("mine")
    code, _, err = _cli(["run", TINY, "--out", out, "--quiet"], capsys)
    assert code == 2 and "--force" in _one_line_error(err, str(out))
    assert main(["run", str(TINY), "--out", str(out), "--quiet", "--force"]) == 0
    assert not (out / "maps" / "old_object.npz").exists() and (out / "notes.txt").read_text() == "mine"
    # a recording the earlier run made inside its folder goes with it
    assert main(["run", str(TINY), "--out", str(out), "--quiet", "--force", "--record", str(out / "rec.mcap")]) == 0
    assert main(["run", str(TINY), "--out", str(out), "--quiet", "--force"]) == 0
    assert not (out / "rec.mcap").exists() and (out / "notes.txt").read_text() == "mine"
    # a folder that is not a palpate run, a run folder given to replay, a file given as --out
    other = tmp_path / "photos"
    other.mkdir()
    (other / "a.jpg").write_bytes(b"x")
    code, _, err = _cli(["run", TINY, "--out", other, "--quiet", "--force"], capsys)
    assert code == 2 and "holds no palpate output" in _one_line_error(err, str(other))
    assert (other / "a.jpg").read_bytes() == b"x"
    code, _, err = _cli(["replay", tiny_run[1], "--memory", tiny_run[2], "--out", run, "--quiet"], capsys)
    assert code == 2 and "holds a palpate run, not a replay" in _one_line_error(err, str(run))
    code, _, err = _cli(["run", TINY, "--out", other / "a.jpg", "--quiet"], capsys)
    assert code == 2 and "is a file, not a folder" in _one_line_error(err, "a.jpg")


def test_record_and_memory_outputs_never_destroy_inputs(tmp_path, capsys, data_dir):
    scenario = tmp_path / "s.toml"
    scenario.write_text(TINY.read_text())
    text = scenario.read_text()
    code, _, err = _cli(["run", scenario, "--out", tmp_path / "o1", "--record", scenario, "--force"], capsys)
    assert code == 2 and "is an input" in _one_line_error(err, "s.toml")
    assert scenario.read_text() == text
    important = tmp_path / "important.txt"
    important.write_text("keep")
    code, _, err = _cli(["run", scenario, "--out", tmp_path / "o2", "--record", important], capsys)
    assert code == 2 and "exists; add --force" in _one_line_error(err, "important.txt")
    assert important.read_text() == "keep"
    params = tmp_path / "p.csv"
    params.write_bytes((SEED_TABLE).read_bytes())
    code, _, err = _cli(["memory", "train", params, "-o", params, "--force"], capsys)
    assert code == 2 and "is an input" in _one_line_error(err, "p.csv")
    assert params.read_bytes() == (SEED_TABLE).read_bytes()
    mem = tmp_path / "m.json"
    mem.write_text("{}")
    code, _, err = _cli(["memory", "train", params, "-o", mem], capsys)
    assert code == 2 and "exists; add --force" in _one_line_error(err, "m.json")
    assert main(["memory", "train", str(params), "-o", str(mem), "--force"]) == 0
    assert json.loads(mem.read_text())["format"] == "palpate.haptic_memory"


# ---- bounded reads and one-line errors --------------------------------------------------------------------

def test_devices_folders_and_pipes_are_refused_before_reading(tmp_path, capsys):
    zero = tmp_path / "memory.json"
    zero.symlink_to("/dev/zero")
    code, _, err = _cli(["memory", "show", zero], capsys)
    assert code == 2 and "not a regular file" in _one_line_error(err, "memory.json")
    fifo = tmp_path / "fifo.toml"
    os.mkfifo(fifo)  # opening a FIFO for reading would block until a writer came
    with pytest.raises(ValidationError, match="fifo.toml.*not a regular file"):
        read_toml(fifo, "scenario file")
    with pytest.raises(ValidationError, match="not a regular file"):
        read_text(tmp_path, "scenario file")


def test_size_limits_are_checked_before_reading_and_can_be_raised(tmp_path, monkeypatch, capsys):
    big = tmp_path / "big.json"
    with open(big, "wb") as f:
        f.truncate(int(limits.LIMITS["text_mb"].default * 1e6) + 1)  # sparse: no time spent writing it
    code, _, err = _cli(["memory", "show", big], capsys)
    line = _one_line_error(err, "big.json", "text_mb", "--limit text_mb=")
    assert code == 2 and "docs/limits.md" in line
    monkeypatch.setenv(limits.ENV, "text_mb=100")
    with pytest.raises(ValidationError, match="not valid JSON"):  # read now, and found to be NUL bytes
        read_json(big, "haptic memory")
    monkeypatch.delenv(limits.ENV)
    code, _, err = _cli(["--limit", "json_depth=3", "memory", "show", REPO / "tests" / "data" / "nope.json"], capsys)
    assert code == 2 and "cannot read haptic memory: not found" in _one_line_error(err, "nope.json")
    code, _, err = _cli(["--limit", "bogus=1", "memory", "show", big], capsys)
    assert code == 2 and "unknown limit 'bogus'" in _one_line_error(err)
    code, out, err = _cli(["--limit", "text_mb=300", "memory", "show", big], capsys)  # read, then found NUL bytes
    assert code == 2 and "not valid JSON" in _one_line_error(err, "big.json")
    assert limits.ENV not in os.environ  # the limit held for that command only


@pytest.mark.parametrize("text, message", [
    ("[" * 100000 + "]" * 100000, "json_depth"),
    ('{"a": ' * 70 + "1" + "}" * 70, "nesting depth is 70 levels"),
    ('{"format": 1, "format": 2}', "key 'format' appears twice"),
    ('{"x": ' + "9" * 5000 + "}", "digits"),
    ('{"x": NaN}', "NaN"),
    ('{"x": "' + "y" * 100000 + '", "format": 3}', "key 'format' is 3"),
])
def test_hostile_json_is_one_line_naming_the_file(tmp_path, capsys, text, message):
    path = tmp_path / "mem.json"
    path.write_text(text)
    code, _, err = _cli(["memory", "show", path], capsys)
    line = _one_line_error(err, "mem.json", message)
    assert code == 2 and len(line) < 400


@pytest.mark.parametrize("text, message", [
    (b"[scenario]\nname = \"caf\xe9\"\n", "not UTF-8 text"),
    (b"[scenario]\nname = \"x\"\nseed = " + b"9" * 5000 + b"\n", "digits"),
    (b"a = " + b"[" * 5000 + b"]" * 5000, "nesting"),
])
def test_hostile_toml_is_one_line_naming_the_file(tmp_path, capsys, text, message):
    path = tmp_path / "scen.toml"
    path.write_bytes(text)
    code, _, err = _cli(["run", path, "--out", tmp_path / "out"], capsys)
    assert code == 2
    _one_line_error(err, "scen.toml", message)


@pytest.mark.parametrize("edit, key", [
    (lambda r: r["objects"][0].update(size_mm=[float("inf"), 20.0, 40.0]), "objects[0].size_mm"),
    (lambda r: r["objects"][0].update(position_mm=[float("nan"), 0.0]), "objects[0].position_mm"),
    (lambda r: r["objects"][0].update(grid_origin_mm=[0.0, float("nan")]), "objects[0].grid_origin_mm"),
    (lambda r: r["objects"][0].update(inclusions=[{"material": "hard", "shape": "sphere",
                                                   "center_mm": [float("nan"), 0.0, 5.0], "size_mm": [4.0]}]),
     "objects[0].inclusions[0].center_mm"),
    (lambda r: r["materials"][0].update(young_kpa=1e300), "materials[0].young_kpa: must be <= 1000000"),
    (lambda r: r.update(fingertip={"rows": 20000, "cols": 20000}), "fingertip.rows"),
    (lambda r: r.update(fingertip={"rows": 100, "cols": 100}), "taxels"),
    (lambda r: r.setdefault("sensors", {}).update(taxels={"rate_hz": 1e-300}), "sensors.taxels.rate_hz"),
    (lambda r: r["objects"][0].update(grid_cells=[100000, 100000]), "map_cells"),
    (lambda r: r["exploration"].update(cell_mm=0.001), "exploration.cell_mm"),
    (lambda r: r["scenario"].update(seed=2**200), "scenario.seed"),
    (lambda r: r["exploration"].update(budget=10**30), "exploration.budget"),
])
def test_implausible_or_huge_scenario_values_are_named_at_load(edit, key):
    raw = _tiny_raw()
    edit(raw)
    with pytest.raises(ValidationError, match="s.toml: " + key.replace("[", r"\[").replace("]", r"\]")
                       if "." in key else key):
        parse_scenario(raw, "s.toml", base_dir=TINY.parent)


def test_large_maps_from_small_object_and_cell_are_refused():
    raw = _tiny_raw()
    raw["objects"][0]["size_mm"] = [5000.0, 5000.0, 40.0]
    raw["exploration"]["cell_mm"] = 1.0
    with pytest.raises(ValidationError,
                       match=r"objects\[0\] \(Block\): its map .*25000000 cells, over the limit map_cells = 4000000"):
        parse_scenario(raw, "s.toml", base_dir=TINY.parent)


def test_npz_arrays_declaring_huge_shapes_are_refused_before_decoding(tmp_path):
    npz, sidecar = Grid2D(["a", "b"], (4, 3)).save(tmp_path / "map.npz")
    import zipfile

    header = {"descr": "<f8", "fortran_order": False, "shape": (100000, 100000, 2)}
    with zipfile.ZipFile(npz, "w") as zf:
        import io

        buf = io.BytesIO()
        np.lib.format.write_array_header_1_0(buf, header)
        zf.writestr("probabilities.npy", buf.getvalue() + b"\0" * 64)
        buf = io.BytesIO()
        np.save(buf, np.zeros((3, 4), bool))
        zf.writestr("explored.npy", buf.getvalue())
    with pytest.raises(ValidationError, match=r"map.npz: array 'probabilities' of shape \[100000, 100000, 2\]: "
                                              r"decoded size is 160000 MB, over the limit npz_mb = 512 MB"):
        Grid2D.load(npz)


def _material_folder(tmp_path: Path) -> Path:
    folder = tmp_path / "mat"
    p = np.zeros((3, 4, 2))
    p[..., 0] = 1.0
    HapticMaterialMap((0.0, 0.0), 0.01, ["soft", "hard"], p).write(folder)
    return folder


def _edit_manifest(folder: Path, **changes) -> None:
    doc = json.loads((folder / "manifest.json").read_text())
    doc.update(changes)
    (folder / "manifest.json").write_text(json.dumps(doc))


def test_haptic_material_folders_are_read_within_bounds(tmp_path):
    folder = _material_folder(tmp_path)
    assert HapticMaterialMap.read(folder).shape == (3, 4)
    for changes, message in (({"origin_m": [float("nan"), 0.0]}, "manifest.json: .*NaN"),
                             ({"origin_m": [1e400, 0.0]}, "manifest.json: .*Infinity"),
                             ({"origin_m": ["0", 0.0]}, "key 'origin_m'"), ({"shape": [3.5, 4]}, "key 'shape'"),
                             ({"shape": [30000, 30000]}, "png_pixels")):
        f = tmp_path / f"case{len(message)}_{len(str(changes))}"
        f.mkdir()
        for p in folder.iterdir():
            (f / p.name).write_bytes(p.read_bytes())
        _edit_manifest(f, **changes)
        with pytest.raises(ValidationError, match=message):
            HapticMaterialMap.read(f)
    outside = tmp_path / "secret.png"
    outside.write_bytes((folder / "measured.png").read_bytes())
    for fname in (str(outside), "../secret.png"):
        _edit_manifest(folder, measured_mask=fname)
        with pytest.raises(ValidationError, match="must be a file name inside"):
            HapticMaterialMap.read(folder)
    (folder / "link.png").symlink_to(outside)
    _edit_manifest(folder, measured_mask="link.png")
    with pytest.raises(ValidationError, match="leads outside the material folder"):
        HapticMaterialMap.read(folder)


def test_png_problems_are_named(tmp_path):
    import struct
    import zlib

    folder = _material_folder(tmp_path)
    png = folder / "measured.png"
    good = png.read_bytes()
    png.write_bytes(good[: len(good) // 2])
    with pytest.raises(ValidationError, match="measured.png: not a readable PNG"):
        HapticMaterialMap.read(folder)
    png.write_bytes(b"GIF89a" + good[6:])
    with pytest.raises(ValidationError, match="measured.png: not a PNG"):
        HapticMaterialMap.read(folder)
    # an IHDR declaring 9000 x 9000 pixels (81 MP) in a file of a few hundred bytes: refused from the header
    ihdr = struct.pack(">IIBBBBB", 9000, 9000, 8, 0, 0, 0, 0)
    chunk = struct.pack(">I", 13) + b"IHDR" + ihdr + struct.pack(">I", zlib.crc32(b"IHDR" + ihdr))
    png.write_bytes(good[:8] + chunk + good[33:])
    with pytest.raises(ValidationError, match=r"measured.png: 9000 x 9000 image: pixels is 81000000 pixels, over the "
                                              r"limit png_pixels = 16000000"):
        HapticMaterialMap.read(folder)


def test_errors_are_one_line_and_tracebacks_come_with_debug(tmp_path, capsys, monkeypatch):
    bad = tmp_path / "bad.toml"
    bad.write_text("[scenario\n")
    code, _, err = _cli(["run", bad, "--out", tmp_path / "o"], capsys)
    assert code == 2 and "Traceback" not in err
    _one_line_error(err, "bad.toml")
    with pytest.raises(ValidationError):
        main(["--debug", "run", str(bad), "--out", str(tmp_path / "o")])

    def boom(_args):
        raise KeyError("a bug")

    import palpate.core.cli.memory as memory_cli

    monkeypatch.setattr(memory_cli, "cmd_show", boom)
    code, _, err = _cli(["memory", "show", bad], capsys)
    assert code == 1 and err.count("\n") == 1 and "internal error: KeyError" in err and "--debug" in err


def test_memory_show_no_audit_is_the_recovery_the_audit_error_names(tmp_path, capsys, data_dir):
    mem = tmp_path / "m.json"
    assert main(["memory", "train", str(SEED_TABLE), "-o", str(mem)]) == 0
    doc = json.loads(mem.read_text())
    doc["means_N"][0][0] += 1.0
    mem.write_text(json.dumps(doc))
    capsys.readouterr()
    code, _, err = _cli(["memory", "show", mem], capsys)
    assert code == 2 and "--no-audit" in _one_line_error(err, "m.json", "means_N")
    code, out, _ = _cli(["memory", "show", mem, "--no-audit"], capsys)
    assert code == 0 and "Haptic memory" in out


def test_scenario_files_are_loaded_through_the_bounded_reader(tmp_path):
    path = tmp_path / "s.toml"
    path.write_bytes(TINY.read_bytes())
    assert load_scenario(path).name == "tiny"
    path.unlink()
    path.symlink_to("/dev/zero")
    with pytest.raises(ValidationError, match="s.toml: scenario file: is a device"):
        load_scenario(path)


def test_a_mesh_must_be_a_regular_file(tmp_path):
    raw = _tiny_raw()
    (tmp_path / "zero.obj").symlink_to("/dev/zero")
    raw["objects"][0].update(shape="mesh", mesh=str(tmp_path / "zero.obj"))
    with pytest.raises(ValidationError, match=r"s.toml: objects\[0\].mesh: is a device, pipe or socket"):
        parse_scenario(raw, "s.toml", base_dir=tmp_path)


def test_a_reader_that_goes_away_ends_the_command_quietly(tmp_path, data_dir):
    import subprocess
    import sys

    mem = tmp_path / "m.json"
    assert main(["memory", "train", str(SEED_TABLE), "-o", str(mem)]) == 0
    cli = "import sys; from palpate.core.cli import main; sys.exit(main())"
    proc = subprocess.Popen([sys.executable, "-c", cli, "memory", "show", str(mem)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE)
    proc.stdout.close()  # like `| head -0`: closed before the command writes a byte
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 141 and err == b""


def test_a_png_shorter_than_its_header_is_named(tmp_path):
    folder = _material_folder(tmp_path)
    png = folder / "measured.png"
    png.write_bytes(png.read_bytes()[:22])
    with pytest.raises(ValidationError, match="measured.png: not a PNG file"):
        HapticMaterialMap.read(folder)


def test_a_map_reaching_past_its_object_is_named_with_the_scenario_and_object(tmp_path, capsys):
    raw = tomllib.loads(TINY.read_text())
    path = tmp_path / "s.toml"
    path.write_text(TINY.read_text().replace("size_mm = [30.0, 20.0, 40.0]", "size_mm = [1.5, 1.5, 1.5]"))
    assert "size_mm = [1.5" in path.read_text() and raw["objects"][0]["name"] == "Block"
    code, _, err = _cli(["run", path, "--out", tmp_path / "out", "--quiet"], capsys)
    assert code == 2
    _one_line_error(err, "s.toml: object 'Block', cell [1, 1]", "check the object's size_mm")


@pytest.mark.parametrize("text", ['{"t": [[1.0, 2.0], [3.0, 1e999]]}', '{"t": [["inf", -1e999]]}', "1e999",
                                  '[{"a": [1, 2]}, {"b": [0.5, 1e400]}]'])
def test_a_number_too_large_for_a_float_is_refused_wherever_it_sits(text):
    with pytest.raises(ValidationError, match="too large for a float"):
        parse_json(text, "doc.json", "a test document")


def test_tables_of_numbers_are_read_as_written_and_their_nesting_counted():
    doc = {"t": [[1e308, -2.5], [3, 4]], "s": ["inf", 1.5, True, None], "n": 12345678901234567890123}
    assert parse_json(json.dumps(doc), "doc.json", "a test document") == doc
    deep = "[" * 65 + "1.5" + "]" * 65
    with pytest.raises(ValidationError, match="json_depth"):
        parse_json(deep, "doc.json", "a test document")
    assert parse_json("[" * 60 + "1.5" + "]" * 60, "doc.json", "a test document") is not None


def test_a_list_that_starts_with_numbers_and_holds_long_strings_is_read_without_padding_them():
    # a table read as one array must not lay every string out at the longest one's width: 12 kB of text here would
    # take 16 MB as a numpy string array
    import tracemalloc

    doc = [1.5] + ["y"] * 2000 + ["x" * 2000]
    text = json.dumps(doc)
    tracemalloc.start()
    try:
        assert parse_json(text, "doc.json", "a test document") == doc
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 20 * len(text)


def test_a_write_that_fails_midway_leaves_the_old_file_whole_and_no_temporary(tmp_path):
    # a run killed while writing summary.json must not leave a truncated one that a sweep would have to judge
    path = tmp_path / "summary.json"
    write_text(path, '{"presses": 12}')
    with pytest.raises(UnicodeEncodeError):
        write_text(path, '{"name": "' + "x" * 100_000 + "\ud800" + '"}')
    assert path.read_text(encoding="utf-8") == '{"presses": 12}'
    assert sorted(p.name for p in tmp_path.iterdir()) == ["summary.json"]
    write_text(path, "{}")
    assert path.read_text(encoding="utf-8") == "{}"
