"""The fine material map under a cell map: a wall inside a cell, read by presses, is drawn where it lies and each
side named by its read modulus; bad input is refused."""

from __future__ import annotations

import numpy as np
import pytest

from palpate.core.boundary.moduli import MaterialModuli, material_moduli
from palpate.core.boundary.reading import NoiseModel, read_boundary
from palpate.core.errors import ValidationError
from palpate.core.mapping.fine import ELONGATION, REACH, REACH_MAX, fine_map, reading_reach, unseen_walls
from palpate.core.mapping.geometry import MapGeometry
from palpate.core.session.boundaries import shipped_templates

DEPTH = 0.004
GAIN = 1.2e-3  # counts per Pa
NOISE = NoiseModel(0.58, 2.0, 255.0)


@pytest.fixture(scope="module")
def templates():
    return shipped_templates()


def _image(templates, soft: float, wall_at: float | None, x0: float, contrast: float) -> np.ndarray:
    """Counts a press at x0 reads beside a wall at x = wall_at (harder side +x), or on one material of modulus
    ``soft`` (Pa) when wall_at is None: the templates themselves, scaled and rounded."""
    wall, plain = templates.at_depth(DEPTH)
    scale = soft / 1e5 * GAIN
    if wall_at is None:
        img = plain
    else:
        o = int(np.argmin(np.abs(templates.offsets - (wall_at - x0))))
        c = int(np.argmin(np.abs(templates.contrasts - contrast)))
        img = wall[int(np.argmin(np.abs(templates.angles))), o, c]
    counts = np.clip(np.rint(img * scale), 0, 255)
    counts[counts <= 2] = 0
    return counts


def test_a_wall_inside_a_cell_is_drawn_where_it_lies(templates):
    soft, hard = 20e3, 120e3
    geometry = MapGeometry("grid2d", ("soft", "hard"), (0.0, 0.0), 0.01, (5, 2))
    # the cell map got the cell astride the wall (20-30 mm, wall at 23 mm) wrong, as a press there feels both
    probs = np.zeros((2, 5, 2))
    probs[:, :2] = [0.9, 0.1]
    probs[:, 2:] = [0.1, 0.9]
    wall_at = 0.023
    readings = []
    for ix in range(5):
        for iy in range(2):
            x0, y0 = 0.005 + 0.01 * ix, 0.005 + 0.01 * iy
            near = abs(wall_at - x0) < 0.007
            img = _image(templates, soft if near or x0 < wall_at else hard, wall_at if near else None, x0, hard / soft)
            readings.append(((x0, y0), read_boundary(img, DEPTH, templates, NOISE)))
    refs = {name: [read_boundary(_image(templates, e, None, 0, 1), DEPTH, templates, NOISE)]
            for name, e in (("soft", soft), ("hard", hard))}
    moduli = material_moduli(refs)
    fine = fine_map(geometry, probs, readings, moduli=moduli)
    x = fine.centres()[..., 0]
    truth = (x > wall_at).astype(int)
    cells = np.argmax(probs, axis=-1).repeat(10, axis=0).repeat(10, axis=1)
    assert np.mean(cells == truth) < 0.95
    assert np.mean(fine.labels() == truth) >= 0.97
    # the drawn wall is within a millimetre of the true one on every row
    first_hard = np.argmax(fine.labels() == 1, axis=1) * fine.resolution
    assert np.all(np.abs(first_hard - wall_at) <= 1.01e-3)
    assert np.allclose(fine.probabilities.sum(axis=-1), 1.0)


def test_moduli_name_a_side_by_the_nearest_reference():
    m = MaterialModuli(("a", "b", "c"), np.log([10.0, 100.0, 1000.0]), np.full(3, 0.2))
    assert np.argmax(m.probabilities(np.log(90.0))) == 1
    p = m.probabilities(np.log(12.0), order=("c", "a", "x"))
    assert np.argmax(p) == 1 and p[2] == 0.0 and p.sum() == pytest.approx(1.0)
    with pytest.raises(ValidationError, match="no reading"):
        material_moduli({"a": []})


