"""Lump depth from the press over a spot: the shipped templates read back, a press over a layer or an inclusion of
sizes, depths and contrasts off the templates' grid (the closed-form contact law) read at its depth and as its
material, no lump read where none is, spots carry their lump, and bad templates are refused by name."""

from __future__ import annotations

import json

import numpy as np
import pytest

from palpate.core.boundary.lump_depth import (
    MIN_POINTS,
    TOP_SD_FLOOR,
    LumpEvidence,
    press_curve,
    read_lump_depth,
    reference_curves,
)
from palpate.core.boundary.lump_templates import (
    LUMP_TEMPLATES_FILE,
    lump_templates_from_document,
    read_lump_templates,
)
from palpate.core.boundary.moduli import MaterialModuli
from palpate.core.boundary.reading import BoundaryReading
from palpate.core.errors import ValidationError
from palpate.core.mapping.anomalies import anomaly_report
from palpate.core.mapping.geometry import MapGeometry
from palpate.core.world.resources import models_dir
from palpate.core.world.scene import FingertipSpec, Layer, Material
from palpate.sim.contact.lump_templates import pad_sum
from palpate.sim.reference.sample import AxisInclusion, AxisymmetricSample

TEMPLATES = read_lump_templates(models_dir() / LUMP_TEMPLATES_FILE)
TIP = FingertipSpec()
#: Three references as in the project's scenes (20, 115, 450 kPa): log moduli as a boundary reading gives them,
#: up to an offset (the image's gain), which the contrasts do not see.
MODULI = MaterialModuli(("soft", "medium", "hard"), np.log([20e3, 115e3, 450e3]) + 3.0, np.full(3, 0.15))
GAIN = 0.004  # counts per Pa of a sensel: the curves' ratio must not depend on it


def _curve(sample: AxisymmetricSample) -> np.ndarray:
    return np.log(GAIN * pad_sum(sample, TIP, TEMPLATES.depths))


def _evidence(curves=()) -> LumpEvidence:
    refs = {m: _curve(AxisymmetricSample(bulk=Material(m, e, 0.4), thickness=0.04))
            for m, e in (("soft", 20e3), ("medium", 115e3), ("hard", 450e3))}
    return LumpEvidence(TEMPLATES, refs, tuple(curves))


def test_shipped_templates_cover_the_pad_and_read_back():
    assert TEMPLATES.pad.matches(type(TEMPLATES.pad).of(TIP))
    assert TEMPLATES.log_ratio.shape == (len(TEMPLATES.shapes), len(TEMPLATES.contrasts), len(TEMPLATES.tops),
                                         len(TEMPLATES.depths))
    # a harder deep material raises the pad's reading, a softer one lowers it, a deeper one by less
    hard, soft = TEMPLATES.at_contrast(8.0), TEMPLATES.at_contrast(1 / 8)
    assert np.all(hard[0] > 0) and np.all(soft[0] < 0)
    assert np.all(np.diff(hard[0, :, -1]) < 0) and np.all(np.diff(soft[0, :, -1]) > 0)
    # on a stored contrast the stored table itself; between two, between them
    k = list(TEMPLATES.contrasts).index(4.0)
    np.testing.assert_array_equal(TEMPLATES.at_contrast(4.0), TEMPLATES.log_ratio[:, k])
    mid = TEMPLATES.at_contrast(np.sqrt(8.0))
    lo, hi = np.minimum(TEMPLATES.log_ratio[:, k - 1], TEMPLATES.log_ratio[:, k]), np.maximum(
        TEMPLATES.log_ratio[:, k - 1], TEMPLATES.log_ratio[:, k])
    assert np.all((mid >= lo - 1e-12) & (mid <= hi + 1e-12))
    # beyond the grid clamped on its own side: a contrast of 1.1 is read from harder templates, never softer ones
    np.testing.assert_array_equal(TEMPLATES.at_contrast(1.1), TEMPLATES.at_contrast(2.0))
    for bad in (1.0, 0.0, -2.0, float("nan")):
        with pytest.raises(ValidationError, match="contrast"):
            TEMPLATES.at_contrast(bad)


@pytest.mark.parametrize(("deep", "e_top", "e_deep", "shape", "radius", "top"), [
    ("hard", 115e3, 450e3, "layer", 0.0, 2.3e-3),
    ("medium", 20e3, 115e3, "layer", 0.0, 4.6e-3),
    ("soft", 115e3, 20e3, "layer", 0.0, 1.7e-3),
    ("hard", 20e3, 450e3, "sphere", 10e-3, 2.2e-3),
    ("soft", 450e3, 20e3, "cylinder", 15e-3, 3.3e-3),
])
def test_a_lump_off_the_grid_is_read_at_its_depth_and_as_its_material(deep, e_top, e_deep, shape, radius, top):
    top_name = {20e3: "soft", 115e3: "medium", 450e3: "hard"}[e_top]
    m_top, m_deep = Material("top", e_top, 0.4), Material("deep", e_deep, 0.4)
    if shape == "layer":
        sample = AxisymmetricSample(bulk=m_deep, thickness=0.04, layers=(Layer(m_top, top),))
    else:
        sample = AxisymmetricSample(bulk=m_top, thickness=0.04,
                                    inclusion=AxisInclusion(m_deep, shape, top, radius, 2 * radius))
    lump = read_lump_depth(_curve(sample), top_name, _evidence(), MODULI)
    assert lump is not None and lump.material == deep
    assert lump.top == pytest.approx(top, abs=0.45e-3)
    assert lump.rms < 0.05 < lump.rms_plain
    # its spread covers what one press cannot tell apart (a lump's size against its depth), and no more
    assert TOP_SD_FLOOR <= lump.top_sd < 3e-3 and abs(lump.top - top) <= lump.top_sd
    assert 0.4 < lump.p_material <= 1.0
    if shape == "layer":
        assert lump.shape == "layer"


