"""palpate's classifiers are scikit-learn estimators (clone, cross_val_score, Pipeline, GridSearchCV), checked with
scikit-learn itself; and any scikit-learn classifier can judge the presses of a run."""

from __future__ import annotations

import inspect
import json

import numpy as np
import pytest
from sklearn.base import clone, is_classifier
from sklearn.linear_model import LogisticRegression
from sklearn.model_selection import GridSearchCV, LeaveOneOut, StratifiedKFold, cross_val_predict, cross_val_score
from sklearn.pipeline import make_pipeline
from sklearn.preprocessing import StandardScaler

import palpate
from palpate.core.errors import NotFittedError, ValidationError
from palpate.core.perception.classifier_memory import ClassifierMemory
from palpate.core.perception.crossval import leave_one_out
from palpate.core.perception.layered_estimator import LayeredMemoryClassifier
from palpate.core.perception.memory import HapticMemory

TINY = "sweeps/tiny_base"


def _two_materials(n: int = 12, seed: int = 0):
    rng = np.random.default_rng(seed)
    x = np.vstack([rng.normal([10.0, 1.0, 2e-4, 1e-5], [1.0, 0.5, 3e-5, 4e-6], (n, 4)),
                   rng.normal([13.0, 0.0, 2.6e-4, 2e-5], [1.0, 0.5, 3e-5, 4e-6], (n, 4))])
    return x, ["soft"] * n + ["hard"] * n


@pytest.mark.parametrize("estimator", [HapticMemory(ddof=1, prior=[0.3, 0.7]), LayeredMemoryClassifier(cell=0.001),
                                       ClassifierMemory(LogisticRegression(C=2.0), name="lr")])
def test_parameters_are_the_constructors_and_clone_rebuilds_them(estimator):
    params = estimator.get_params(deep=False)
    assert list(params) == list(inspect.signature(type(estimator)).parameters)
    twin = clone(estimator)
    assert type(twin) is type(estimator) and twin is not estimator
    assert repr(twin.get_params(deep=False)) == repr(params)
    assert is_classifier(estimator) and not estimator.fitted and not hasattr(estimator, "classes_")
    with pytest.raises(ValidationError, match="has no parameter 'nope'"):
        clone(estimator).set_params(nope=1)


def test_set_params_reaches_a_wrapped_estimator():
    memory = ClassifierMemory(LogisticRegression())
    assert memory.get_params()["estimator__C"] == 1.0
    memory.set_params(estimator__C=0.5, name="lr")
    assert memory.estimator.C == 0.5 and memory.label == "lr"
    assert clone(memory).estimator.C == 0.5 and clone(memory).estimator is not memory.estimator


def test_a_fitted_memory_clones_unfitted_and_keeps_its_settings():
    x, y = _two_materials()
    memory = HapticMemory(ddof=1).fit(x, y)
    assert list(memory.classes_) == ["soft", "hard"]
    twin = clone(memory)
    assert not twin.fitted and twin.ddof == 1
    with pytest.raises(NotFittedError):
        twin.predict_proba(x)
    assert memory.get_params()["ddof"] == 1  # fit changed no setting


def test_cross_val_score_is_the_same_folds_by_hand():
    x, y = _two_materials(seed=1)
    folds = StratifiedKFold(4, shuffle=True, random_state=3)
    scores = cross_val_score(HapticMemory(ddof=1), x, y, cv=folds)
    labels = np.asarray(y)
    by_hand = [HapticMemory(ddof=1).fit(x[tr], labels[tr]).score(x[te], labels[te]) for tr, te in folds.split(x, y)]
    np.testing.assert_array_equal(scores, by_hand)


def test_leave_one_out_agrees_with_scikit_learns():
    x, y = _two_materials(n=8, seed=2)
    ours = leave_one_out(x, y, ddof=1)
    theirs = cross_val_predict(HapticMemory(ddof=1), x, y, cv=LeaveOneOut())
    assert list(theirs) == [ours.materials[i] for i in ours.predicted]
    assert cross_val_score(HapticMemory(ddof=1), x, y, cv=LeaveOneOut()).mean() == pytest.approx(ours.accuracy)


def test_pipeline_and_grid_search():
    x, y = _two_materials(seed=4)
    pipe = make_pipeline(StandardScaler(), HapticMemory()).fit(x, y)
    scaled = StandardScaler().fit(x).transform(x)
    np.testing.assert_allclose(pipe.predict_proba(x), HapticMemory().fit(scaled, y).predict_proba(scaled))
    search = GridSearchCV(HapticMemory(), {"ddof": [0, 1], "min_eig": [1e-6, 1e-3]}, cv=3).fit(x, y)
    assert isinstance(search.best_estimator_, HapticMemory) and search.best_estimator_.fitted
    assert set(search.best_params_) == {"ddof", "min_eig"}