def test_bad_maps_are_refused():
    geometry = MapGeometry("grid2d", ("a", "b"), (0.0, 0.0), 0.01, (3, 2))
    with pytest.raises(ValidationError, match="probabilities"):
        fine_map(geometry, np.full((3, 2, 2), 0.5), [])
    with pytest.raises(ValidationError, match="resolution"):
        fine_map(geometry, np.full((2, 3, 2), 0.5), [], resolution=0.02)
    for t in (0.0, -1.0, np.inf, np.nan):
        with pytest.raises(ValidationError, match="temperature"):
            fine_map(geometry, np.full((2, 3, 2), 0.5), [], temperature=t)
    for w in (-0.1, np.inf, np.nan):
        with pytest.raises(ValidationError, match="far_weight"):
            fine_map(geometry, np.full((2, 3, 2), 0.5), [], far_weight=w)
    for lo, hi, k in ((0.006, 0.005, 0.6), (0.006, np.inf, 0.6), (0.006, 0.009, -1.0), (0.006, 0.009, np.nan)):
        with pytest.raises(ValidationError, match="reach_max"):
            fine_map(geometry, np.full((2, 3, 2), 0.5), [], reach=lo, reach_max=hi, spacing=k)
    for spread, start in ((-0.5, 0.006), (np.inf, 0.006), (1.0, -0.001), (1.0, np.nan)):
        with pytest.raises(ValidationError, match="wall_spread"):
            fine_map(geometry, np.full((2, 3, 2), 0.5), [], wall_spread=spread, wall_spread_from=start)
    voxel = MapGeometry("voxel", ("a", "b"), (0.0, 0.0), 0.01, (3, 2, 2), z_top=0.03)
    with pytest.raises(ValidationError, match="2-D"):
        fine_map(voxel, np.full((2, 3, 2), 0.5), [])


def test_a_map_too_large_for_a_millimetre_raster_gets_a_coarser_one_within_the_limit(monkeypatch, templates):
    geometry = MapGeometry("grid2d", ("soft", "hard"), (0.0, 0.0), 0.01, (20, 10))
    probs = np.tile([0.7, 0.3], (10, 20, 1))
    img = _image(templates, 20e3, None, 0.0, 1.0)
    reading = read_boundary(img, DEPTH, templates, NOISE)
    assert fine_map(geometry, probs, [((0.05, 0.05), reading)]).resolution == pytest.approx(1e-3)
    # 200 cells under a limit of 5000 points: 5 points a cell side (2 mm), not 10
    monkeypatch.setenv("PALPATE_LIMITS", "map_cells=5000")
    fine = fine_map(geometry, probs, [((0.05, 0.05), reading)])
    assert fine.resolution == pytest.approx(2e-3) and fine.probabilities.shape == (50, 100, 2)
    assert np.all(fine.labels() == 0) and np.allclose(fine.probabilities.sum(axis=-1), 1.0)
    monkeypatch.setenv("PALPATE_LIMITS", "map_cells=250")
    assert fine_map(geometry, probs, []).resolution == pytest.approx(1e-2)


def _raster(cell: float, nx: int, ny: int, stride: int = 1) -> list:
    return [(((ix + 0.5) * cell, (iy + 0.5) * cell), None) for ix in range(0, nx, stride) for iy in range(ny)]


def test_a_reading_reaches_further_the_farther_apart_the_presses_lie():
    """0.6 of the presses' mean spacing, within 6-9 mm: a raster of 10 mm cells keeps 6 mm (its walls stay sharp),
    one of 12 mm cells 7.2 mm, a third of the 10 mm cells or a raster of 20 mm cells 9 mm."""
    def reach(cell, presses, nx=12, ny=9):
        return reading_reach(MapGeometry("grid2d", ("a", "b"), (0.0, 0.0), cell, (nx, ny)), presses)

    assert reach(0.010, _raster(0.010, 12, 9)) == pytest.approx(REACH)
    assert reach(0.012, _raster(0.012, 12, 9)) == pytest.approx(0.0072)
    assert reach(0.010, _raster(0.010, 12, 9, stride=3)) == pytest.approx(REACH_MAX)
    assert reach(0.020, _raster(0.020, 12, 9)) == pytest.approx(REACH_MAX)
    assert reach(0.010, []) == pytest.approx(REACH_MAX)
    # a place pressed again, or a press at the same millimetre, is one place
    twice = _raster(0.012, 12, 9) + [((x + 2e-4, y), r) for (x, y), r in _raster(0.012, 12, 9)]
    assert reach(0.012, twice) == pytest.approx(0.0072)