def test_no_lump_where_the_press_reads_as_its_material_or_too_little_is_known():
    ev = _evidence()
    assert read_lump_depth(ev.references["medium"] + 0.01, "medium", ev, MODULI) is None  # plain fits best
    harder = ev.references["medium"] + 0.5
    assert read_lump_depth(harder, "medium", ev, MODULI, sign="harder") is not None
    assert read_lump_depth(harder, "hard", ev, MODULI, sign="harder") is None  # nothing is harder than hard
    short = harder.copy()
    short[MIN_POINTS - 1:] = np.nan  # a press too shallow to say
    assert read_lump_depth(short, "medium", ev, MODULI) is None
    assert read_lump_depth(harder, "unknown", ev, MODULI) is None
    with pytest.raises(ValidationError, match="one value per template depth"):
        read_lump_depth(harder[:-1], "medium", ev, MODULI)


def test_press_curves_interpolate_the_loading_and_stop_at_the_deepest_point():
    c_d = np.array([0.0, 1e-3, 2e-3, 3e-3])
    c_p = np.array([0.0, 10.0, 30.0, 60.0])
    curve = press_curve(c_d, c_p, [0.5e-3, 1.5e-3, 3e-3, 3.5e-3])
    np.testing.assert_allclose(curve[:3], np.log([5.0, 20.0, 60.0]))
    assert np.isnan(curve[3])  # past the press
    assert np.all(np.isnan(press_curve([1e-3], [5.0], [1e-3])))  # one sample is no curve

    class _R:  # a perceived press, as training hands them over
        class press:
            c_D, c_P = c_d, c_p

    refs = reference_curves({"m": (_R(), _R())}, [1e-3, 4e-3])
    np.testing.assert_allclose(refs["m"][0], np.log(10.0))
    assert np.isnan(refs["m"][1])


def test_a_spot_carries_the_lump_its_strongest_press_reads():
    geometry = MapGeometry("grid2d", ("soft", "medium", "hard"), (0.0, 0.0), 0.01, (5, 5))
    probs = np.zeros((5, 5, 3))
    probs[..., 1] = 1.0  # the map names medium everywhere
    ev0 = _evidence()
    readings, curves = [], []
    for iy in range(5):
        for ix in range(5):
            over = (ix, iy) == (2, 2)
            log_plain = MODULI.log_mean[1] + (1.0 if over else 0.0)
            readings.append(((0.005 + 0.01 * ix, 0.005 + 0.01 * iy), BoundaryReading(
                p_boundary=0.1, angle=0.0, angle_sd=0.1, offset=0.0, offset_sd=1e-3, contrast=2.0, reach=5.5e-3,
                posterior=np.full((1, 1), 0.1), p_plain=0.9, angles=np.zeros(1), offsets=np.zeros(1),
                log_plain=log_plain)))
            layer = AxisymmetricSample(bulk=Material("d", 450e3, 0.4), thickness=0.04,
                                       layers=(Layer(Material("t", 115e3, 0.4), 3e-3),))
            curves.append(_curve(layer) if over else ev0.references["medium"])
    ev = LumpEvidence(TEMPLATES, ev0.references, tuple(curves))
    (spot,) = anomaly_report(geometry, probs, readings, MODULI, lumps=ev)
    assert spot["sign"] == "harder" and spot["lump"]["material"] == "hard"
    assert spot["lump"]["top_m"] == pytest.approx(3e-3, abs=0.6e-3)
    json.dumps(spot)  # summary-ready
    assert "lump" not in anomaly_report(geometry, probs, readings, MODULI)[0]
    with pytest.raises(ValidationError, match="press curves"):
        anomaly_report(geometry, probs, readings, MODULI, lumps=LumpEvidence(TEMPLATES, ev0.references, ()))


def _doc() -> dict:
    return json.loads((models_dir() / LUMP_TEMPLATES_FILE).read_text())


@pytest.mark.parametrize(("edit", "message"), [
    (lambda d: d.update(format="other"), "not a palpate-lump-templates"),
    (lambda d: d.pop("tops"), "needs pad"),
    (lambda d: d.update(contrasts=[1.0] + d["contrasts"][1:]), "none 1|increasing"),
    (lambda d: d.update(tops=d["tops"][::-1]), "increasing"),
    (lambda d: d.update(shapes=["cube"] + d["shapes"][1:]), "shapes"),
    (lambda d: d.update(radii=[0.005] + d["radii"][1:]), "shapes"),
    (lambda d: d.update(depths=d["depths"][:-1]), "log_ratio must have shape"),
    (lambda d: d.update(depths=[float("nan")] + d["depths"][1:]), "finite"),
    (lambda d: d.update(poisson=0.7), "poisson"),
])
def test_bad_templates_are_refused_by_name(edit, message):
    doc = _doc()
    edit(doc)
    with pytest.raises(ValidationError, match=message):
        lump_templates_from_document(doc, "lumps.json")


def test_missing_templates_say_how_to_make_them(tmp_path):
    with pytest.raises(ValidationError, match="benchmarks/lump_templates.py"):
        read_lump_templates(tmp_path / "none.json")
