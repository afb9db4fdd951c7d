"""Plugins: a policy, a classifier and a feature extractor from a separate installed package (entry points) or
registered in process run a shipped scenario, and every output names them."""

from __future__ import annotations

import importlib
import json
import sys
import textwrap

import numpy as np
import pytest

import palpate
from palpate.core.cli import main
from palpate.core.errors import ValidationError
from palpate.core.world.resources import find_scenario

TINY = "sweeps/tiny_base"  # a 3 x 2 cell block, raster, budget 3, analytic presses

PLUGIN = '''
"""A tiny third-party package: a checkerboard policy, a scikit-learn classifier, a two-number feature extractor."""
from palpate.core.planning.policies import Target
from sklearn.linear_model import LogisticRegression
from sklearn.pipeline import make_pipeline
from sklearn.preprocessing import StandardScaler


class Checkerboard:
    """The black cells of a checkerboard in raster order, then the white ones."""

    def __init__(self, context):
        nx, ny = context.geometry.plane_shape
        cells = [(ix, iy) for iy in range(ny) for ix in range(nx)]
        self.queue = [c for c in cells if sum(c) % 2 == 0] + [c for c in cells if sum(c) % 2 == 1]

    def next_target(self, grid, post=None, last=None):
        return Target(*self.queue.pop(0)) if self.queue else None


def logistic():
    return make_pipeline(StandardScaler(), LogisticRegression())


def stiffness(result):
    return None if result.fit is None else result.fit.params[[0, 2]]
'''

ENTRY_POINTS = """
[palpate.policies]
checkerboard = checker_plugin:Checkerboard

[palpate.classifiers]
plugin_lr = checker_plugin:logistic

[palpate.features]
stiffness = checker_plugin:stiffness
"""


@pytest.fixture
def installed_plugin(tmp_path, monkeypatch):
    """The package installed as pip would lay it out: its module and a dist-info with entry_points.txt."""
    site = tmp_path / "site"
    (site / "checker_plugin").mkdir(parents=True)
    (site / "checker_plugin" / "__init__.py").write_text(textwrap.dedent(PLUGIN))
    info = site / "checker_plugin-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: checker-plugin\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(ENTRY_POINTS)
    monkeypatch.syspath_prepend(str(site))
    importlib.invalidate_caches()
    yield site
    sys.modules.pop("checker_plugin", None)


def _scenario_file(tmp_path, **replace) -> str:
    text = find_scenario(TINY).read_text()
    text = text.replace('policy = "raster"', f'policy = "{replace["policy"]}"')
    text = text.replace("[training]\n", f'[training]\nclassifier = "{replace["classifier"]}"\n'
                                        f'features = "{replace["features"]}"\n')
    path = tmp_path / "plugged.toml"
    path.write_text(text)
    return str(path)


def test_an_installed_plugin_package_runs_a_shipped_scenario(installed_plugin, tmp_path, capsys):
    assert {"checkerboard"} <= set(palpate.available()["policies"])
    scenario = _scenario_file(tmp_path, policy="checkerboard", classifier="plugin_lr", features="stiffness")
    assert main(["run", scenario, "--out", str(tmp_path / "out"), "--quiet"]) == 0
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    algorithms = summary["algorithms"]
    assert {k: algorithms[k] for k in ("policy", "classifier", "features")} == {
        "policy": "checkerboard", "classifier": "plugin_lr", "features": "stiffness"}
    for key, target in (("policy", "Checkerboard"), ("classifier", "logistic"), ("features", "stiffness")):
        assert algorithms["origins"][key] == f"checker-plugin 0.1 (checker_plugin:{target})"
    obj = summary["objects"][0]
    assert obj["policy"] == "checkerboard"
    assert [p["cell"] for p in obj["per_press"]] == [[1, 1], [3, 1], [2, 2]]  # 1-based: the black cells
    memory = json.loads((tmp_path / "out" / "memory.json").read_text())
    assert memory["classifier"] == "plugin_lr" and memory["features"] == "stiffness"
    X = np.array(memory["training"]["X"])
    fitted = sum(f is not None for fits in summary["training"].values() for f in fits)
    assert X.shape == (fitted, 2) and fitted >= 10
    # each map update is the plugin pipeline's posterior for [n1, a1] of the press, refitted here independently
    from sklearn.linear_model import LogisticRegression
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler

    refit = make_pipeline(StandardScaler(), LogisticRegression()).fit(X, memory["training"]["labels"])
    order = [list(refit.classes_).index(m) for m in summary["materials"]]
    for row in obj["per_press"]:
        x = np.array([[row["fit"]["n1"], row["fit"]["a1"]]])
        np.testing.assert_allclose(row["posterior"], refit.predict_proba(x)[0][order], rtol=1e-6)


def test_a_plugin_registered_in_process(tmp_path):
    class Diagonal:
        def __init__(self, context):
            self.k, self.n = 0, min(context.geometry.plane_shape)

        def next_target(self, grid, post=None, last=None):
            self.k += 1
            return palpate.Target(self.k - 1, self.k - 1) if self.k <= self.n else None

    palpate.register_policy("diagonal", Diagonal)
    try:
        with pytest.raises(ValidationError, match="already registered"):
            palpate.register_policy("diagonal", lambda context: None)
        result = palpate.run(palpate.load_scenario(TINY), tmp_path / "out", policy="diagonal",
                             features=lambda r: None if r.fit is None else 2.0 * r.fit.params)
        assert result.summary["algorithms"]["origins"]["policy"] == "registered in process"
        assert result.summary["algorithms"]["features"] == "<lambda>"
        obj = result.summary["objects"][0]
        assert [p["cell"] for p in obj["per_press"]] == [[1, 1], [2, 2]]
        assert obj["stop_reason"] == "policy_exhausted"
    finally:
        palpate.unregister("diagonal")
    with pytest.raises(ValidationError, match="exploration.policy: must be one of predefined, .*info_gain, boundary; "
                                              "got 'diagonal'"):
        palpate.with_settings(palpate.load_scenario(TINY), exploration={"policy": "diagonal"})


def test_registrations_are_checked():
    with pytest.raises(ValidationError, match="'raster' is palpate's own exploration policy"):
        palpate.register_policy("raster", lambda context: None)
    with pytest.raises(ValidationError, match="must be callable"):
        palpate.register_classifier("nothing", None)
    with pytest.raises(ValidationError, match="non-empty string"):
        palpate.register_features(" x", len)


def test_a_policy_choosing_a_cell_off_the_map_is_an_error(tmp_path):
    class OffMap:
        def __init__(self, context):
            pass

        def next_target(self, grid, post=None, last=None):
            return palpate.Target(7, 0)

    palpate.register_policy("off_map", OffMap)
    try:
        with pytest.raises(ValidationError, match=r"'off_map' chose cell \(7, 0\) .* outside the 3 x 2 map"):
            palpate.run(palpate.load_scenario(TINY), tmp_path / "out", policy="off_map")
    finally:
        palpate.unregister("off_map")


def test_a_trained_memory_file_cannot_be_judged_by_a_plugin(tmp_path):
    from sklearn.linear_model import LogisticRegression

    palpate.register_classifier("lr_here", LogisticRegression)
    try:
        with pytest.raises(ValidationError, match="training.memory: a trained memory file is a haptic memory"):
            palpate.with_settings(palpate.load_scenario(TINY),
                                  training={"memory": str(tmp_path / "m.json"), "classifier": "lr_here"})
    finally:
        palpate.unregister("lr_here")