def test_a_reading_reaches_only_points_near_its_press_and_that_changes_nothing_visible(templates):
    soft, hard = 20e3, 120e3
    geometry = MapGeometry("grid2d", ("soft", "hard"), (0.0, 0.0), 0.01, (10, 6))
    probs = np.full((6, 10, 2), 0.5)
    probs[:, :3] = [0.9, 0.1]
    probs[:, 3:] = [0.2, 0.8]
    wall_at = 0.027
    readings = []
    for x0 in (0.015, 0.025, 0.035, 0.085):  # the last one far from the wall, beyond the cut-off of the others
        near = abs(wall_at - x0) < 0.007
        img = _image(templates, soft if near or x0 < wall_at else hard, wall_at if near else None, x0, hard / soft)
        readings.append(((x0, 0.031), read_boundary(img, DEPTH, templates, NOISE)))
    moduli = material_moduli({name: [read_boundary(_image(templates, e, None, 0, 1), DEPTH, templates, NOISE)]
                              for name, e in (("soft", soft), ("hard", hard))})
    cut, everywhere = (fine_map(geometry, probs, readings, moduli=moduli, cutoff=c) for c in (5.0, None))
    np.testing.assert_allclose(cut.probabilities, everywhere.probabilities, rtol=0, atol=1e-9)
    assert np.array_equal(cut.labels(), everywhere.labels())
    # the shipped cut-off drops weights below 1e-5, a 5000th of a point's own cell's: none moves by more than 2e-4
    shipped = fine_map(geometry, probs, readings, moduli=moduli)
    np.testing.assert_allclose(shipped.probabilities, everywhere.probabilities, rtol=0, atol=2e-4)
    assert np.array_equal(shipped.labels(), everywhere.labels())
    # a press off the map entirely changes nothing
    off = fine_map(geometry, probs, [*readings, ((0.5, 0.5), readings[0][1])], moduli=moduli)
    np.testing.assert_array_equal(off.probabilities, shipped.probabilities)


def test_the_temperature_sharpens_each_point_without_moving_its_label(templates):
    soft, hard = 20e3, 120e3
    geometry = MapGeometry("grid2d", ("soft", "hard", "none"), (0.0, 0.0), 0.01, (4, 2))
    probs = np.full((2, 4, 3), 0.1)
    probs[:, :2, 0], probs[:, 2:, 1] = 0.8, 0.8
    wall_at = 0.021
    img = _image(templates, soft, wall_at, 0.018, hard / soft)
    readings = [((0.018, 0.01), read_boundary(img, DEPTH, templates, NOISE))]
    plain, sharp = (fine_map(geometry, probs, readings, temperature=t, wall_spread=0.0) for t in (1.0, 0.5))
    assert np.array_equal(plain.labels(), sharp.labels())
    # at temperature 1/2 each point is its mixture squared and renormalised; a point's largest share only grows
    squared = plain.probabilities**2 / np.sum(plain.probabilities**2, axis=-1, keepdims=True)
    np.testing.assert_allclose(sharp.probabilities, squared, rtol=1e-12)
    assert np.all(sharp.probabilities.max(axis=-1) >= plain.probabilities.max(axis=-1) - 1e-12)
    assert np.any(sharp.probabilities.max(axis=-1) > plain.probabilities.max(axis=-1) + 0.05)
    # an extreme temperature stays a distribution (no 0 / 0)
    extreme = fine_map(geometry, probs, readings, temperature=1e-4)
    assert np.all(np.isfinite(extreme.probabilities))
    np.testing.assert_allclose(extreme.probabilities.sum(axis=-1), 1.0)


def _two_presses(templates):
    """An 80 mm strip of 10 mm cells the cell map knows only at its ends, pressed there: soft at 5 mm, hard at 75 mm:
    (geometry, cell probabilities, readings, moduli)."""
    soft, hard = 20e3, 120e3
    geometry = MapGeometry("grid2d", ("soft", "hard"), (0.0, 0.0), 0.01, (8, 1))
    probs = np.full((1, 8, 2), 0.5)  # the cell map knows nothing yet
    probs[0, 0], probs[0, 7] = [0.9, 0.1], [0.1, 0.9]
    readings = [((0.005, 0.005), read_boundary(_image(templates, soft, None, 0, 1), DEPTH, templates, NOISE)),
                ((0.075, 0.005), read_boundary(_image(templates, hard, None, 0, 1), DEPTH, templates, NOISE))]
    moduli = material_moduli({name: [read_boundary(_image(templates, e, None, 0, 1), DEPTH, templates, NOISE)]
                              for name, e in (("soft", soft), ("hard", hard))})
    return geometry, probs, readings, moduli


def test_a_point_no_press_reaches_takes_its_nearest_press_material(templates):
    geometry, probs, readings, moduli = _two_presses(templates)
    near_only, with_far = (fine_map(geometry, probs, readings, moduli=moduli, far_weight=w) for w in (0.0, 0.05))
    x = with_far.centres()[0, :, 0]
    # 30-50 mm from both presses: beyond their reach, the nearest one decides, with little confidence
    middle = (x > 0.030) & (x < 0.050)
    assert np.array_equal(with_far.labels()[0], (x > 0.040).astype(int))
    assert np.all(with_far.probabilities[0, middle].max(axis=-1) < 0.8)
    assert np.allclose(near_only.probabilities[0, (x > 0.035) & (x < 0.045)], 0.5, atol=1e-3)
    # two presses 70 mm apart reach 9 mm: 7-9 mm from the soft one its reading outweighs the unknowing cell more
    # than a 6 mm reach would let it
    fixed = fine_map(geometry, probs, readings, moduli=moduli, reach_max=REACH)
    beside = (x > 0.012) & (x < 0.014)
    assert np.all(with_far.probabilities[0, beside, 0] > fixed.probabilities[0, beside, 0] + 0.02)
    # near the presses the far term changes nothing visible
    assert np.array_equal(near_only.labels()[0, x < 0.015], with_far.labels()[0, x < 0.015])


