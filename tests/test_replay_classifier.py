"""Replaying a run whose presses a classifier plugin judged: its memory.json (format palpate.classifier_memory) is
read by load_memory, the plugin found again by name and fitted to the stored rows, and the replay gives the run's
posteriors and maps bit for bit; a plugin that resolves nowhere, or a tampered file, is refused by name."""

from __future__ import annotations

import copy
import json
import tomllib
from pathlib import Path

import numpy as np
import pytest

import palpate
from palpate.core.cli import main
from palpate.core.errors import ValidationError
from palpate.core.mapping.grids import Grid2D
from palpate.core.perception.classifier_memory import ClassifierMemory, classifier_for
from palpate.core.perception.memory import HapticMemory
from palpate.core.perception.memory_loading import check_replayable, classifier_memory_from_dict, load_memory
from palpate.core.session.replay import replay_recording
from palpate.core.world.scenario_file import parse_scenario

pytest.importorskip("sklearn")
from sklearn.discriminant_analysis import LinearDiscriminantAnalysis  # noqa: E402

SMALL = (Path(__file__).parent / "test_run.py").read_text().split('SMALL = """', 1)[1].split('"""', 1)[0]
V1_MEMORY = Path(__file__).parent / "data" / "recording_v1" / "memory.json"
CLASSIFIER = "lda_test"


@pytest.fixture(scope="module")
def lda_run(tmp_path_factory):
    """The small scenario run with its presses judged by LDA, registered in process for this module only."""
    from palpate.core.session.run import run_scenario

    palpate.register_classifier(CLASSIFIER, LinearDiscriminantAnalysis)
    try:
        out = tmp_path_factory.mktemp("run")
        raw = tomllib.loads(SMALL)
        raw["outputs"] = {"render_3d": False, "haptic_material": False, "figures": False}
        raw["training"]["classifier"] = CLASSIFIER
        summary = run_scenario(parse_scenario(raw, "small.toml"), out, record=out / "run.mcap")
        yield summary, out
    finally:
        palpate.unregister(CLASSIFIER)


def _posteriors(summary: dict) -> list:
    return [[row["posterior"] for row in obj["per_press"]] for obj in summary["objects"]]


def _same_maps(run_out: Path, replay_out: Path, summary: dict) -> None:
    for obj in summary["objects"]:
        for name in (obj["name"], f"{obj['name']}_postprocessed"):
            ran, replayed = Grid2D.load(run_out / "maps" / f"{name}.npz"), Grid2D.load(replay_out / "maps" /
                                                                                       f"{name}.npz")
            np.testing.assert_array_equal(replayed.probabilities, ran.probabilities)
            np.testing.assert_array_equal(replayed.explored, ran.explored)


def _tampered(out: Path, tmp_path: Path, edit) -> Path:
    doc = json.loads((out / "memory.json").read_text())
    edit(doc)
    path = tmp_path / "memory.json"
    path.write_text(json.dumps(doc))
    return path


def test_the_run_was_judged_by_the_plugin(lda_run):
    summary, out = lda_run
    doc = json.loads((out / "memory.json").read_text())
    assert doc["format"] == "palpate.classifier_memory" and doc["classifier"] == CLASSIFIER
    assert summary["algorithms"]["classifier"] == CLASSIFIER and summary["algorithms"]["features"] == "power_law"
    posts = [p for rows in _posteriors(summary) for p in rows if p is not None]
    assert len(posts) >= 4


def test_cli_replay_gives_the_runs_posteriors_and_maps_bit_for_bit(lda_run, tmp_path):
    summary, out = lda_run
    assert main(["replay", str(out / "run.mcap"), "--memory", str(out / "memory.json"), "--out",
                 str(tmp_path / "replay"), "--no-figures", "--quiet"]) == 0
    replayed = json.loads((tmp_path / "replay" / "summary.json").read_text())
    assert _posteriors(replayed) == _posteriors(summary)  # floats through JSON: exact
    _same_maps(out, tmp_path / "replay", summary)
    assert replayed["algorithms"] == {"classifier": CLASSIFIER, "features": "power_law",
                                      "origins": {"classifier": "registered in process", "features": "palpate"}}
    assert {k: summary["algorithms"][k] for k in ("classifier", "features")} == {
        k: replayed["algorithms"][k] for k in ("classifier", "features")}
    # the posteriors are LDA's on each press's [n1, n2, a1, a2] (not the haptic memory's): fitted here independently
    doc = json.loads((out / "memory.json").read_text())
    lda = LinearDiscriminantAnalysis().fit(np.array(doc["training"]["X"]), doc["training"]["labels"])
    order = [list(lda.classes_).index(m) for m in replayed["materials"]]
    rows = [r for obj in replayed["objects"] for r in obj["per_press"] if r["posterior"] is not None]
    for r in rows:
        x = np.array([[r["fit"][k] for k in ("n1", "n2", "a1", "a2")]])
        np.testing.assert_allclose(r["posterior"], lda.predict_proba(x)[0][order], rtol=1e-9, atol=1e-12)