def test_classifier_memory_orders_columns_by_material_and_copies_the_estimator():
    x, y = _two_materials(seed=5)
    lr = LogisticRegression()
    memory = ClassifierMemory(lr, materials=["soft", "hard", "foam"]).fit(x, y)
    assert not hasattr(lr, "coef_")  # the estimator given stays unfitted; the fitted copy is estimator_
    reference = LogisticRegression().fit(x, y).predict_proba(x)  # columns in scikit-learn's order: hard, soft
    p = memory.predict_proba(x)
    np.testing.assert_allclose(p[:, 0], reference[:, 1])
    np.testing.assert_allclose(p[:, 1], reference[:, 0])
    assert np.all(p[:, 2] == 0)  # never seen in training
    with pytest.raises(ValidationError, match="X has 3 features per press"):
        memory.predict_proba(x[:, :3])
    with pytest.raises(ValidationError, match=r"has no fit\(\) method"):
        ClassifierMemory(object()).fit(x, y)


def test_classifier_memory_crossval_is_scikit_learns_leave_one_out():
    x, y = _two_materials(n=6, seed=6)
    ours = ClassifierMemory(LogisticRegression()).crossval(x, y)
    theirs = cross_val_predict(LogisticRegression(), x, y, cv=LeaveOneOut(), method="predict_proba")
    np.testing.assert_allclose(ours.posteriors, theirs[:, ::-1], rtol=1e-9)  # ours: soft, hard


def test_layered_memory_classifier_judges_by_the_deepest_layer():
    training = palpate.train_memory(palpate.load_scenario(TINY))  # 2 mm presses: four 0.5 mm layers
    presses = [r for rs in training.presses.values() for r in rs]
    labels = [m for m, rs in training.presses.items() for _ in rs]
    clf = LayeredMemoryClassifier(cell=0.0005, n_layers=4).fit(presses, labels)
    pr = presses[0].press
    deepest = [p for p in clf.layered_.layer_posteriors(pr.t, pr.c_P, pr.c_A, pr.c_D) if p is not None][-1]
    np.testing.assert_allclose(clf.predict_proba(presses[:1])[0], deepest)
    assert clf.score(presses, labels) == 1.0  # 20 kPa against 450 kPa
    scores = cross_val_score(LayeredMemoryClassifier(cell=0.0005, n_layers=4), presses, labels, cv=3)
    assert scores.shape == (3,) and np.all(scores >= 0.5)
    with pytest.raises(ValidationError, match="judges perceived presses"):
        clf.predict_proba(np.zeros((2, 4)))


def test_a_scikit_learn_classifier_judges_a_run(tmp_path):
    scenario = palpate.load_scenario(TINY)
    result = palpate.run(scenario, tmp_path / "lr", classifier=make_pipeline(StandardScaler(), LogisticRegression()))
    assert result.summary["algorithms"] == {"policy": "raster", "classifier": "Pipeline", "features": "power_law",
                                            "origins": {"policy": "palpate", "classifier": "given in Python",
                                                        "features": "given in Python"}}
    memory = json.loads((result.out / "memory.json").read_text())
    assert memory["format"] == "palpate.classifier_memory" and memory["materials"] == ["soft", "hard"]
    # the map's posterior of each press is the pipeline's, refitted here on the stored training data
    X, labels = np.array(memory["training"]["X"]), memory["training"]["labels"]
    refit = make_pipeline(StandardScaler(), LogisticRegression()).fit(X, labels)
    step = result.summary["objects"][0]["per_press"][0]
    params = np.array([step["fit"][k] for k in ("n1", "n2", "a1", "a2")])
    expected = refit.predict_proba(params[None])[0][[list(refit.classes_).index(m) for m in ("soft", "hard")]]
    np.testing.assert_allclose(step["posterior"], expected, rtol=1e-6)
    assert result.summary["crossval"]["accuracy"] == {"soft": 1.0, "hard": 1.0}


@pytest.mark.parametrize("policy", ["info_gain", "boundary"])
def test_a_classifier_cannot_run_where_the_haptic_memory_is_needed(policy, tmp_path):
    scenario = palpate.with_settings(palpate.load_scenario(TINY), exploration={"policy": policy})
    with pytest.raises(ValidationError, match=f"{policy} predicts presses from the haptic memory"):
        palpate.run(scenario, tmp_path / "out", classifier=LogisticRegression())
    assert not (tmp_path / "out").exists()