def test_a_wall_drawn_far_from_every_press_is_placed_only_roughly(templates):
    geometry, probs, readings, moduli = _two_presses(templates)
    sure, rough = (fine_map(geometry, probs, readings, moduli=moduli, wall_spread=w) for w in (0.0, 1.0))
    x = rough.centres()[0, :, 0]
    assert np.array_equal(sure.labels(), rough.labels())
    # the map draws the wall midway, 35 mm from both presses: beside it a point is nearly undecided
    beside = np.abs(x - 0.040) < 0.0015
    assert np.all(rough.labels()[0, x < 0.039] == 0) and np.all(rough.labels()[0, x > 0.041] == 1)
    assert np.all(rough.probabilities[0, beside].max(axis=-1) < 0.55)
    assert np.all(sure.probabilities[0, beside].max(axis=-1) > rough.probabilities[0, beside].max(axis=-1) + 0.05)
    # a point b from the drawn wall, d from its nearest press swaps sides with probability Phi(-b / (d - 7 mm))
    from scipy.special import ndtr

    wall = x[np.argmax(rough.labels()[0] == 1)] - 0.0005  # where the labels change
    k = int(np.argmin(np.abs(x - 0.0305)))  # about 10 mm left of the wall, 25.5 mm right of the soft press
    d = np.hypot(x[k] - 0.005, rough.centres()[0, k, 1] - 0.005)
    f = ndtr(-(wall - x[k]) / (d - 0.007))
    p1, p2 = sure.probabilities[0, k].max(), sure.probabilities[0, k].min()
    assert rough.probabilities[0, k].max() == pytest.approx((1 - f) * p1 + f * p2, rel=1e-9)
    # within 7 mm of a press the readings place walls themselves: nothing changes there
    close = np.min(np.abs(x[:, None] - np.array([0.005, 0.075])), axis=1) <= 0.007
    np.testing.assert_array_equal(rough.probabilities[0, close], sure.probabilities[0, close])
    # a map of one material has no wall to misplace
    one = np.full((1, 8, 2), [0.9, 0.1])
    np.testing.assert_array_equal(unseen_walls(one, rough.centres(), np.array([[0.005, 0.005]]), 1e-3), one)


def test_a_read_wall_goes_on_past_its_press(templates):
    """Along a wall one press read, beside it, that press outweighs one 10 mm off on the wall's far side that felt
    one material for longer than if its reading reached the same way in every direction."""
    soft, hard = 20e3, 120e3
    geometry = MapGeometry("grid2d", ("soft", "hard"), (0.0, 0.0), 0.01, (6, 4))
    probs = np.full((4, 6, 2), 0.5)  # the cell map knows nothing
    wall_at = 0.023
    moduli = material_moduli({name: [read_boundary(_image(templates, e, None, 0, 1), DEPTH, templates, NOISE)]
                              for name, e in (("soft", soft), ("hard", hard))})
    on_wall = read_boundary(_image(templates, soft, wall_at, 0.020, hard / soft), DEPTH, templates, NOISE)
    plain = read_boundary(_image(templates, hard, None, 0.030, 1), DEPTH, templates, NOISE)
    assert on_wall.p_plain < 0.1 and plain.p_plain > 0.9
    readings = [((0.020, 0.005), on_wall), ((0.030, 0.025), plain)]
    stretched, round_ = (fine_map(geometry, probs, readings, moduli=moduli, elongation=e) for e in (ELONGATION, 1.0))
    column = int(0.0215 / stretched.resolution)  # 1.5 mm on the wall's soft side

    def soft_until(fine):  # how far along the wall the soft side reaches, mm from the press
        return int(np.argmax(fine.labels()[:, column] == 1)) - 5

    assert soft_until(round_) >= 9  # a reach of 9 mm (two presses far apart)
    assert soft_until(stretched) >= soft_until(round_) + 2
    # across the wall, near the press that read it, both agree with the truth
    x = stretched.centres()[5, :, 0]
    across = (np.abs(x - wall_at) > 0.0015) & (x < 0.03)
    assert np.array_equal(stretched.labels()[5, across], (x[across] > wall_at).astype(int))
    assert np.array_equal(round_.labels()[5, across], stretched.labels()[5, across])
    for e in (0.5, np.inf, np.nan):
        with pytest.raises(ValidationError, match="elongation"):
            fine_map(geometry, probs, readings, moduli=moduli, elongation=e)
