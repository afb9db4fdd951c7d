"""Haptic memory (seed 000, sec. 6.6 and 6.8.2): Table 6.6 and 6.7 from the shipped per-press data, numerics at
the extremes, bad input, and the JSON file format."""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.stats import multivariate_normal

from palpate.core.errors import NotFittedError, ValidationError
from palpate.core.perception.crossval import leave_one_out
from palpate.core.perception.gaussian import regularise_covariance
from palpate.core.perception.memory import MIN_SAMPLES, HapticMemory
from palpate.core.perception.params_table import read_params_csv

MATERIALS = ["Material_1", "Material_2", "Material_3"]

# Table 6.6 of seed 000, as printed (1 decimal).
TABLE_6_6 = {
    "Material_1": dict(mu_N=(75.2, 13.9), S_N=((117.4, -3.5), (-3.5, 42.5)),
                       mu_A=(3.0, 12.5), S_A=((0.1, -1.1), (-1.1, 38.1))),
    "Material_2": dict(mu_N=(432.6, 9.6), S_N=((24042.6, -1626.1), (-1626.1, 356.2)),
                       mu_A=(2.9, 3.5), S_A=((0.2, -2.4), (-2.4, 44.9))),
    "Material_3": dict(mu_N=(1638.3, -2.7), S_N=((396276.5, -32354.7), (-32354.7, 6959.4)),
                       mu_A=(10.9, -69.7), S_A=((0.8, -20.2), (-20.2, 554.2))),
}
# Table 6.7 as printed.
TABLE_6_7 = np.array([[0.82, 0.18, 0.00], [0.00, 1.00, 0.00], [0.00, 0.00, 1.00]])
HALF_UNIT = 0.05  # every number in Tables 6.3-6.6 is rounded to 0.1


THESIS_CSV = Path(__file__).resolve().parent.parent / "models" / "realism" / "seed000_tables_6_3_to_6_5.csv"


@pytest.fixture(scope="module")
def thesis():
    return read_params_csv(THESIS_CSV)


def _cov_rounding_bound(x: np.ndarray, j: int, k: int) -> float:
    """Largest change of the population covariance entry (j, k) when every input moves by up to HALF_UNIT,
    plus the table's own rounding: first order (1/n) sum(|d_j| + |d_k|) h, second order h^2 (|d delta| <= 2h)."""
    d = x - x.mean(axis=0)
    first = HALF_UNIT * (np.abs(d[:, j]) + np.abs(d[:, k])).mean()
    return first + 4 * HALF_UNIT**2 + HALF_UNIT + 1e-9


def test_csv_transcribes_tables_6_3_to_6_5(thesis):
    params, labels, extra = thesis
    assert params.shape == (30, 4)
    assert labels == [m for m in MATERIALS for _ in range(10)]
    assert extra["run"].tolist() == list(range(1, 11)) * 3
    # Spot checks against the seed text, one row per table (exploration index, n1, n2, Phi_N, a1, a2, Phi_A).
    np.testing.assert_array_equal(params[8], [82.8, -2.8, 2.8, 17.4])
    assert (extra["phi_n"][8], extra["phi_a"][8]) == (2793.3, 3036.6)
    np.testing.assert_array_equal(params[17], [177.2, 38.9, 3.8, -9.7])
    np.testing.assert_array_equal(params[24], [183.6, 213.1, 10.5, -44.2])
    assert extra["phi_n"][24] == 671769.1


def test_table_6_6_reproduced_with_population_covariance(thesis):
    """ddof=0 reproduces every entry of Table 6.6 within the rounding of its inputs, except two printed means
    that the data contradict: Material_3's mu_n1 (1638.3 printed, data 1683.28: two digits swapped) and
    Material_1's mu_a2 (12.5 printed, data 13.46; the a2 variance 38.0 does match, so no single a2 value was
    mis-read: that would move the variance too)."""
    params, labels, _ = thesis
    mem = HapticMemory().fit(params, labels)
    assert mem.ddof == 0
    assert mem.materials == MATERIALS
    np.testing.assert_allclose(mem.prior, [1 / 3] * 3)
    lab = np.array(labels)
    known_typos = {("Material_3", "mu_N", 0): 1683.28, ("Material_1", "mu_A", 1): 13.46}
    for k, name in enumerate(MATERIALS):
        x = params[lab == name]
        table = TABLE_6_6[name]
        assert all(v == 0.0 for v in mem.regularisation[name].values())
        for key, mean in (("mu_N", mem.means_N[k]), ("mu_A", mem.means_A[k])):
            for j in range(2):
                if (name, key, j) in known_typos:
                    assert mean[j] == pytest.approx(known_typos[(name, key, j)], abs=1e-9)
                    assert abs(mean[j] - table[key][j]) > 0.9
                else:
                    assert abs(mean[j] - table[key][j]) <= 2 * HALF_UNIT + 1e-9, (name, key, j)
        for key, cov, cols in (("S_N", mem.covs_N[k], (0, 1)), ("S_A", mem.covs_A[k], (2, 3))):
            for j in range(2):
                for i in range(2):
                    bound = _cov_rounding_bound(x, cols[j], cols[i])
                    assert abs(cov[j, i] - table[key][j][i]) <= bound, (name, key, j, i, cov[j, i], bound)


