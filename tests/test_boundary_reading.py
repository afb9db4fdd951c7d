"""The per-press boundary reading: against the 3-D FE image reference (held-out cases), its symmetries, a simulated
press end to end, and its refusals."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from palpate.core.boundary.press import read_press, yaw_of
from palpate.core.boundary.reading import NoiseModel, read_boundary
from palpate.core.boundary.templates import read_templates, templates_from_document
from palpate.core.errors import ValidationError
from palpate.core.files import decimal_array
from palpate.core.perception.press import perceive_press
from palpate.core.session.boundaries import noise_of, shipped_templates
from palpate.core.session.sources import PressTarget
from palpate.core.world.resources import models_dir
from palpate.core.world.scene import FingertipSpec, Scene, TaxelSensorSpec
from palpate.sim.bem.templates import make_templates
from palpate.sim.bem.wall import load_wall_table
from palpate.sim.source import SimSource
from palpate.sim.validity.boundary_reading import check_readings
from palpate.sim.validity.image_cases import image_cases, wall_case
from palpate.sim.validity.image_reference import load_image_reference, reference_image


@pytest.fixture(scope="module")
def templates():
    return shipped_templates()


@pytest.fixture(scope="module")
def report_checks(templates):
    return check_readings(load_image_reference(), templates, seeds=range(4), depths=(0.003, 0.004),
                          splits=("report",))


def test_held_out_fe_walls_are_located_to_a_millimetre(report_checks):
    walls = [r for r in report_checks if r.family == "wall" and abs(r.offset) <= 0.005]
    assert len(walls) >= 40
    assert all(r.side_right for r in walls), [r.case for r in walls if not r.side_right]
    pos = np.array([r.position_error for r in walls])
    assert np.median(pos) <= 0.6e-3
    assert np.percentile(pos, 90) <= 1.5e-3
    assert max(math.degrees(r.angle_error) for r in walls) <= 20
    # calibrated: the stated offset spread covers the truth about as often as a Gaussian's would
    z = np.array([(r.read_offset - r.offset) / r.offset_sd for r in walls])
    assert 0.55 <= np.mean(np.abs(z) < 1) <= 0.95
    assert np.mean(np.abs(z) < 2) >= 0.75
    assert min(r.p_boundary for r in walls) >= 0.5


def test_one_material_reads_as_no_wall(report_checks, templates):
    blocks = [r for r in report_checks if r.family == "block"]
    assert blocks and max(r.p_boundary for r in blocks) <= 0.2


def _fe_counts(name: str, depth: float, seed: int = 0) -> tuple[np.ndarray, float]:
    from palpate.sim.sensors import taxel_counts
    case = next(c for c in image_cases() if c.name == name)
    image = reference_image(load_image_reference(), case)
    k = int(np.argmin(np.abs(image.depth - depth)))
    return taxel_counts(image.pressure[k], TaxelSensorSpec(), np.random.default_rng(seed)).astype(float), float(
        image.depth[k])


@pytest.mark.parametrize("name", ["wall_20-115kPa_t0_o+2mm_nu0.45", "wall_20-115kPa_t45_o-2mm_nu0.45"])
def test_reading_turns_and_mirrors_with_the_image(templates, name):
    counts, depth = _fe_counts(name, 0.003)
    noise = noise_of(TaxelSensorSpec())
    base = read_boundary(counts, depth, templates, noise)
    # row 0 is the pad's +y: np.rot90 turns the image by +90 deg, [:, ::-1] mirrors x
    turned = read_boundary(np.rot90(counts), depth, templates, noise)
    mirrored = read_boundary(counts[:, ::-1], depth, templates, noise)
    assert abs(math.remainder(turned.angle - base.angle - math.pi / 2, 2 * math.pi)) < 1e-6
    assert abs(math.remainder(mirrored.angle - (math.pi - base.angle), 2 * math.pi)) < 1e-6
    assert turned.offset == pytest.approx(base.offset, abs=1e-9)
    # a yaw turns the output frame only
    yawed = read_boundary(counts, depth, templates, noise, yaw=0.3)
    assert abs(math.remainder(yawed.angle - base.angle - 0.3, 2 * math.pi)) < 1e-6


def test_templates_spread_by_symmetry_match_a_direct_solve():
    tip, walls = FingertipSpec(), load_wall_table()
    kw = dict(depths=(0.003,), offsets=(0.001,), contrasts=(6.0,))
    spread = templates_from_document(make_templates(tip, walls, angles_deg=(30.0,), **kw), "spread")
    direct = make_templates(tip, walls, angles_deg=(0.0, 60.0), **kw)
    direct_wall = decimal_array(direct["wall"], "wall", 6)
    want = direct_wall[0, 1, 0, 0]
    got = spread.wall[0, int(np.argmin(np.abs(spread.angles - math.radians(60)))), 0, 0]
    assert np.abs(got - want).max() <= 0.05 * want.max()
    # and the mirror about the diagonal of 0 deg is 90 deg, exactly
    zero = dict(direct, angles_deg=[0.0], wall=direct_wall[:, :1].tolist())
    full = templates_from_document(zero, "zero")
    at = lambda deg: full.wall[0, int(np.argmin(np.abs(full.angles - math.radians(deg)))), 0, 0]  # noqa: E731
    np.testing.assert_allclose(at(90), np.swapaxes(at(0)[::-1, ::-1], 0, 1))


def test_a_simulated_press_beside_a_wall_is_read_from_its_stream(templates):
    obj = wall_case(20, 115, 0.45, 0, 0.0).object_spec()
    source = SimSource(Scene(objects=(obj,)), fidelity="bem", seed=3)
    noise = noise_of(TaxelSensorSpec())
    for x in (-0.002, 0.001):
        rec = source.press(PressTarget(x, 0.0, depth=0.004))
        res = perceive_press(rec)
        reading = read_press(rec, res, templates, noise)
        assert reading is not None and reading.p_boundary > 0.9
        assert math.cos(reading.angle) > 0.95  # harder side at +x
        # the wall at world x = 0 lies at -x from a press at x
        assert reading.offset == pytest.approx(-res.location[0], abs=1.2e-3)


def test_yaw_of_a_quaternion():
    half = 0.4
    assert yaw_of(np.array([math.cos(half), 0, 0, math.sin(half)])) == pytest.approx(2 * half)


def test_bad_images_and_depths_are_refused(templates):
    noise = NoiseModel(0.6, 2.0, 255.0)
    good = np.full((4, 4), 50.0)
    for image, depth, match in ((np.ones((3, 4)), 0.003, "4x4"), (good * np.nan, 0.003, "finite"),
                                (-good, 0.003, "finite"), (np.zeros((4, 4)), 0.003, "no sensel"),
                                (good, 0.0, "depth"), (good, 0.02, "depth")):
        with pytest.raises(ValidationError, match=match):
            read_boundary(image, depth, templates, noise)
    with pytest.raises(ValidationError, match="noise"):
        NoiseModel(0.0)


def test_a_damaged_templates_file_is_refused(tmp_path):
    doc = json.loads((models_dir() / "boundary_templates.json").read_text())
    for key, value, match in (("format", "other", "not a"), ("offsets", [0.0, 0.0], "increasing"),
                              ("contrasts", [0.5] * 6, "contrasts"), ("plain", [[[1.0]]], "shape")):
        bad = dict(doc, **{key: value})
        path = tmp_path / f"{key}.json"
        path.write_text(json.dumps(bad))
        with pytest.raises(ValidationError, match=match):
            read_templates(path)
    plain = templates_from_document(doc, "shipped").plain
    neg = dict(doc, plain=(-plain - 1).tolist())
    with pytest.raises(ValidationError, match="pressures"):
        templates_from_document(neg, "neg")
    with pytest.raises(ValidationError, match="not found"):
        read_templates(tmp_path / "missing.json")


def test_the_shipped_templates_are_what_the_code_makes():
    doc = json.loads((models_dir() / "boundary_templates.json").read_text())
    offsets, contrasts = [-0.003, 0.0015], [4.0]
    made = make_templates(FingertipSpec(), load_wall_table(), angles_deg=(15.0,), offsets=offsets,
                          contrasts=contrasts)
    assert made["depths"] == doc["depths"]
    a = doc["angles_deg"].index(15.0)
    o = [int(np.argmin(np.abs(np.asarray(doc["offsets"]) - v))) for v in offsets]
    c = doc["contrasts"].index(4.0)
    shipped, ours = (decimal_array(d["wall"], "wall", 6) for d in (doc, made))
    np.testing.assert_allclose(ours[:, 0, :, 0], shipped[:, a][:, o][:, :, c], atol=0.2)
    np.testing.assert_allclose(decimal_array(made["plain"], "plain", 3), decimal_array(doc["plain"], "plain", 3),
                               atol=0.2)