def test_replay_recording_with_load_memory(lda_run, tmp_path):
    summary, out = lda_run
    memory = load_memory(out / "memory.json")
    assert isinstance(memory, ClassifierMemory) and memory.label == CLASSIFIER
    assert isinstance(memory.estimator_, LinearDiscriminantAnalysis) and memory.features is None
    doc = json.loads((out / "memory.json").read_text())
    assert memory.materials == doc["materials"] and memory.training_labels == doc["training"]["labels"]
    replayed = replay_recording(out / "run.mcap", memory, tmp_path / "replay", figures=False)
    assert _posteriors(replayed) == _posteriors(summary)
    _same_maps(out, tmp_path / "replay", summary)


def test_an_unregistered_classifier_is_named_with_how_to_provide_it(lda_run, tmp_path, capsys):
    _, out = lda_run
    path = _tampered(out, tmp_path, lambda d: d.update(classifier="nowhere_lda"))
    code = main(["replay", str(out / "run.mcap"), "--memory", str(path), "--out", str(tmp_path / "replay"),
                 "--quiet"])
    err = capsys.readouterr().err
    assert code == 2
    assert "'nowhere_lda'" in err and "'palpate.classifiers'" in err and "palpate.register_classifier" in err
    assert not (tmp_path / "replay").exists()  # refused before any output


def test_an_unregistered_feature_extractor_is_named(lda_run, tmp_path):
    _, out = lda_run
    path = _tampered(out, tmp_path, lambda d: d.update(features="nowhere_features"))
    with pytest.raises(ValidationError, match=r"'nowhere_features'.*'palpate\.features'.*palpate\.register_features"):
        load_memory(path)


def _set_x(row: int, col: int, value):
    def edit(doc):
        doc["training"]["X"][row][col] = value
    return edit


@pytest.mark.parametrize("edit, message", [
    (lambda d: d.update(version=2), "key 'version' is 2"),
    (lambda d: d.update(version=True), "key 'version' is True"),
    (lambda d: d["training"]["labels"].__setitem__(3, "granite"), r"'training.labels' names \['granite'\]"),
    (lambda d: d["training"]["X"][2].pop(), "row 2 has 3 values, row 0 has 4"),
    (lambda d: d["training"]["X"].pop(), "must be a list of .* rows"),
    (_set_x(1, 0, "1.0"), "row 1 holds something other than numbers"),
    (lambda d: d.update(materials=["soft", "soft", "hard"]), "'materials' must be a non-empty list of distinct"),
    (lambda d: d.update(format="palpate.pickle"), "key 'format' is 'palpate.pickle'"),
    (lambda d: d.pop("classifier"), "missing key 'classifier'"),
])
def test_a_tampered_classifier_memory_is_refused(lda_run, tmp_path, edit, message):
    _, out = lda_run
    with pytest.raises(ValidationError, match=message):
        load_memory(_tampered(out, tmp_path, edit))


def test_a_non_finite_training_row_is_refused(lda_run, tmp_path):
    _, out = lda_run
    doc = json.loads((out / "memory.json").read_text())
    text = (out / "memory.json").read_text()
    first = repr(doc["training"]["X"][0][0])
    path = tmp_path / "memory.json"
    path.write_text(text.replace(first, "NaN", 1))
    with pytest.raises(ValidationError, match="NaN is not a number JSON allows"):
        load_memory(path)
    nan = copy.deepcopy(doc)
    nan["training"]["X"][5][2] = float("nan")
    with pytest.raises(ValidationError, match=r"'training.X' row 5 is not finite"):
        classifier_memory_from_dict(nan, "memory.json")


