"""The public API (``import palpate``): cheap to import, and each function returns what the command line writes."""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
from importlib.metadata import version

import numpy as np
import pytest

import palpate
from palpate.core.errors import ValidationError

TINY = "sweeps/tiny_base"  # two materials, a 30 x 20 mm block at (15, 10) mm, 10 mm cells, analytic presses


def test_import_palpate_loads_nothing_until_a_name_is_used():
    code = ("import json, sys, palpate\nv = palpate.__version__\nroots = ('numpy', 'scipy', 'palpate')\n"
            "print(json.dumps([v, sorted(m for m in sys.modules if m.split('.')[0] in roots)]))")
    v, modules = json.loads(subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                                           check=True, timeout=60).stdout)
    assert v == version("palpate")
    assert modules == ["palpate", "palpate.core"]


def test_unknown_names_are_attribute_errors():
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        palpate.nope  # noqa: B018
    assert {"load_scenario", "press", "train_memory", "run", "__version__"} <= set(dir(palpate))


def test_load_scenario_by_name_or_path():
    from palpate.core.world.resources import scenarios_dir

    by_name = palpate.load_scenario(TINY)
    assert by_name == palpate.load_scenario(scenarios_dir() / "sweeps" / "tiny_base.toml")
    assert by_name.references == ["soft", "hard"] and by_name.exploration.depth == pytest.approx(0.002)
    with pytest.raises(ValidationError, match="not the name of a shipped scenario"):
        palpate.load_scenario("no_such_scenario")


def test_press_at_a_cell_of_an_object():
    scenario = palpate.load_scenario(TINY)
    one = palpate.press(scenario, "Block", cell=(3, 2))
    # the block spans 0-30 mm x 0-20 mm in 10 mm cells: cell (3, 2) is centred at (25, 15) mm
    assert one.target == pytest.approx((0.025, 0.015))
    assert one.frames and one.poses and one.frames[0].counts.shape == (4, 4)
    # robot variability: the press reaches the planned 2 mm, under the 10 N limit
    assert one.truth.indentation.max() == pytest.approx(0.002, rel=0.05)
    assert one.truth.force.max() < 10.0
    assert one.params.shape == (4,) and np.all(np.isfinite(one.params))
    assert one.result.location == pytest.approx((0.025, 0.015), abs=1e-3)
    same = palpate.press(scenario, xy=(0.025, 0.015))  # the one object may go unnamed
    assert np.array_equal(same.params, one.params)


def test_a_harder_material_presses_stiffer():
    soft = palpate.load_scenario(TINY)
    hard = palpate.with_settings(soft, objects=[soft.raw["objects"][0] | {"material": "hard"}])
    n1_soft = palpate.press(soft, cell=(1, 1)).params[0]
    n1_hard = palpate.press(hard, cell=(1, 1)).params[0]
    assert n1_hard > 5 * n1_soft  # 450 kPa against 20 kPa


def test_press_rejects_bad_targets():
    scenario = palpate.load_scenario(TINY)
    with pytest.raises(ValidationError, match="either xy .* or cell"):
        palpate.press(scenario, "Block")
    with pytest.raises(ValidationError, match=r"cell \(4, 1\) is outside the 3 x 2 map"):
        palpate.press(scenario, "Block", cell=(4, 1))
    with pytest.raises(ValidationError, match="no object 'Lump'; its objects: Block"):
        palpate.press(scenario, "Lump", cell=(1, 1))
    for cell in ((1.5, 1), ("1", 1), (True, 1), (np.nan, 1), (1, 1, 1)):
        with pytest.raises(ValidationError, match="cell must be two whole numbers"):
            palpate.press(scenario, "Block", cell=cell)
    for xy in ((0.01,), "ab", ((0.1, 0.2), (0.3, 0.4))):
        with pytest.raises(ValidationError, match=r"xy must be \(x, y\) in m"):
            palpate.press(scenario, "Block", xy=xy)
    with pytest.raises(ValidationError, match="press: x must be a finite number"):
        palpate.press(scenario, "Block", xy=("0.01", 0.01))
    with pytest.raises(ValidationError, match="press: seed must be a whole number >= 0"):
        palpate.press(scenario, "Block", cell=(1, 1), seed=-3)
    # numpy's numbers and arrays are numbers too
    assert palpate.press(scenario, "Block", xy=np.array([0.015, 0.01]), seed=np.int64(2)).target == (0.015, 0.01)
    by_numpy = palpate.press(scenario, "Block", cell=(np.int64(1), 1))
    assert by_numpy.target == palpate.press(scenario, "Block", cell=(1, 1)).target


def test_train_memory_is_the_memory_a_run_writes(tmp_path):
    scenario = palpate.load_scenario(TINY)
    training = palpate.train_memory(scenario)
    assert training.memory.materials == ["soft", "hard"]
    assert training.crossval.confusion.shape == (2, 2)
    assert [len(p) for p in training.presses.values()] == [6, 6]
    result = palpate.run(scenario, tmp_path / "run", policy="random")
    written = palpate.HapticMemory.load(result.out / "memory.json")
    # the same presses (the run lays them on its timeline, which moves the fits' last bits only)
    assert written.training_labels == training.memory.training_labels
    np.testing.assert_allclose(written.training_params, training.memory.training_params, rtol=1e-9)
    np.testing.assert_allclose(written.means_N, training.memory.means_N, rtol=1e-9)
    assert result.summary == json.loads((tmp_path / "run" / "summary.json").read_text())
    assert result.summary["objects"][0]["policy"] == "random"
    grid = result.map("Block")
    assert grid.probabilities.shape == (2, 3, 2)
    post = np.asarray(result.summary["objects"][0]["per_press"][-1]["posterior"])
    assert post.shape == (2,) and post.sum() == pytest.approx(1.0)


def test_settings_are_validated_like_the_file():
    scenario = palpate.load_scenario(TINY)
    with pytest.raises(ValidationError, match="exploration.policy"):
        palpate.with_settings(scenario, exploration={"policy": "spiral"})
    changed = palpate.with_settings(scenario, exploration={"depth_mm": 3.0})
    assert changed.exploration.depth == pytest.approx(0.003) and scenario.exploration.depth == pytest.approx(0.002)


def test_the_tutorial_runs_end_to_end(tmp_path):
    from pathlib import Path

    tutorial = Path(__file__).resolve().parent.parent / "docs" / "tutorial.py"
    proc = subprocess.run([sys.executable, str(tutorial), str(tmp_path / "tutorial")], capture_output=True,
                          text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    summary = json.loads((tmp_path / "tutorial" / "summary.json").read_text())
    assert summary["algorithms"]["policy"] == "backwards"
    assert [p["cell"] for p in summary["objects"][0]["per_press"]] == [[3, 2], [2, 2], [1, 2]]
    assert f"palpate {version('palpate')}" in proc.stdout


def test_every_name_the_api_doc_uses_exists():
    import re
    from pathlib import Path

    doc = (Path(__file__).resolve().parent.parent / "docs" / "api.md").read_text()
    used = set(re.findall(r"palpate\.([A-Za-z_]+)", doc)) - {"policies", "classifiers", "features", "sim_backends",
                                                                   "commands"}
    assert {"load_scenario", "press", "train_memory", "run", "register_policy"} <= used
    # submodules of an extra (palpate.gym) are found without importing them: the extra may not be installed
    submodules = {n for n in used if n in palpate._SUBMODULES and importlib.util.find_spec(f"palpate.{n}")}
    missing = sorted(name for name in used - submodules if not hasattr(palpate, name))
    assert not missing, f"docs/api.md names palpate.{missing}, which do not exist"
