"""Scenario files: the shipped ones load, and every kind of mistake names the file and the key path."""

import tomllib
from pathlib import Path

import pytest

from palpate.core.errors import ValidationError
from palpate.core.world.scenario_file import load_scenario, parse_scenario

SCENARIOS = sorted((Path(__file__).resolve().parent.parent / "scenarios").glob("*.toml"))


@pytest.mark.parametrize("path", SCENARIOS, ids=[p.stem for p in SCENARIOS])
def test_shipped_scenarios_load(path):
    s = load_scenario(path)
    assert len(s.references) >= 2
    assert s.objects, "a shipped scenario explores at least one object"
    for obj in s.objects:
        for m in obj.spec.materials():
            assert s.materials[m.name].like in s.references


def test_thesis_scenario_is_the_seed_experiment():
    s = load_scenario(Path(__file__).resolve().parent.parent / "scenarios" / "thesis_ch6.toml")
    assert s.references == ["Material_1", "Material_2", "Material_3"]
    assert s.training.presses_per_material == 10
    assert [o.spec.name for o in s.objects] == ["Object_1", "Object_2", "Object_3"]
    # Seed 000 Table 6.8, 1-based cells
    assert s.objects[1].regions == ((5, 5), (12, 7), (5, 8), (20, 5), (20, 8))
    assert s.exploration.cell_size == pytest.approx(0.01) and s.exploration.presses_per_region == 2


def _base() -> dict:
    return tomllib.loads("""
[scenario]
name = "t"
[[materials]]
name = "a"
young_kpa = 20
[[materials]]
name = "b"
young_kpa = 200
[[objects]]
name = "o"
size_mm = [50, 50, 30]
material = "a"
regions = [[1, 1]]
""")


def test_minimal_scenario_converts_units():
    s = parse_scenario(_base(), "t.toml")
    assert s.materials["b"].material.young == pytest.approx(200e3)
    assert s.objects[0].spec.size == pytest.approx((0.05, 0.05, 0.03))
    assert s.fidelity == "auto"


@pytest.mark.parametrize(
    "mutate, key, expected",
    [
        (lambda d: d["scenario"].update(fidelity="fast"), "scenario.fidelity", "must be one of"),
        (lambda d: d["scenario"].update(colour="red"), "scenario.colour", "unknown key"),
        (lambda d: d["materials"][0].update(young_kpa="soft"), "materials[0].young_kpa", "expected a number"),
        (lambda d: d["materials"][1].update(young_kpa=-3), "materials[1].young_kpa", "must be >"),
        (lambda d: d["objects"][0].update(size_mm=[50, 50]), "objects[0].size_mm", "expected 3 numbers"),
        (lambda d: d["objects"][0].update(material="steel"), "objects[0].material", "unknown material"),
        (lambda d: d["objects"][0].update(regions=[[0, 1]]), "objects[0].regions[0]", "1-based"),
        (lambda d: d.update(training={"presses_per_material": 3}), "training.presses_per_material", ">= 4"),
        (lambda d: d.update(exploration={"map": "octree"}), "exploration.map", "must be one of"),
        (lambda d: d["materials"][0].update(reference=False), "materials[0].like", "missing"),
        (lambda d: d.pop("scenario"), "scenario", "missing"),
    ],
)
def test_bad_scenarios_name_file_and_key(mutate, key, expected):
    d = _base()
    mutate(d)
    with pytest.raises(ValidationError) as err:
        parse_scenario(d, "bad.toml")
    msg = str(err.value)
    assert msg.startswith("bad.toml: "), msg
    assert key in msg and expected in msg, msg


def test_unreadable_files_are_reported(tmp_path):
    with pytest.raises(ValidationError, match="not found"):
        load_scenario(tmp_path / "nope.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("[scenario\nname=1")
    with pytest.raises(ValidationError, match="bad.toml: not valid TOML"):
        load_scenario(bad)


def test_loading_never_executes_code(tmp_path):
    # A TOML string that looks like Python stays a string; only the schema's keys are accepted.
    d = _base()
    d["scenario"]["name"] = "__import__('os').system('false')"
    s = parse_scenario(d, "t.toml")
    assert s.name.startswith("__import__")


def test_a_misspelt_key_is_answered_with_the_key_meant():
    d = _base()
    d["objects"][0]["matrial"] = "a"
    with pytest.raises(ValidationError, match=r"objects\[0\]\.matrial: unknown key \(did you mean 'material'\?"):
        parse_scenario(d, "bad.toml")
    d = _base()
    d["scenario"]["xyzzy"] = 1  # nothing close: no guess
    with pytest.raises(ValidationError) as err:
        parse_scenario(d, "bad.toml")
    assert "did you mean" not in str(err.value) and "scenario.xyzzy: unknown key" in str(err.value)


def _with_inclusion(shape: str, center, size, obj_shape: str = "box") -> dict:
    d = _base()
    if obj_shape == "cylinder":
        d["objects"][0].update(shape="cylinder", size_mm=[25, 30])
    d["objects"][0]["inclusions"] = [{"material": "b", "shape": shape, "center_mm": center, "size_mm": size}]
    return d


@pytest.mark.parametrize("shape, center, size, obj_shape", [
    ("box", [100, 0, 15], [10, 10, 10], "box"),       # beside the block (it spans x -25..25 mm)
    ("sphere", [0, 0, 40], [5], "box"),               # above its top (30 mm up from the table)
    ("box", [0, 0, -10], [10, 10, 10], "box"),        # under the table
    ("column", [0, 40, 0], [10, 10], "box"),          # a column beside it
    ("box", [24, 24, 15], [10, 10, 10], "cylinder"),  # in the corner of the cylinder's bounding square only
])
def test_an_inclusion_outside_its_object_is_refused_with_the_key(shape, center, size, obj_shape):
    with pytest.raises(ValidationError) as err:
        parse_scenario(_with_inclusion(shape, center, size, obj_shape), "bad.toml")
    msg = str(err.value)
    assert msg.startswith("bad.toml: objects[0].inclusions[0].center_mm: ") and "outside object 'o'" in msg, msg
    assert "z up from the table" in msg


@pytest.mark.parametrize("shape, center, size, obj_shape", [
    ("box", [24, 0, 15], [10, 10, 10], "box"),        # reaching 1 mm into the block's side
    ("sphere", [0, 0, 32], [5], "box"),               # poking 3 mm down into it from above
    ("column", [0, 0, 0], [10, 10], "box"),
    ("box", [15, 15, 15], [10, 10, 10], "cylinder"),  # its corner (10, 10) is inside the 25 mm radius
])
def test_an_inclusion_meeting_its_object_is_accepted_and_listed(shape, center, size, obj_shape):
    s = parse_scenario(_with_inclusion(shape, center, size, obj_shape), "t.toml")
    assert [m.name for m in s.objects[0].spec.materials()] == ["a", "b"]
