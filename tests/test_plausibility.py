"""Numbers read from files are checked for physical plausibility, not only for NaN and infinity: a recording's
pose 1e300 m away or sensel of 1e300 m^2, a haptic material's origin 1e300 m away or cells of 1e-300 m, probability
maps that are no probabilities, and integers too long to be numbers are one-line errors naming the file and the
field; the ranges are limits (docs/limits.md) a user can widen with ``palpate --limit NAME=VALUE``."""

from __future__ import annotations

import dataclasses
import json
import warnings
from pathlib import Path

import numpy as np
import pytest

from palpate.core import limits
from palpate.core.cli import main
from palpate.core.errors import RecordingError, ValidationError
from palpate.core.io.mcap_reader import read_recording
from palpate.core.io.mcap_writer import RecordingWriter
from palpate.core.world.haptic_material import HapticMaterialMap

REPO = Path(__file__).resolve().parent.parent
V1 = REPO / "tests" / "data" / "recording_v1"


def _rewritten(dst: Path, *, pose_z: float | None = None, sensel_area: float | None = None, at: int = 5) -> Path:
    """The shipped recording rewritten with one pose's z or one frame's sensel area (every frame's: the pad's
    area is one number) replaced."""
    rec = read_recording(V1 / "run.mcap")
    with RecordingWriter(dst, dict(rec.metadata)) as w:
        for a in rec.annotations:
            w.write_annotation(a.t, a.kind, dict(a.data))
        for f in rec.frames:
            if sensel_area is not None:
                f = dataclasses.replace(f, sensel_area=sensel_area)
            w.write_taxel(f)
        for i, p in enumerate(rec.poses):
            if pose_z is not None and i == at:
                p = dataclasses.replace(p, position=np.array([p.position[0], p.position[1], pose_z]))
            w.write_pose(p)
    return dst


def _error_line(err: str) -> str:
    lines = [line for line in err.strip().splitlines() if line.startswith("palpate: ")]
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


@pytest.mark.parametrize(("change", "field"), [({"pose_z": 1e300}, "position.z"),
                                               ({"sensel_area": 1e300}, "sensel_area")],
                         ids=["pose z 1e300 m", "sensel area 1e300 m^2"])
def test_a_recording_with_an_absurd_magnitude_is_a_one_line_error(tmp_path, capsys, change, field):
    rec = _rewritten(tmp_path / "absurd.mcap", **change)
    out = tmp_path / "out"
    code = main(["replay", str(rec), "--memory", str(V1 / "memory.json"), "--out", str(out), "--no-figures",
                 "--quiet"])
    line = _error_line(capsys.readouterr().err)
    assert code == 2 and str(rec) in line and field in line and "--limit" in line, line
    assert not (out / "summary.json").exists()


def test_a_plausibility_range_is_a_limit_a_user_can_widen(tmp_path, monkeypatch):
    rec = _rewritten(tmp_path / "far.mcap", pose_z=150.0)
    with pytest.raises(RecordingError, match=r"position\.z.*length_m"):
        read_recording(rec)
    monkeypatch.setenv(limits.ENV, "length_m=1000")
    assert read_recording(rec).poses[5].position[2] == 150.0


def _material(folder: Path, rng) -> Path:
    p = rng.dirichlet(np.ones(2), size=(3, 4))
    p[0, 0] = 0.0  # a measured cell whose every probability is zero
    HapticMaterialMap((0.0, 0.0), 0.01, ["soft", "hard"], p, measured=np.ones((3, 4), bool)).write(folder)
    return folder / "manifest.json"


def _edit(mpath: Path, edit) -> None:
    manifest = json.loads(mpath.read_text())
    edit(manifest)
    mpath.write_text(json.dumps(manifest))


def _fixed(manifest: dict, folder: Path) -> None:
    """Undo _material's zero cell: both maps at half in cell [0, 0] (a valid folder)."""
    from PIL import Image

    for name in ("soft", "hard"):
        path = folder / f"material_probability_{name}.png"
        img = np.array(Image.open(path))
        img[-1, 0] = 128
        Image.fromarray(img).save(path)


@pytest.mark.filterwarnings("error")
@pytest.mark.parametrize(("edit", "words"), [
    (lambda m: m.update(origin_m=[1e300, 0.0]), ("origin_m", "length_m")),
    (lambda m: m.update(cell_size_m=1e-300), ("cell_size_m", "length_min_m")),
    (lambda m: m.update(cell_size_m=1e300), ("cell_size_m", "length_m")),
    (lambda m: m["maps"].update(material_probability_ghost={**m["maps"]["material_probability_soft"],
                                                            "material": "ghost"}), ("ghost", "materials")),
    (lambda m: m["maps"]["material_probability_soft"].update(range=[1.0, 0.0]), ("material_probability_soft", "range")),
    (lambda m: m["maps"]["material_probability_hard"].update(resolution=-1 / 255), ("material_probability_hard",
                                                                                     "resolution")),
], ids=["origin 1e300", "cell 1e-300", "cell 1e300", "unlisted material", "inverted range", "negative resolution"])
def test_a_haptic_material_with_implausible_numbers_is_refused_with_the_key(tmp_path, rng, edit, words):
    mpath = _material(tmp_path / "hm", rng)
    _fixed({}, tmp_path / "hm")
    HapticMaterialMap.read(tmp_path / "hm")  # valid before the edit
    _edit(mpath, edit)
    with pytest.raises(ValidationError) as exc:
        HapticMaterialMap.read(tmp_path / "hm")
    assert str(mpath) in str(exc.value) and all(w in str(exc.value) for w in words), exc.value


def test_a_measured_cell_whose_probabilities_are_all_zero_is_refused(tmp_path, rng):
    mpath = _material(tmp_path / "hm", rng)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ValidationError, match=r"cell \[0, 0\].*sum to 0") as exc:
            HapticMaterialMap.read(tmp_path / "hm")
    assert str(mpath.parent) in str(exc.value)


def test_an_integer_of_5000_digits_in_a_realism_profile_is_a_one_line_error(tmp_path):
    from palpate.sim.realism.profile_file import load_profile

    path = tmp_path / "long.toml"
    path.write_text("[press]\ntilt_deg = " + "9" * 5000 + "\n")
    with pytest.raises(ValidationError, match="long.toml") as exc:
        load_profile(path)
    assert len(str(exc.value)) < 300 and "\n" not in str(exc.value)


@pytest.mark.parametrize(("line", "value", "key"), [
    ("SENSEL_AREA 0.0645 sq cm", "SENSEL_AREA 1e300 sq cm", "SENSEL_AREA"),
    ("ROW_SPACING 0.254 cm", "ROW_SPACING 1e300 cm", "ROW_SPACING")])
def test_a_tekscan_header_with_an_absurd_magnitude_is_refused(tmp_path, capsys, line, value, key):
    export = tmp_path / "absurd.csv"
    export.write_text((REPO / "tests" / "data" / "tekscan_press.csv").read_text().replace(line, value))
    code = main(["import", "tekscan", str(export), "--out", str(tmp_path / "x.mcap")])
    err = _error_line(capsys.readouterr().err)
    assert code == 2 and f"{export.name}:" in err and key in err and "--limit" in err, err
    assert not (tmp_path / "x.mcap").exists()