def test_table_6_6_is_not_the_sample_covariance(thesis):
    params, labels, _ = thesis
    mem = HapticMemory(ddof=1).fit(params, labels)
    x = params[np.array(labels) == "Material_1"]
    # 130.7 against the printed 117.4: 10/9 of the population variance, far outside input rounding.
    assert abs(mem.covs_N[0, 0, 0] - 117.4) > 5 * _cov_rounding_bound(x, 0, 0)
    np.testing.assert_allclose(mem.covs_N[0], np.cov(x[:, :2].T, ddof=1), rtol=1e-12)


def test_table_6_7_leave_one_out(thesis):
    """Table 6.7's 0.82/0.18 is not a MAP count fraction (10 presses give multiples of 0.1): the MAP confusion
    is 0.8/0.2 with either estimator. It is the *mean leave-one-out posterior* with the sample covariance
    (ddof=1, MATLAB's cov default): 0.819/0.181. With ddof=0 (which Table 6.6 uses) it is 0.809/0.191."""
    params, labels, _ = thesis
    expected_map = np.array([[0.8, 0.2, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    for ddof in (0, 1):
        cv = leave_one_out(params, labels, ddof=ddof)
        assert cv.materials == MATERIALS
        np.testing.assert_array_equal(cv.counts, expected_map * 10)
        np.testing.assert_allclose(cv.confusion, expected_map)
        np.testing.assert_allclose(cv.mean_posterior.sum(axis=1), 1.0)
        assert not np.allclose(cv.confusion, TABLE_6_7, atol=0.005)
    cv1 = leave_one_out(params, labels, ddof=1)
    np.testing.assert_allclose(cv1.mean_posterior, TABLE_6_7, atol=0.005)
    cv0 = leave_one_out(params, labels, ddof=0)
    assert abs(cv0.mean_posterior[0, 0] - 0.82) > 0.005
    # The two Material_1 presses taken for Material_2: run 8 (n1 = 102.4) and run 9 (n2 = -2.8).
    wrong = np.flatnonzero(cv1.predicted != cv1.truth)
    assert wrong.tolist() == [7, 8]
    assert cv1.accuracy == pytest.approx(28 / 30)
    np.testing.assert_allclose(cv1.per_material_accuracy, [0.8, 1.0, 1.0])


def test_leave_one_out_holds_out_only_one_press(thesis):
    """The held-out press's own material is learned from the other 9, the other materials from all 10."""
    params, labels, _ = thesis
    cv = leave_one_out(params, labels)
    keep = np.arange(30) != 3
    mem = HapticMemory().fit(params[keep], [lab for lab, k in zip(labels, keep, strict=True) if k])
    np.testing.assert_allclose(cv.posteriors[3], mem.predict_proba(params[3])[0], rtol=1e-12)
    full = HapticMemory().fit(params, labels)
    np.testing.assert_allclose(mem.covs_N[1:], full.covs_N[1:], rtol=0)


def test_log_likelihood_matches_scipy(thesis, rng):
    params, labels, _ = thesis
    mem = HapticMemory().fit(params, labels)
    x = params[rng.choice(30, 7)] + rng.normal(0, 5, (7, 4))
    ll = mem.log_likelihood(x)
    for k in range(3):
        ref = multivariate_normal(mem.means_N[k], mem.covs_N[k]).logpdf(x[:, :2]) + multivariate_normal(
            mem.means_A[k], mem.covs_A[k]
        ).logpdf(x[:, 2:])
        np.testing.assert_allclose(ll[:, k], ref, rtol=1e-10)
    # eq. 6.11 with a non-uniform prior, straight in linear space where it does not underflow
    prior = np.array([0.5, 0.3, 0.2])
    mem2 = HapticMemory(prior=prior).fit(params, labels)
    joint = np.exp(ll) * prior
    ok = joint.sum(axis=1) > 1e-250
    np.testing.assert_allclose(mem2.predict_proba(x)[ok], (joint / joint.sum(axis=1, keepdims=True))[ok], rtol=1e-9)


def test_prior_as_mapping_and_zero_prior(thesis):
    params, labels, _ = thesis
    mem = HapticMemory(prior={"Material_1": 0.0, "Material_2": 1.0, "Material_3": 1.0}).fit(params, labels)
    np.testing.assert_allclose(mem.prior, [0.0, 0.5, 0.5])
    p = mem.predict_proba(params[:10])
    assert np.all(p[:, 0] == 0.0) and np.all(np.isfinite(p))
    assert mem.predict(params[:1]) == ["Material_2"]
    with pytest.raises(ValidationError, match="Material_9"):
        HapticMemory(prior={"Material_9": 1.0}).fit(params, labels)
    with pytest.raises(ValidationError, match="prior has 2 values"):
        HapticMemory(prior=[1, 1]).fit(params, labels)
    with pytest.raises(ValidationError, match="prior must be finite"):
        HapticMemory(prior=[1, -1, 1]).fit(params, labels)


@settings(max_examples=40, deadline=None)
@given(
    direction=st.lists(st.floats(-1, 1, allow_nan=False), min_size=4, max_size=4).filter(
        lambda v: np.linalg.norm(v) > 0.1
    ),
    magnitude=st.sampled_from([1e3, 1e6, 1e12, 1e30, 1e99]),
)
def test_posterior_finite_and_normalised_far_from_every_mean(direction, magnitude):
    params, labels, _ = read_params_csv(THESIS_CSV)
    mem = _memory_cache(params, labels)
    x = np.array(direction)[None, :] / np.linalg.norm(direction) * magnitude
    p = mem.predict_proba(x)
    assert np.all(np.isfinite(p)) and np.all(p >= 0)
    assert p.sum() == pytest.approx(1.0, abs=1e-12)
    assert np.all(np.isfinite(mem.log_likelihood(x)))


def test_posterior_1e12_away_is_decided_not_nan(thesis):
    params, labels, _ = thesis
    mem = HapticMemory().fit(params, labels)
    x = np.tile(mem.means_N.mean(axis=0).tolist() + mem.means_A.mean(axis=0).tolist(), (3, 1)) + np.array(
        [[1e12, 0, 0, 0], [0, -1e12, 0, 0], [0, 0, 0, 1e12]]
    )
    p = mem.predict_proba(x)
    np.testing.assert_allclose(p.sum(axis=1), 1.0)
    # far along n1 the widest n1 Gaussian (Material_3) explains the press best
    assert mem.predict(x[:1]) == ["Material_3"]
    # the naive linear-space formula underflows to 0/0 here
    with np.errstate(all="ignore"):
        naive = np.exp(mem.log_likelihood(x))
        assert np.all(naive == 0.0)


def test_regularisation_of_collinear_presses(rng):
    """Three presses on a line give a singular covariance; the loading makes it well conditioned relative to
    each dimension's scale (n1 in the thousands, n2 in the units) and is reported."""
    t = np.array([0.0, 1.0, 2.0])
    a = np.column_stack([1000 + 300 * t, 5 - 2 * t, 3 + 0.1 * t, 10 + t])  # exactly collinear in N and in A
    b = rng.normal([50, 5, 3, 10], [10, 2, 0.3, 4], (5, 4))
    mem = HapticMemory(min_eig=1e-4).fit(np.vstack([a, b]), ["line"] * 3 + ["blob"] * 5)
    assert mem.regularisation["line"]["N"] > 0 and mem.regularisation["line"]["A"] > 0
    assert mem.regularisation["blob"] == {"N": 0.0, "A": 0.0}
    for cov in (mem.covs_N[0], mem.covs_A[0]):
        s = np.sqrt(np.diag(cov))
        e = np.linalg.eigvalsh(cov / np.outer(s, s))
        assert e[0] / e[-1] >= 1e-4 * (1 - 1e-6)
        assert e[0] / e[-1] <= 1.5e-4  # the smallest loading, not a blanket one
    p = mem.predict_proba(np.vstack([a, b]))
    assert np.all(np.isfinite(p))
    assert mem.predict(a) == ["line"] * 3


def test_regularise_covariance_constant_column_uses_fallback_scale():
    cov = np.array([[4.0, 0.0], [0.0, 0.0]])
    out, lam = regularise_covariance(cov, 1e-6, fallback_var=np.array([1.0, 9.0]))
    assert lam > 0
    np.testing.assert_allclose(out[1, 1], lam * 9.0)
    np.testing.assert_allclose(out[0, 0], 4.0 * (1 + lam))
    with pytest.raises(ValidationError, match="constant"):
        regularise_covariance(cov, 1e-6, fallback_var=np.array([1.0, 0.0]))


def test_identical_presses_still_give_a_usable_memory():
    """A deterministic simulation can press a material identically every time: zero covariance."""
    x = np.vstack([np.tile([100.0, 5.0, 3.0, 10.0], (4, 1)), np.tile([400.0, -5.0, 2.0, 4.0], (4, 1))])
    mem = HapticMemory().fit(x, ["soft"] * 4 + ["hard"] * 4)
    assert mem.regularisation["soft"] == {"N": mem.min_eig, "A": mem.min_eig}
    np.testing.assert_allclose(np.diag(mem.covs_N[0]), mem.min_eig * x[:, :2].var(axis=0))
    p = mem.predict_proba(x + 1.0)
    assert np.all(np.isfinite(p))
    assert mem.predict(x) == ["soft"] * 4 + ["hard"] * 4


def test_fit_presses_takes_objects_with_params(thesis):
    params, labels, _ = thesis
    fits = [SimpleNamespace(params=p) for p in params]
    a = HapticMemory().fit_presses(fits, labels)
    b = HapticMemory().fit(params, labels)
    np.testing.assert_array_equal(a.covs_A, b.covs_A)
    with pytest.raises(ValidationError, match=r"fits\[2\].*no .params"):
        HapticMemory().fit_presses(fits[:2] + [object()], labels[:3])
    with pytest.raises(ValidationError, match=r"fits\[0\].params has 3 values"):
        HapticMemory().fit_presses([SimpleNamespace(params=[1, 2, 3])], ["x"])


def test_from_table_path_and_rows(thesis):
    params, labels, _ = thesis
    a = HapticMemory.from_table(THESIS_CSV, ddof=1)
    rows = [dict(material=lab, n1=p[0], n2=p[1], a1=p[2], a2=p[3]) for p, lab in zip(params, labels, strict=True)]
    b = HapticMemory.from_table(rows, ddof=1)
    np.testing.assert_array_equal(a.covs_N, b.covs_N)
    assert a.ddof == 1
    with pytest.raises(ValidationError, match=r"row 1 lacks key\(s\) \['a2'\]"):
        HapticMemory.from_table([rows[0], {"material": "x", "n1": 1, "n2": 2, "a1": 3}])


# ---- bad input ------------------------------------------------------------------------------------------------


_CACHE: dict = {}


def _memory_cache(params, labels) -> HapticMemory:
    if "m" not in _CACHE:
        _CACHE["m"] = HapticMemory().fit(params, labels)
    return _CACHE["m"]


@settings(max_examples=40, deadline=None)
@given(
    row=st.integers(0, 29),
    col=st.integers(0, 3),
    bad=st.sampled_from([np.nan, np.inf, -np.inf, 1e300]),
    where=st.sampled_from(["fit", "predict", "predict_proba", "log_likelihood"]),
)
def test_non_finite_input_rejected_naming_row_and_column(row, col, bad, where):
    params, labels, _ = read_params_csv(THESIS_CSV)
    x = params.copy()
    x[row, col] = bad
    names = ["n1", "n2", "a1", "a2"]
    with pytest.raises(ValidationError, match=rf"params\[{row}\] column '{names[col]}'"):
        if where == "fit":
            HapticMemory().fit(x, labels)
        else:
            getattr(_memory_cache(params, labels), where)(x)


@settings(max_examples=30, deadline=None)
@given(shape=st.sampled_from([(30,), (30, 3), (30, 5), (2, 15, 4), (0, 4), (4, 30)]))
def test_wrong_shape_rejected(shape):
    params, labels, _ = read_params_csv(THESIS_CSV)
    mem = _memory_cache(params, labels)
    x = np.ones(shape)
    with pytest.raises(ValidationError, match=r"shape|empty"):
        mem.predict_proba(x)
    with pytest.raises(ValidationError, match=r"shape|empty|labels has"):
        HapticMemory().fit(x, labels)


@settings(max_examples=30, deadline=None)
@given(name=st.text(min_size=1, max_size=12).filter(lambda s: s.strip() and s.strip() not in MATERIALS))
def test_unknown_material_rejected(name):
    params, labels, _ = read_params_csv(THESIS_CSV)
    mem = _memory_cache(params, labels)
    bad = list(labels)
    bad[4] = name
    with pytest.raises(ValidationError, match=r"labels\[4\].*not a material"):
        mem.score(params, bad)
    with pytest.raises(ValidationError, match="not in materials"):
        HapticMemory(materials=MATERIALS).fit(params, bad)


def test_bad_labels_and_settings(thesis):
    params, labels, _ = thesis
    with pytest.raises(ValidationError, match="labels has 29 entries but params has 30 rows"):
        HapticMemory().fit(params, labels[:-1])
    with pytest.raises(ValidationError, match=r"labels\[0\] is ''"):
        HapticMemory().fit(params, [""] + labels[1:])
    with pytest.raises(ValidationError, match="not a single string"):
        HapticMemory().fit(params[:1], "Material_1")
    # scikit-learn's convention: the constructor stores settings, fit() validates them.
    with pytest.raises(ValidationError, match="ddof must be 0"):
        HapticMemory(ddof=2).fit(params, labels)
    with pytest.raises(ValidationError, match="min_eig"):
        HapticMemory(min_eig=0.0).fit(params, labels)
    with pytest.raises(ValidationError, match="duplicate"):
        HapticMemory(materials=["a", "a"]).fit(params, labels)
    with pytest.raises(NotFittedError, match="not trained"):
        HapticMemory().predict(params)


def test_too_few_presses_per_material(thesis):
    params, labels, _ = thesis
    keep = [i for i in range(30) if labels[i] != "Material_2" or i < 10 + MIN_SAMPLES - 1]
    with pytest.raises(ValidationError, match=rf"'Material_2' has {MIN_SAMPLES - 1} press"):
        HapticMemory().fit(params[keep], [labels[i] for i in keep])
    keep = [i for i in range(30) if labels[i] != "Material_2" or i < 10 + MIN_SAMPLES]
    HapticMemory().fit(params[keep], [labels[i] for i in keep])  # enough to train...
    with pytest.raises(ValidationError, match=r"leave-one-out needs at least"):
        leave_one_out(params[keep], [labels[i] for i in keep])  # ...not to hold one out
    with pytest.raises(ValidationError, match="'Material_4' has 0 press"):
        HapticMemory(materials=MATERIALS + ["Material_4"]).fit(params, labels)


# ---- JSON ------------------------------------------------------------------------------------------------------


def test_save_load_round_trip_is_exact(thesis, tmp_path, rng):
    params, labels, _ = thesis
    mem = HapticMemory(prior=[0.2, 0.3, 0.5], ddof=1).fit(params + rng.normal(0, 1e-3, params.shape), labels)
    path = tmp_path / "memory.json"
    mem.save(path)
    back = HapticMemory.load(path)
    for key in ("prior", "means_N", "covs_N", "means_A", "covs_A", "training_params"):
        np.testing.assert_array_equal(getattr(back, key), getattr(mem, key))
    assert (back.materials, back.ddof, back.min_eig) == (mem.materials, mem.ddof, mem.min_eig)
    assert back.training_labels == labels and back.regularisation == mem.regularisation
    x = rng.normal(0, 300, (20, 4))
    np.testing.assert_array_equal(back.predict_proba(x), mem.predict_proba(x))
    doc = json.loads(path.read_text())
    assert doc["format"] == "palpate.haptic_memory" and doc["version"] == 1
    assert not path.read_bytes().startswith(b"\x80")  # JSON text, never a pickle


def _corrupt(doc, key_path, value):
    d = doc
    for k in key_path[:-1]:
        d = d[k]
    if value is KeyError:
        del d[key_path[-1]]
    else:
        d[key_path[-1]] = value


@pytest.mark.parametrize(
    "key_path, value, message",
    [
        (("version",), 3, "key 'version' is 3"),
        (("format",), "something", "key 'format'"),
        (("materials",), KeyError, "missing key 'materials'"),
        (("covs_N",), KeyError, "missing key 'covs_N'"),
        (("means_A",), [[1.0, 2.0]], r"key 'means_A' has shape \(1, 2\), expected \(3, 2\)"),
        (("covs_A", 1, 0, 0), -5.0, r"key 'covs_A' \[Material_2\] is not positive definite"),
        (("covs_N", 0, 0, 1), 1.0, r"key 'covs_N' \[Material_1\] is not symmetric"),
        (("prior",), [0.5, 0.5, 0.5], "key 'prior' must be >= 0 and sum to 1"),
        (("ddof",), 3, "key 'ddof' is 3"),
        (("regularisation", "Material_3"), KeyError, "key 'regularisation'"),
        (("training", "labels", 0), "Material_7", r"key 'training.labels' names \['Material_7'\]"),
        (("training", "params"), [[1, 2, 3, 4]], r"key 'training.params' has shape"),
        (("means_N", 0, 0), 76.0, "key 'means_N' does not match a re-fit of key 'training'"),
    ],
)
def test_load_corrupted_json_names_the_key(thesis, tmp_path, key_path, value, message):
    params, labels, _ = thesis
    doc = HapticMemory().fit(params, labels).to_dict()
    _corrupt(doc, key_path, value)
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(ValidationError, match=message) as info:
        HapticMemory.load(path)
    assert str(path) in str(info.value)


def test_load_rejects_non_json_nan_and_missing_file(thesis, tmp_path):
    params, labels, _ = thesis
    text = HapticMemory().fit(params, labels).to_json()
    path = tmp_path / "m.json"
    path.write_text(text.replace('"min_eig": 1e-06', '"min_eig": NaN'))
    with pytest.raises(ValidationError, match="NaN"):
        HapticMemory.load(path)
    path.write_text(text[: len(text) // 2])
    with pytest.raises(ValidationError, match=r"m.json:\d+: not valid JSON"):
        HapticMemory.load(path)
    with pytest.raises(ValidationError, match="cannot read"):
        HapticMemory.load(tmp_path / "absent.json")
    # audit=False accepts hand-edited parameters that still form a valid memory
    doc = json.loads(text)
    doc["means_N"][0][0] = 76.0
    path.write_text(json.dumps(doc))
    assert HapticMemory.load(path, audit=False).means_N[0, 0] == 76.0


# ---- CSV --------------------------------------------------------------------------------------------------------


def _write(tmp_path, text, name="params.csv"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_csv_any_column_order_comments_and_extra_columns(tmp_path):
    p = _write(tmp_path, "# per-press fits\nA2, note ,material,a1,n2,n1\n4,x,foam,3,2,1\n\n8,y,foam,7,6,5\n")
    params, labels, extra = read_params_csv(p)
    np.testing.assert_array_equal(params, [[1, 2, 3, 4], [5, 6, 7, 8]])
    assert labels == ["foam", "foam"]
    assert extra["note"].tolist() == ["x", "y"]


@pytest.mark.parametrize(
    "text, message",
    [
        ("material,n1,n2,a1,a2\nfoam,1,2,3,4\nfoam,1,2,abc,4\n", r"params.csv:3: column 'a1': 'abc' is not a number"),
        ("material,n1,n2,a1,a2\n\n\nfoam,1,2,3,nan\n", r"params.csv:4: column 'a2': 'nan' is not a finite number"),
        ("material,n1,n2,a1,a2\nfoam,1,2,3\n", r"params.csv:2: has 4 fields, expected 5"),
        ("material,n1,n2,a1\nfoam,1,2,3\n", r"params.csv:1: header lacks column\(s\) 'a2'"),
        ("material,n1,n2,a1,a2,n1\n", r"params.csv:1: header repeats column\(s\) \['n1'\]"),
        ("material,n1,n2,a1,a2\n", "header only"),
        ("", "empty"),
        ("material,n1,n2,a1,a2\n ,1,2,3,4\n", r"params.csv:2: column 'material': empty"),
    ],
)
def test_csv_errors_name_file_line_and_column(tmp_path, text, message):
    with pytest.raises(ValidationError, match=message):
        read_params_csv(_write(tmp_path, text))


def test_csv_not_utf8_or_missing(tmp_path):
    p = tmp_path / "params.csv"
    p.write_bytes(b"material,n1,n2,a1,a2\n\xff\xfe,1,2,3,4\n")
    with pytest.raises(ValidationError, match="not UTF-8"):
        read_params_csv(p)
    with pytest.raises(ValidationError, match="cannot read"):
        read_params_csv(tmp_path / "nope.csv")
