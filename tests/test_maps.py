"""Probabilistic material maps: seed 001 Tables 2-3, seed 000 eq. 6.15, grid geometry, files."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from palpate.core import mapping as maps
from palpate.core.errors import ValidationError
from palpate.core.mapping.grids import Grid2D, VoxelGrid

# Seed 001 Table 2 (Object_1, one volumetric column, l1 = surface ... l6 = deepest), entropies in log10.
T2_50 = np.array([[0.4137, 0.4077, 0.1786], [0.5133, 0.4862, 0.0005], [0.6471, 0.3529, 0.0000],
                  [0.9285, 0.0715, 0.0000], [0.9990, 0.0010, 0.0000], [0.7314, 0.2686, 0.0000]])
T2_50_H = np.array([0.4510, 0.3027, 0.2918, 0.1118, 0.0033, 0.2527])
T2_100 = np.array([[0.4739, 0.4573, 0.0688], [0.5677, 0.4323, 0.0000], [0.7977, 0.2023, 0.0000],
                   [0.9925, 0.0075, 0.0000], [0.9995, 0.0005, 0.0000], [0.9999, 0.0001, 0.0000]])
T2_100_H = np.array([0.3891, 0.2970, 0.2187, 0.0191, 0.0018, 0.0002])
T2_CONT = np.array([[0.5271, 0.4431, 0.0298], [0.7001, 0.2999, 0.0000], [0.9769, 0.0231, 0.0000],
                    [0.9989, 0.0011, 0.0000], [0.9999, 0.0001, 0.0000], [0.9996, 0.0001, 0.0000]])
T2_CONT_H = np.array([0.3487, 0.2652, 0.0478, 0.0036, 0.0004, 0.0017])
HALF_ULP = 0.5e-4  # the tables print 4 decimals


# ---------------------------------------------------------------------------------------------------------------
# entropy


def test_entropy_closed_forms():
    assert maps.entropy([1 / 3, 1 / 3, 1 / 3]) == pytest.approx(math.log10(3))
    assert maps.entropy([0.5, 0.5], base=2) == pytest.approx(1.0)
    assert maps.entropy([0.25] * 4, base=math.e) == pytest.approx(math.log(4))
    # 0 log 0 = 0: a certain distribution has zero entropy, and no RuntimeWarning is raised.
    with np.errstate(all="raise"):
        assert maps.entropy([1.0, 0.0, 0.0]) == 0.0
    h = maps.entropy(np.array([[0.2, 0.8], [0.8, 0.2]]).T, axis=0)
    assert h.shape == (2,) and h[0] == pytest.approx(h[1])


@pytest.mark.parametrize("bad", [[np.nan, 0.5, 0.5], [-0.1, 0.6, 0.5], [1.5, 0.0, 0.0]])
def test_entropy_rejects_non_probabilities(bad):
    with pytest.raises(ValidationError, match="p must"):
        maps.entropy(bad)


@pytest.mark.parametrize("base", [1.0, 0.0, -2.0, float("nan")])
def test_entropy_rejects_bad_base(base):
    with pytest.raises(ValidationError, match="base"):
        maps.entropy([0.5, 0.5], base=base)


def _entropy_interval(p_rounded: np.ndarray, half: float = HALF_ULP, n: int = 81) -> tuple[float, float]:
    """Range of log10 entropy over all distributions that round to ``p_rounded`` (3 materials)."""
    lo = np.clip(p_rounded - half, 0.0, 1.0)
    hi = np.clip(p_rounded + half, 0.0, 1.0)
    p2, p3 = np.meshgrid(np.linspace(lo[1], hi[1], n), np.linspace(lo[2], hi[2], n))
    p1 = 1.0 - p2 - p3
    ok = (p1 >= lo[0] - 1e-12) & (p1 <= hi[0] + 1e-12)
    if not ok.any():
        return (math.nan, math.nan)
    pts = np.stack([np.clip(p1[ok], 0, 1), p2[ok], p3[ok]], axis=-1)
    h = maps.entropy(pts)
    return float(h.min()), float(h.max())


def test_table2_entropies_match_where_the_table_is_consistent():
    """Every H of seed 001 Table 2 against log10 entropy of the printed probabilities.

    A printed H is consistent when some distribution that rounds to the printed probabilities has an entropy that
    rounds to it. Two of the 18 are not: 50% l3 (0.6471/0.3529 has H = 0.2820, the table says 0.2918) and the
    continuity column's l6 (0.9996/0.0001/0.0000 does not even sum to 1; its H of 0.0017 matches no rounding of
    it). The other sixteen agree, most to the printed digit, the rest within the rounding of tiny probabilities.
    """
    mismatches = set()
    for column, probs, hs in (("50%", T2_50, T2_50_H), ("100%", T2_100, T2_100_H),
                              ("continuity", T2_CONT, T2_CONT_H)):
        for row, (p, h_table) in enumerate(zip(probs, hs, strict=True), start=1):
            h_lo, h_hi = _entropy_interval(p)
            if not (h_lo - HALF_ULP <= h_table <= h_hi + HALF_ULP):
                mismatches.add((column, f"l{row}"))
    assert mismatches == {("50%", "l3"), ("continuity", "l6")}
    assert maps.entropy(T2_50[2]) == pytest.approx(0.2820, abs=HALF_ULP)


def test_table3_unexplored_entropy_is_log10_3():
    assert round(float(maps.entropy(np.full(3, 1 / 3))), 4) == 0.4771


# ---------------------------------------------------------------------------------------------------------------
# seed 001 eq. 3 and eq. 5 against Tables 2 and 3


def test_table3_vertical_extrapolation_of_l3():
    """Table 3: l3 assumed unexplored, filled from l2 and l4 of Table 2's 100% column with weights 1/H.

    (The seed's text says "upper l1 and lower l3"; the numbers are those of l2 and l4, the direct neighbours.)
    With the table's own H (computed by the authors from unrounded probabilities) the result is the table's to
    4 decimals; with H recomputed from the rounded probabilities it is within 1e-4.
    """
    col = T2_100.copy()
    col[2] = 1 / 3
    explored = np.ones(6, dtype=bool)
    explored[2] = False
    before_total = maps.entropy(col).sum()

    out = maps.extrapolate_vertical(col, explored, h=T2_100_H)
    np.testing.assert_array_equal(np.round(out[2], 4), [0.9668, 0.0332, 0.0])
    # H of the printed result is the printed 0.0633; ours (0.06323) differs only by the rounding of p.
    assert round(float(maps.entropy([0.9668, 0.0332, 0.0])), 4) == 0.0633
    assert float(maps.entropy(out[2])) == pytest.approx(0.0633, abs=2 * HALF_ULP)
    np.testing.assert_array_equal(np.delete(out, 2, axis=0), np.delete(col, 2, axis=0))

    out_h = maps.extrapolate_vertical(col, explored)
    np.testing.assert_allclose(out_h[2], [0.9668, 0.0332, 0.0], atol=1e-4)
    assert maps.entropy(out_h).sum() < before_total


def test_table2_continuity_column_l1_to_l5():
    """Eq. 5 from the ORIGINAL 100% values (Jacobi) reproduces Table 2's continuity column for l1..l5.

    Inputs are the printed (rounded) values, so each output is known to +-0.5e-4 from the inputs plus 0.5e-4 of
    printing: agreement within 1e-4 is agreement to the table's precision.
    """
    explored = np.ones(6, dtype=bool)
    out = maps.verify_continuity(T2_100, explored, h=T2_100_H)
    np.testing.assert_allclose(out[:5], T2_CONT[:5], atol=2 * HALF_ULP + 1e-12)
    out_h = maps.verify_continuity(T2_100, explored)
    np.testing.assert_allclose(out_h[:5], T2_CONT[:5], atol=1.5e-4)
    # Entropies of the reproduced column agree with the table's H for l1..l5 too.
    np.testing.assert_allclose(maps.entropy(out[:5]), T2_CONT_H[:5], atol=3e-4)


def test_table2_continuity_is_jacobi_not_sequential():
    """Updating from the top with already-updated lower voxels would not give the table (l1..l4 differ)."""
    seq = T2_100.copy()
    for l in range(4, -1, -1):  # bottom-up sweep reusing updated values
        pair = seq[l : l + 2]
        w = 1 / maps.entropy(pair)
        seq[l] = (w[:, None] * pair).sum(0) / w.sum()
    assert np.abs(seq[:4] - T2_CONT[:4]).max() > 1e-3


def test_table2_continuity_l6_is_inconsistent():
    """l6 is the bottom voxel: eq. 5 has no lower neighbour for it, so it must stay (0.9999, 0.0001, 0.0000).

    The table prints (0.9996, 0.0001, 0.0000): it sums to 0.9997, which no rounding of a distribution can give
    (three values each within 0.5e-4 of a printed digit sum to at most 0.99985), and it is not what eq. 5 gives.
    The table's l6 of that column is a typo or came from data not shown; the code follows eq. 5.
    """
    out = maps.verify_continuity(T2_100, np.ones(6, dtype=bool), h=T2_100_H)
    np.testing.assert_array_equal(out[5], T2_100[5])
    assert T2_CONT[5].sum() + 3 * HALF_ULP < 1.0
    assert abs(out[5, 0] - T2_CONT[5, 0]) > 2 * HALF_ULP


def test_continuity_leaves_unexplored_and_runs_without_lower_neighbour():
    p = np.array([[0.6, 0.4], [0.9, 0.1], [0.5, 0.5], [0.2, 0.8], [0.99, 0.01]])
    explored = np.array([True, True, False, True, False])
    out = maps.verify_continuity(p, explored)
    w = 1 / maps.entropy(p[:2])
    np.testing.assert_allclose(out[0], (w[:, None] * p[:2]).sum(0) / w.sum())
    np.testing.assert_array_equal(out[1:], p[1:])  # l2 (lower unexplored), l3 (unexplored), l4, l5 unchanged


def test_vertical_extrapolation_only_fills_single_gaps():
    p = np.tile([0.5, 0.5], (6, 1))
    p[0] = [0.9, 0.1]
    p[3] = [0.2, 0.8]
    explored = np.array([True, False, False, True, False, False])
    out = maps.extrapolate_vertical(p, explored)
    np.testing.assert_array_equal(out, p)  # two-voxel gap and bottom gap stay


# ---------------------------------------------------------------------------------------------------------------
# seed 000 eq. 6.15


def _uniform(ny, nx, m=3):
    return np.full((ny, nx, m), 1 / m)


def test_eq615_unexplored_cell_takes_entropy_weighted_mean():
    p = _uniform(3, 3)
    explored = np.zeros((3, 3), dtype=bool)
    a, b = np.array([0.7, 0.2, 0.1]), np.array([0.1, 0.1, 0.8])
    p[0, 0], p[2, 1] = a, b
    explored[0, 0] = explored[2, 1] = True
    out = maps.extrapolate_unexplored(p, explored)
    ha, hb = maps.entropy(a), maps.entropy(b)
    expected = (a / ha + b / hb) / (1 / ha + 1 / hb)
    np.testing.assert_allclose(out[1, 1], expected, rtol=1e-12)
    np.testing.assert_allclose(out[1, 0], expected, rtol=1e-12)  # touches both too
    np.testing.assert_allclose(out[0, 1], a, rtol=1e-12)  # only a is its neighbour
    np.testing.assert_array_equal(out[explored], p[explored])
    np.testing.assert_allclose(out.sum(-1), 1.0, atol=1e-12)


def test_eq615_certain_neighbour_dominates_without_division_by_zero():
    p = _uniform(3, 3)
    explored = np.zeros((3, 3), dtype=bool)
    p[0, 0] = [0.0, 1.0, 0.0]  # H = 0
    p[2, 2] = [0.6, 0.3, 0.1]
    explored[0, 0] = explored[2, 2] = True
    with np.errstate(all="raise"):
        out = maps.extrapolate_unexplored(p, explored)
    np.testing.assert_allclose(out[1, 1], [0.0, 1.0, 0.0], atol=1e-9)
    assert np.all(np.isfinite(out))


def test_eq615_cell_without_explored_neighbour_stays_uniform():
    p = _uniform(5, 5)
    explored = np.zeros((5, 5), dtype=bool)
    p[0, 0] = [0.8, 0.1, 0.1]
    explored[0, 0] = True
    out = maps.extrapolate_unexplored(p, explored)
    changed = np.any(out != p, axis=-1)
    assert set(zip(*np.nonzero(changed), strict=True)) == {(0, 1), (1, 0), (1, 1)}
    np.testing.assert_array_equal(out[2:, 2:], p[2:, 2:])


def test_eq615_unexplored_neighbours_do_not_contribute():
    p = _uniform(1, 3)
    p[0, 0] = [0.8, 0.1, 0.1]
    p[0, 2] = [0.1, 0.1, 0.8]  # a non-uniform but unexplored cell: not evidence
    explored = np.array([[True, False, False]])
    out = maps.extrapolate_unexplored(p, explored)
    np.testing.assert_allclose(out[0, 1], p[0, 0])


def test_eq615_edges_and_corners_use_only_in_grid_neighbours():
    rng = np.random.default_rng(7)
    p = rng.dirichlet([1, 1, 1], size=(4, 5))
    explored = np.ones((4, 5), dtype=bool)
    for cell in [(0, 0), (0, 4), (3, 0), (3, 4), (0, 2), (2, 0)]:
        explored[cell] = False
    out = maps.extrapolate_unexplored(p, explored)
    w = np.where(explored, 1 / maps.entropy(p), 0.0)
    for iy, ix in [(0, 0), (0, 4), (3, 0), (3, 4), (0, 2), (2, 0)]:
        ys = [y for y in (iy - 1, iy, iy + 1) if 0 <= y < 4]
        xs = [x for x in (ix - 1, ix, ix + 1) if 0 <= x < 5]
        num = sum(w[y, x] * p[y, x] for y in ys for x in xs if (y, x) != (iy, ix))
        den = sum(w[y, x] for y in ys for x in xs if (y, x) != (iy, ix))
        np.testing.assert_allclose(out[iy, ix], num / den, rtol=1e-12)


def test_eq615_extra_axes_are_independent_layers():
    rng = np.random.default_rng(3)
    p = rng.dirichlet([1, 1], size=(4, 4, 3))
    explored = rng.random((4, 4, 3)) < 0.5
    out = maps.extrapolate_unexplored(p, explored)
    for k in range(3):
        np.testing.assert_array_equal(out[:, :, k], maps.extrapolate_unexplored(p[:, :, k], explored[:, :, k]))


def test_postprocessing_rejects_bad_input():
    p = _uniform(2, 2)
    with pytest.raises(ValidationError, match="explored must have shape"):
        maps.extrapolate_unexplored(p, np.zeros((3, 2), dtype=bool))
    with pytest.raises(ValidationError, match="sum to one"):
        maps.extrapolate_unexplored(p * 2, np.zeros((2, 2), dtype=bool))
    q = p.copy()
    q[1, 1, 0] = np.nan
    with pytest.raises(ValidationError, match="finite"):
        maps.verify_continuity(q, np.ones((2, 2), dtype=bool))
    with pytest.raises(ValidationError, match="h_min"):
        maps.extrapolate_vertical(p, np.ones((2, 2), dtype=bool), h_min=0.0)


# ---------------------------------------------------------------------------------------------------------------
# seed 001 eq. 2


def test_update_is_normalised_product():
    prior = np.array([0.5, 0.3, 0.2])
    meas = np.array([0.2, 0.6, 0.2])
    out = maps.update(prior, meas)
    np.testing.assert_allclose(out, prior * meas / (prior * meas).sum(), rtol=1e-12)
    # likelihood scale does not matter
    np.testing.assert_allclose(maps.update(prior, meas * 1e-200), out, rtol=1e-12)


def test_update_clamps_so_evidence_can_still_move_the_cell():
    p = np.full(3, 1 / 3)
    for _ in range(50):
        p = maps.update(p, [1.0, 1e-30, 0.0], p_min=1e-6)
    assert p[1] > 0 and p[2] > 0 and p[0] < 1.0
    assert p.min() >= 1e-6 * (1 - 3e-6)
    for _ in range(3):
        p = maps.update(p, [1e-4, 1.0, 1e-4])
    assert p.argmax() == 1


def test_update_vectorised_over_cells_with_broadcast_measurement():
    rng = np.random.default_rng(11)
    prior = rng.dirichlet([1, 1, 1], size=(4, 5))
    meas = np.array([0.1, 0.3, 0.6])
    out = maps.update(prior, meas)
    for iy in range(4):
        for ix in range(5):
            np.testing.assert_allclose(out[iy, ix], maps.update(prior[iy, ix], meas), rtol=1e-12)


def test_update_errors_name_the_problem():
    with pytest.raises(ValidationError, match="no material"):
        maps.update([1.0, 0.0], [0.0, 1.0])
    with pytest.raises(ValidationError, match="does not broadcast"):
        maps.update(np.full((2, 3), 1 / 3), [0.5, 0.5])
    with pytest.raises(ValidationError, match="likelihood_or_posterior must be finite"):
        maps.update([0.5, 0.5], [np.inf, 1.0])
    with pytest.raises(ValidationError, match="prior must be non-negative"):
        maps.update([-0.5, 1.5], [0.5, 0.5])
    with pytest.raises(ValidationError, match="p_min"):
        maps.update([0.5, 0.5], [0.5, 0.5], p_min=0.6)
    with pytest.raises(ValidationError, match="at least 2 materials"):
        maps.update([1.0], [1.0])


# ---------------------------------------------------------------------------------------------------------------
# Grid2D


MATS = ["Material_1", "Material_2", "Material_3"]


def test_grid2d_geometry_and_seed_cells():
    g = Grid2D(MATS, (21, 9), origin=(0.10, -0.02))
    assert g.probabilities.shape == (9, 21, 3)
    # Seed 000 Table 6.8, Object_2 region 5: 1-based cell (20, 8) on a 1 cm grid
    x, y = g.cell_centre(20 - 1, 8 - 1)
    assert (x, y) == pytest.approx((0.10 + 0.195, -0.02 + 0.075))
    assert g.cell_of(x, y) == (19, 7)
    centres = g.cell_centres()
    assert centres.shape == (9, 21, 2)
    assert tuple(centres[7, 19]) == pytest.approx((x, y))
    assert g.cell_of(0.10, -0.02) == (0, 0)
    assert g.cell_of(0.10 + 0.21, -0.02 + 0.09) == (20, 8)  # far corner belongs to the last cell
    with pytest.raises(ValidationError, match="x = .* outside"):
        g.cell_of(0.0999, 0.0)
    with pytest.raises(ValidationError, match="outside the grid"):
        g.cell_centre(21, 0)
    ext = Grid2D.from_extent(MATS, (0.0, 0.205), (0.0, 0.05))
    assert ext.shape == (21, 5)


def test_grid2d_update_marks_explored_and_is_read_only():
    g = Grid2D(MATS, (5, 4))
    ix, iy = g.update(0.025, 0.031, [0.8, 0.15, 0.05])
    assert (ix, iy) == (2, 3)
    assert g.explored.sum() == 1 and g.explored[3, 2]
    np.testing.assert_allclose(g.probabilities[3, 2], [0.8, 0.15, 0.05])
    np.testing.assert_allclose(g.probabilities[0, 0], 1 / 3)
    with pytest.raises(ValueError):
        g.probabilities[0, 0, 0] = 1.0
    with pytest.raises(ValidationError, match=r"p_meas must have shape \(3,\)"):
        g.update_cell(0, 0, [0.5, 0.5])
    assert g.mean_entropy() < math.log10(3)


def test_grid2d_postprocessed_returns_new_grid_and_lowers_entropy():
    g = Grid2D(MATS, (5, 5))
    for ix, iy in [(1, 1), (3, 3)]:
        g.update_cell(ix, iy, [0.9, 0.05, 0.05])
    before = g.probabilities.copy()
    post = g.postprocessed()
    np.testing.assert_array_equal(g.probabilities, before)
    np.testing.assert_array_equal(post.explored, g.explored)
    assert post.mean_entropy() < g.mean_entropy()
    np.testing.assert_allclose(post.probabilities[2, 2], [0.9, 0.05, 0.05])
    np.testing.assert_allclose(post.probabilities[4, 0], 1 / 3)  # no explored neighbour


def test_grid2d_accuracy():
    g = Grid2D(MATS, (3, 2))
    g.update_cell(0, 0, [0.9, 0.05, 0.05])
    g.update_cell(1, 0, [0.05, 0.9, 0.05])
    g.update_cell(2, 0, [0.05, 0.05, 0.9])
    truth = np.array([[0, 1, 0], [-1, -1, -1]])
    assert g.accuracy(truth) == pytest.approx(2 / 3)
    assert g.accuracy(truth, mask=np.array([[True, True, False], [True, True, True]])) == 1.0
    with pytest.raises(ValidationError, match="no cell"):
        g.accuracy(np.full((2, 3), -1))
    with pytest.raises(ValidationError, match="shape"):
        g.accuracy(np.zeros((3, 2), dtype=int))


def test_grid2d_save_load_round_trip(tmp_path):
    g = Grid2D(MATS, (4, 3), origin=(0.01, 0.02), cell_size=0.005, p_min=1e-5)
    g.update_cell(1, 2, [0.2, 0.7, 0.1])
    npz, sidecar = g.save(tmp_path / "map.npz")
    meta = json.loads(sidecar.read_text())
    assert meta["format"] == "palpate.map" and meta["version"] == 1 and meta["materials"] == MATS
    back = Grid2D.load(npz)
    np.testing.assert_array_equal(back.probabilities, g.probabilities)
    np.testing.assert_array_equal(back.explored, g.explored)
    assert (back.origin, back.cell_size, back.p_min, back.base, back.materials) == (
        g.origin, g.cell_size, g.p_min, g.base, g.materials)
    with pytest.raises(ValidationError, match="kind"):
        VoxelGrid.load(npz)


def _corrupt_json(sidecar, key, value):
    meta = json.loads(sidecar.read_text())
    if value is KeyError:
        del meta[key]
    else:
        meta[key] = value
    sidecar.write_text(json.dumps(meta))


@pytest.mark.parametrize(
    ("key", "value", "message"),
    [
        ("version", 99, "'version'"),
        ("format", "something", "'format'"),
        ("cell_size_m", -1.0, "'cell_size_m'"),
        ("materials", ["a", "b"], "'materials'"),
        ("shape", [3, 4], "shape"),
        ("origin_m", KeyError, "missing key 'origin_m'"),
        ("p_min", "small", "'p_min'"),
    ],
)
def test_grid2d_load_rejects_bad_metadata(tmp_path, key, value, message):
    npz, sidecar = Grid2D(MATS, (4, 3)).save(tmp_path / "map.npz")
    _corrupt_json(sidecar, key, value)
    with pytest.raises(ValidationError, match=message) as info:
        Grid2D.load(npz)
    assert "map." in str(info.value)  # names the file


def test_grid2d_load_rejects_bad_arrays(tmp_path):
    npz, sidecar = Grid2D(MATS, (4, 3)).save(tmp_path / "map.npz")
    meta = sidecar.read_text()
    bad_p = np.full((3, 4, 3), 1 / 3)
    bad_p[1, 1] = [np.nan, 0.5, 0.5]
    cases = [
        ({"probabilities": bad_p, "explored": np.zeros((3, 4), bool)}, "NaN"),
        ({"probabilities": np.full((3, 4, 3), 0.5), "explored": np.zeros((3, 4), bool)}, "sums to"),
        ({"probabilities": np.full((3, 4, 3), 1 / 3), "explored": np.zeros((3, 4), int)}, "boolean"),
        ({"probabilities": np.full((3, 4, 3), 1 / 3)}, "missing array 'explored'"),
        ({"probabilities": np.full((3, 4, 3), 1 / 3), "explored": np.zeros((3, 4), bool),
          "extra": np.zeros(1)}, "unexpected"),
        ({"probabilities": np.array([object()] * 36, dtype=object).reshape(3, 4, 3),
          "explored": np.zeros((3, 4), bool)}, "cannot read|float"),
    ]
    for arrays, message in cases:
        np.savez(npz, **arrays)
        sidecar.write_text(meta)
        with pytest.raises(ValidationError, match=message):
            Grid2D.load(npz)
    npz.write_bytes(b"not a zip file")
    with pytest.raises(ValidationError, match="not a readable NPZ"):
        Grid2D.load(npz)
    sidecar.write_text("{ not json")
    with pytest.raises(ValidationError, match=r"map.json:\d+: not valid JSON"):
        Grid2D.load(npz)
    with pytest.raises(ValidationError, match="does not exist"):
        Grid2D.load(tmp_path / "absent.npz")


# ---------------------------------------------------------------------------------------------------------------
# VoxelGrid


def test_voxel_press_updates_exactly_the_voxels_down_to_its_depth():
    v = VoxelGrid(MATS, (4, 3, 10), origin=(0.0, 0.0), z_top=0.05, cell_size=0.0025)
    ix, iy, k = v.update_press(0.006, 0.001, 0.005, [0.7, 0.2, 0.1])  # exactly two voxels deep
    assert (ix, iy, k) == (2, 0, 2)
    expected = np.zeros((4, 3, 10), dtype=bool)
    expected[2, 0, :2] = True
    np.testing.assert_array_equal(v.explored, expected)
    np.testing.assert_allclose(v.column(2, 0)[:2], [[0.7, 0.2, 0.1]] * 2)
    np.testing.assert_allclose(v.column(2, 0)[2:], 1 / 3)
    assert v.update_press(0.006, 0.001, 0.0051, [0.7, 0.2, 0.1])[2] == 3
    assert v.update_press(0.001, 0.001, 1.0, [0.7, 0.2, 0.1])[2] == 10  # deeper than the grid: whole column
    # one row per voxel reached
    v.update_press(0.009, 0.006, 0.003, [[0.6, 0.3, 0.1], [0.1, 0.3, 0.6]])
    np.testing.assert_allclose(v.column(3, 2)[:2], [[0.6, 0.3, 0.1], [0.1, 0.3, 0.6]])
    with pytest.raises(ValidationError, match="depth_reached"):
        v.update_press(0.006, 0.001, 0.0, [0.7, 0.2, 0.1])
    with pytest.raises(ValidationError, match=r"\(1, 3\)"):
        v.update_press(0.006, 0.001, 0.002, [[0.7, 0.2, 0.1]] * 2)
    with pytest.raises(ValidationError, match="y = .* outside"):
        v.update_press(0.006, 0.5, 0.002, [0.7, 0.2, 0.1])


def test_voxel_centres_follow_depth_convention():
    v = VoxelGrid(MATS, (2, 2, 4), origin=(0.1, 0.2), z_top=0.03, cell_size=0.0025)
    c = v.voxel_centres()
    assert c.shape == (2, 2, 4, 3)
    assert tuple(c[1, 0, 0]) == pytest.approx((0.1 + 0.00375, 0.2 + 0.00125, 0.03 - 0.00125))
    assert c[0, 0, 3, 2] == pytest.approx(0.03 - 0.00875)


def test_voxel_postprocessed_is_table_pipeline_and_leaves_original():
    v = VoxelGrid(MATS, (1, 1, 6))
    for iz in (0, 1, 3, 4, 5):
        v.update_voxel(0, 0, iz, T2_100[iz])
    before = v.probabilities.copy()
    post = v.postprocessed()
    np.testing.assert_array_equal(v.probabilities, before)
    col = post.column(0, 0)
    # l3 filled from l2 and l4 as measured (Table 3), then continuity on explored voxels only
    np.testing.assert_allclose(col[2], [0.9668, 0.0332, 0.0], atol=2e-4)
    np.testing.assert_allclose(col[0], T2_CONT[0], atol=2e-4)  # l1 with l2 (both explored)
    np.testing.assert_allclose(col[1], v.column(0, 0)[1], atol=1e-12)  # l2: lower neighbour unexplored
    np.testing.assert_allclose(col[3:5], T2_CONT[3:5], atol=2e-4)
    assert post.mean_entropy() < v.mean_entropy()


def test_voxel_lateral_extrapolation_fills_only_what_vertical_did_not():
    v = VoxelGrid(MATS, (3, 3, 3))
    v.update_voxel(0, 0, 0, [0.9, 0.05, 0.05])
    v.update_voxel(0, 0, 2, [0.05, 0.05, 0.9])
    v.update_voxel(1, 0, 0, [0.05, 0.9, 0.05])
    plain = v.postprocessed()
    lat = v.postprocessed(lateral=True)
    np.testing.assert_array_equal(lat.column(0, 0), plain.column(0, 0))  # vertical gap kept its eq. 3 value
    np.testing.assert_allclose(plain.column(1, 1)[0], 1 / 3)
    assert lat.column(1, 1)[0].argmax() in (0, 1) and lat.column(1, 1)[0].max() > 0.4
    np.testing.assert_allclose(lat.column(2, 2), 1 / 3)  # no explored neighbour in any layer


def test_voxel_save_load_round_trip_and_accuracy(tmp_path):
    v = VoxelGrid(MATS, (2, 2, 3), origin=(0.1, 0.2), z_top=0.04)
    v.update_press(0.101, 0.201, 0.006, [0.1, 0.8, 0.1])
    back = VoxelGrid.load(v.save(tmp_path / "vox.npz")[0])
    np.testing.assert_array_equal(back.probabilities, v.probabilities)
    np.testing.assert_array_equal(back.explored, v.explored)
    assert (back.z_top, back.origin, back.cell_size) == (v.z_top, v.origin, v.cell_size)
    truth = np.full((2, 2, 3), -1)
    truth[0, 0] = [1, 1, 0]
    assert v.accuracy(truth) == pytest.approx(2 / 3)
    sidecar = tmp_path / "vox.json"
    _corrupt_json(sidecar, "z_top_m", KeyError)
    with pytest.raises(ValidationError, match="vox.json: missing key 'z_top_m'"):
        VoxelGrid.load(tmp_path / "vox.npz")


# ---------------------------------------------------------------------------------------------------------------
# iterated eq. 6.15 (extrapolation passes)


def _random_plane(rng, shape=(7, 9, 3), frac=0.15):
    p = rng.dirichlet(np.ones(shape[-1]), shape[:-1])
    explored = rng.random(shape[:-1]) < frac
    explored[0, 0] = True
    return p, explored


def test_one_extrapolation_pass_is_the_seed_function_exactly():
    rng = np.random.default_rng(11)
    p, explored = _random_plane(rng)
    ref = maps.extrapolate_unexplored(p, explored)
    assert np.array_equal(maps.extrapolate_unexplored(p, explored, passes=1), ref)
    g = Grid2D(["a", "b", "c"], (9, 7))
    g._p, g._explored = p.copy(), explored.copy()
    assert np.array_equal(g.postprocessed().probabilities, ref)
    assert np.array_equal(g.postprocessed(passes=1).probabilities, ref)


def test_a_cell_two_away_is_filled_on_the_second_pass_not_the_first():
    g = Grid2D(["a", "b", "c"], (5, 5))
    q = np.array([0.8, 0.15, 0.05])
    g.update_cell(0, 0, q)
    u = np.full(3, 1 / 3)
    one, two = g.postprocessed(passes=1).probabilities, g.postprocessed(passes=2).probabilities
    # Cell (ix, iy) = (2, 1) is two columns from the only explored cell: no explored 8-neighbour.
    assert np.allclose(one[1, 2], u) and np.allclose(one[1, 1], g.probabilities[0, 0])
    # On pass 2 its known neighbours are (1, 0) and (1, 1), both copies of the press: it becomes the press.
    assert np.allclose(two[1, 2], g.probabilities[0, 0], atol=1e-12)
    assert np.allclose(two[3, 3], u)  # three away: still untouched after two passes
    full = g.postprocessed(passes=None).probabilities
    assert np.allclose(full, g.probabilities[0, 0], atol=1e-12)
    assert g.postprocessed(passes=None).explored.sum() == 1  # estimates are not measurements


def test_later_passes_weight_filled_cells_by_their_own_entropy():
    # Row of 5 cells: a vague press at x=0, a certain press at x=4; x=2 is filled on pass 2 from x=1 and x=3.
    p = np.full((1, 5, 2), 0.5)
    p[0, 0], p[0, 4] = [0.7, 0.3], [0.01, 0.99]
    explored = np.zeros((1, 5), bool)
    explored[0, [0, 4]] = True
    out = maps.extrapolate_unexplored(p, explored, passes=2)
    w1, w3 = 1 / maps.entropy(p[0, 0]), 1 / maps.entropy(p[0, 4])
    assert np.allclose(out[0, 1], p[0, 0]) and np.allclose(out[0, 3], p[0, 4])
    assert np.allclose(out[0, 2], (w1 * p[0, 0] + w3 * p[0, 4]) / (w1 + w3))


def test_iterated_extrapolation_stays_normalised_and_finite_even_with_certain_cells():
    rng = np.random.default_rng(12)
    for passes in (2, 3, None):
        p, explored = _random_plane(rng, (12, 10, 4), frac=0.05)
        p[explored] = np.eye(4)[rng.integers(4, size=int(explored.sum()))]  # H = 0: the h_min floor
        out = maps.extrapolate_unexplored(p, explored, passes=passes)
        assert np.all(np.isfinite(out)) and (out >= 0).all()
        assert np.allclose(out.sum(axis=-1), 1.0, atol=1e-12)
        assert np.array_equal(out[explored], p[explored])
    # "until done" leaves only cells with no explored cell anywhere in their plane unfilled: here none.
    assert not np.isclose(out, 0.25).all(axis=-1).any()


def test_extrapolation_passes_no_explored_cell_leaves_the_map_and_rejects_bad_passes():
    p = np.full((3, 4, 2), 0.5)
    assert np.array_equal(maps.extrapolate_unexplored(p, np.zeros((3, 4), bool), passes=None), p)
    for bad in (0, -1, 1.5, True, "all"):
        with pytest.raises(ValidationError, match="passes must be an integer >= 1 or None"):
            maps.extrapolate_unexplored(p, np.zeros((3, 4), bool), passes=bad)