def test_a_plugin_that_changed_since_the_run_is_refused_unless_not_audited(lda_run, tmp_path, capsys):
    summary, out = lda_run
    path = _tampered(out, tmp_path, lambda d: d.update(estimator="LinearDiscriminantAnalysis(solver='lsqr')"))
    with pytest.raises(ValidationError, match="key 'estimator'.*--no-audit"):
        load_memory(path)
    assert isinstance(load_memory(path, audit=False), ClassifierMemory)
    assert main(["replay", str(out / "run.mcap"), "--memory", str(path), "--out", str(tmp_path / "r"),
                 "--quiet"]) == 2
    assert "key 'estimator'" in capsys.readouterr().err
    assert main(["replay", str(out / "run.mcap"), "--memory", str(path), "--out", str(tmp_path / "r"),
                 "--quiet", "--no-audit", "--no-figures"]) == 0
    assert _posteriors(json.loads((tmp_path / "r" / "summary.json").read_text())) == _posteriors(summary)


def test_layers_and_voxel_maps_are_refused_for_a_classifier_memory(lda_run, tmp_path, capsys):
    _, out = lda_run
    layers = tmp_path / "layers.json"
    layers.write_text("{}")
    assert main(["replay", str(out / "run.mcap"), "--memory", str(out / "memory.json"), "--out",
                 str(tmp_path / "r"), "--memory-layers", str(layers), "--quiet"]) == 2
    assert "--memory-layers" in capsys.readouterr().err and not (tmp_path / "r").exists()
    memory = load_memory(out / "memory.json")
    with pytest.raises(ValidationError, match=r"voxel map\(s\) \['block'\].*'lda_test' judges 2-D maps only"):
        check_replayable(memory, ["block"], False, "rec.mcap")
    check_replayable(memory, [], False, "rec.mcap")  # 2-D maps: fine
    check_replayable(HapticMemory.load(V1_MEMORY), ["block"], True, "rec.mcap")  # the haptic memory judges voxels


def test_a_haptic_memory_file_still_loads_with_its_audit(tmp_path):
    memory = load_memory(V1_MEMORY)
    assert type(memory) is HapticMemory and memory.materials == ["soft", "medium", "hard"]
    doc = json.loads(V1_MEMORY.read_text())
    doc["means_N"][0][0] *= 1.5
    path = tmp_path / "memory.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(ValidationError, match="key 'means_N' does not match a re-fit"):
        load_memory(path)
    assert type(load_memory(path, audit=False)) is HapticMemory


def test_the_haptic_memory_over_a_registered_feature_extractor_is_rebuilt_as_the_run_built_it(tmp_path):
    """Classifier "haptic_memory" with features of a plugin: the run's memory is a ClassifierMemory around a
    HapticMemory; the file rebuilds it with the extractor under its registered name (not its own ``name``)."""
    def doubled(result):
        return None if result.fit is None else 2.0 * result.fit.params

    doubled.name = "its_own_name"
    palpate.register_features("doubled_test", doubled)
    try:
        materials = ["soft", "hard"]
        ran, origins = classifier_for("haptic_memory", "doubled_test", materials)
        assert origins == {"classifier": "palpate", "features": "registered in process"}
        rng = np.random.default_rng(0)
        X = np.vstack([rng.normal([1, 2, 3, 4], 0.1, (6, 4)), rng.normal([2, 1, 4, 3], 0.1, (6, 4))])
        ran.fit(X, ["soft"] * 6 + ["hard"] * 6)
        ran.save(tmp_path / "memory.json")
        doc = json.loads((tmp_path / "memory.json").read_text())
        assert doc["classifier"] == "haptic_memory" and doc["features"] == "doubled_test"
        again = load_memory(tmp_path / "memory.json")
        assert isinstance(again, ClassifierMemory) and isinstance(again.estimator_, HapticMemory)
        probe = rng.normal([1.5, 1.5, 3.5, 3.5], 0.3, (20, 4))
        np.testing.assert_array_equal(again.predict_proba(probe), ran.predict_proba(probe))

        class Fit:
            params = np.array([1.0, 2.0, 3.0, 4.0])

        class Result:
            fit = Fit()

        np.testing.assert_array_equal(again.press_features(Result()), [2.0, 4.0, 6.0, 8.0])
    finally:
        palpate.unregister("doubled_test")


def test_a_memory_whose_materials_are_in_another_order_is_refused_before_any_output(tmp_path):
    ran = HapticMemory.load(V1_MEMORY)
    shuffled = HapticMemory(list(reversed(ran.materials))).fit(ran.training_params, ran.training_labels)
    with pytest.raises(ValidationError, match=r"map 'slab' was made with materials \['soft', 'medium', 'hard'\]"):
        replay_recording(V1_MEMORY.parent / "run.mcap", shuffled, tmp_path / "out", figures=False)
    assert not (tmp_path / "out").exists()
