"""Scenarios and models ship inside the package and are found by name from any folder; a missing optional extra is
a one-line error naming it, before any work."""

from __future__ import annotations

import sys

import pytest

from palpate.core.cli import main
from palpate.core.errors import ValidationError
from palpate.core.extras import MissingExtraError, missing_extra, require_extra
from palpate.core.world.resources import find_scenario, models_dir, scenarios_dir, shipped_scenarios
from palpate.core.world.scenario_file import load_scenario


def test_shipped_scenarios_are_found_by_name_from_another_folder(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    names = {i.name for i in shipped_scenarios()}
    assert {"thesis_ch6", "heterogeneous", "volumetric", "sweeps/tiny"} <= names
    assert find_scenario("thesis_ch6") == scenarios_dir() / "thesis_ch6.toml"
    assert find_scenario("thesis_ch6.toml") == find_scenario("thesis_ch6")
    assert find_scenario("sweeps/tiny") == scenarios_dir() / "sweeps" / "tiny.toml"
    own = tmp_path / "thesis_ch6.toml"  # a file of the user's own wins over the shipped name
    own.write_text("x")
    assert find_scenario("thesis_ch6.toml") == own.relative_to(tmp_path)
    with pytest.raises(ValidationError, match=r"nope: no such file, and not the name of a shipped scenario \(.*"
                                              r"thesis_ch6.*\); see palpate scenarios list"):
        find_scenario("nope")


def test_every_shipped_scenario_loads_with_its_models(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for info in shipped_scenarios():
        if info.name.startswith("sweeps/"):
            continue
        scenario = load_scenario(info.path)
        assert scenario.name and info.description, info.name
    assert (models_dir() / "flex_calibration.json").is_file()
    assert (models_dir() / "flex_plate_calibration.json").is_file()
    assert (models_dir() / "flex_lump_calibration.json").is_file()
    assert (models_dir() / "fingers" / "planar2.toml").is_file()


def test_scenarios_list_show_and_copy(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["scenarios", "list"]) == 0
    out = capsys.readouterr().out
    assert "thesis_ch6" in out and "Three reference materials" in out
    assert main(["scenarios", "show", "heterogeneous"]) == 0
    assert capsys.readouterr().out == (scenarios_dir() / "heterogeneous.toml").read_text()
    assert main(["scenarios", "copy", "heterogeneous", str(tmp_path)]) == 0
    copy = tmp_path / "heterogeneous.toml"
    assert str(models_dir() / "haptic_materials" / "heterogeneous_block") in copy.read_text()
    assert load_scenario(copy).objects[0].spec.material_map is not None  # the map still resolves from here
    assert main(["scenarios", "copy", "heterogeneous", str(tmp_path)]) == 2  # never overwrites
    assert "exists; not overwriting it" in capsys.readouterr().err


def test_a_copy_is_named_after_its_file(tmp_path, capsys):
    assert main(["scenarios", "copy", "thesis_ch6", str(tmp_path / "my_lab.toml")]) == 0
    copy = load_scenario(tmp_path / "my_lab.toml")
    assert copy.name == "my_lab" and load_scenario(find_scenario("thesis_ch6")).name == "thesis_ch6"
    # everything else is the shipped file's (but the paths to the shipped models)
    shipped = (scenarios_dir() / "thesis_ch6.toml").read_text().splitlines()
    copied = (tmp_path / "my_lab.toml").read_text().splitlines()
    assert [a for a, b in zip(shipped, copied, strict=True) if a != b and "models/" not in a] == ['name = "thesis_ch6"']


def test_sweep_files_are_listed_apart_from_scenarios(capsys):
    assert main(["scenarios", "list"]) == 0
    out = capsys.readouterr().out
    scenarios, sweeps = out.split("\nsweep files (palpate run refuses them")
    assert "sweeps/tiny " not in scenarios and "thesis_ch6" in scenarios
    assert f"palpate sweep {scenarios_dir() / 'sweeps' / 'tiny.toml'} --out DIR" in sweeps
    assert "sweeps/tiny_base" not in sweeps  # tiny_base is a scenario
    kinds = {i.name: i.kind for i in shipped_scenarios()}
    assert kinds["sweeps/tiny"] == "sweep" and kinds["sweeps/tiny_base"] == kinds["thesis_ch6"] == "scenario"


def test_missing_extras_name_the_extra():
    exc = ModuleNotFoundError("No module named 'mujoco'", name="mujoco")
    assert str(missing_extra(exc, "the 'sim' source")) == (
        "the 'sim' source needs the 'sim' extra (module 'mujoco'): install it with pip install 'palpate[sim]'")
    require_extra("the figures", "numpy", "matplotlib")  # installed: no error
    with pytest.raises(MissingExtraError, match="needs the Python module 'surely_not_a_module', which is not"):
        require_extra("x", "surely_not_a_module")


def test_require_extra_names_the_extra_of_a_missing_module(monkeypatch):
    from palpate.core import extras

    real = extras.find_spec
    monkeypatch.setattr(extras, "find_spec", lambda name: None if name == "foxglove" else real(name))
    with pytest.raises(MissingExtraError, match=r"palpate run --live needs the 'live' extra \(module 'foxglove'\): "
                                                r"install it with pip install 'palpate\[live\]'"):
        require_extra("palpate run --live", "foxglove")


def test_run_live_without_the_extra_stops_before_any_work(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "foxglove", None)  # import foxglove now raises ImportError
    out = tmp_path / "out"
    assert main(["run", "thesis_ch6", "--out", str(out), "--live", "0"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1] == ("palpate: error: the live view needs the 'live' extra (module 'foxglove'): install it with "
                       "pip install 'palpate[live]'")
    assert not out.exists()  # nothing trained, nothing written


def test_run_without_the_sim_extra_stops_before_training(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "mujoco", None)
    for name in [m for m in sys.modules if m.startswith("palpate.sim")]:
        monkeypatch.delitem(sys.modules, name)
    out = tmp_path / "out"
    assert main(["run", "thesis_ch6", "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == ("palpate: error: the 'sim' source needs the 'sim' extra (module 'mujoco'): install it with pip "
                   "install 'palpate[sim]'")
    assert not (out / "memory.json").exists()
