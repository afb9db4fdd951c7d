"""The fast map kernels give the floats of the plain formulations they replace, bit for bit (a map must not change
by a bit when it is post-processed or updated faster), and the batch update is the per-cell update in order."""

from __future__ import annotations

import numpy as np
import pytest

from palpate.core.errors import ValidationError
from palpate.core.mapping.extrapolation import extrapolate_plane, extrapolate_unexplored
from palpate.core.mapping.grids import Grid2D, VoxelGrid
from palpate.core.mapping.neighbourhood import box3_sum
from palpate.core.mapping.probability import sum_last


def _plain_eq615(arr: np.ndarray, mask: np.ndarray, base: float = 10.0, h_min: float = 1e-12, h=None):
    """Eq. 6.15 written plainly on whole arrays: masked log entropy, box sums of box3_sum, a masked divide."""
    if h is None:
        plogp = np.log(arr, out=np.zeros_like(arr), where=arr > 0) * arr
        h = np.maximum(plogp.sum(axis=-1) * (-1.0 / np.log(base)), 0.0)
    w = np.where(mask, 1.0 / np.maximum(h, h_min), 0.0)
    num = box3_sum(w[..., None] * arr, axes=(0, 1))
    den = box3_sum(w, axes=(0, 1))
    target = ~mask & (den > 0)
    out = arr.copy()
    np.divide(num, den[..., None], out=out, where=target[..., None])
    return out


def _random_map(rng, shape, m, explored, zeros=False):
    p = rng.dirichlet(np.full(m, 0.4), size=shape)
    if zeros:  # certain cells and exact zeros take the masked-log path
        p[rng.random(shape) < 0.1] = np.eye(m)[0]
    mask = rng.random(shape) < explored
    return p, mask


@pytest.mark.parametrize("shape", [(1, 1), (1, 7), (7, 1), (15, 9), (32, 16), (33, 40), (64, 3), (65, 7), (40, 3, 4)])
def test_blocked_eq615_equals_the_plain_formula_bit_for_bit(rng, shape):
    for m, explored, zeros in ((3, 0.3, False), (2, 0.05, True), (5, 0.8, True), (9, 0.5, False)):
        p, mask = _random_map(rng, shape, m, explored, zeros)
        np.testing.assert_array_equal(extrapolate_plane(p, mask), _plain_eq615(p, mask))
        h = rng.uniform(0, 0.5, shape)
        np.testing.assert_array_equal(extrapolate_unexplored(p, mask, h=h), _plain_eq615(p, mask, h=h))


def test_grid_postprocessing_equals_the_plain_formula(rng):
    grid = Grid2D(["a", "b", "c"], (37, 21))
    cells = rng.integers(0, [37, 21], size=(200, 2))
    for ix, iy in cells:
        grid.update_cell(int(ix), int(iy), rng.dirichlet(np.ones(3)))
    post = grid.postprocessed()
    np.testing.assert_array_equal(post.probabilities, _plain_eq615(grid.probabilities, grid.explored))
    np.testing.assert_array_equal(post.explored, grid.explored)
    assert post.materials == grid.materials and post.materials is not grid.materials


@pytest.mark.parametrize("m", range(2, 12))
def test_sum_over_materials_is_numpys_sum(rng, m):
    for shape in [(), (1,), (5,), (40, 30), (3, 4, 5)]:
        a = rng.normal(size=shape + (m,)) * 10.0 ** rng.uniform(-8, 8, shape + (m,))
        np.testing.assert_array_equal(sum_last(a), a.sum(axis=-1))


@pytest.mark.parametrize("m", [2, 3, 5, 8])
def test_batch_update_is_the_per_cell_update_in_order(rng, m):
    names = [f"m{k}" for k in range(m)]
    one, batch = Grid2D(names, (23, 17)), Grid2D(names, (23, 17))
    n = 3000  # many repeats of a cell: each is fused after the one before it
    ix, iy = rng.integers(0, 23, n), rng.integers(0, 17, n)
    meas = rng.dirichlet(np.full(m, 0.3), n)
    meas[rng.random((n, m)) < 0.1] = 0.0  # underflowed posteriors
    meas[sum_last(meas) == 0, 0] = 1.0
    for k in range(n):
        one.update_cell(int(ix[k]), int(iy[k]), meas[k])
    batch.update_cells(ix, iy, meas)
    np.testing.assert_array_equal(batch.probabilities, one.probabilities)
    np.testing.assert_array_equal(batch.explored, one.explored)


def test_a_small_batch_on_a_large_map_is_the_per_cell_update(rng):
    one, batch = Grid2D(["a", "b", "c"], (60, 50)), Grid2D(["a", "b", "c"], (60, 50))
    ix, iy = rng.integers(0, 60, 100), rng.integers(0, 50, 100)
    ix[50:60], iy[50:60] = ix[0], iy[0]  # one cell eleven times
    meas = rng.dirichlet(np.ones(3), 100)
    for k in range(100):
        one.update_cell(int(ix[k]), int(iy[k]), meas[k])
    batch.update_cells(ix, iy, meas)
    np.testing.assert_array_equal(batch.probabilities, one.probabilities)
    np.testing.assert_array_equal(batch.explored, one.explored)


def test_batch_voxel_update_is_the_per_voxel_update(rng):
    one, batch = VoxelGrid(["a", "b", "c"], (6, 5, 4)), VoxelGrid(["a", "b", "c"], (6, 5, 4))
    idx = rng.integers(0, [6, 5, 4], size=(500, 3))
    meas = rng.dirichlet(np.ones(3), 500)
    for (x, y, z), p in zip(idx, meas, strict=True):
        one.update_voxel(int(x), int(y), int(z), p)
    batch.update_voxels(idx[:, 0], idx[:, 1], idx[:, 2], meas)
    np.testing.assert_array_equal(batch.probabilities, one.probabilities)
    np.testing.assert_array_equal(batch.explored, one.explored)


def test_batch_update_rejects_bad_input_and_changes_nothing(rng):
    grid = Grid2D(["a", "b", "c"], (5, 4))
    before = grid.probabilities.copy()
    ok = rng.dirichlet(np.ones(3), 3)
    bad = [
        (([0, 1, 5], [0, 0, 0], ok), "ix\\[2\\] = 5 is outside"),
        (([0, 1, 2], [0, -1, 0], ok), "iy\\[1\\] = -1 is outside"),
        (([0, 1], [0, 0, 0], ok[:2]), "iy has 3 indices"),
        (([0.0, 1.0, 2.0], [0, 0, 0], ok), "integer cell indices"),
        (([0, 1, 2], [0, 0, 0], ok[:, :2]), "shape \\(3, 3\\)"),
        (([0, 1, 2], [0, 0, 0], np.where(np.eye(3, dtype=bool), np.nan, ok)), "finite"),
        (([0, 1, 2], [0, 0, 0], -ok), "non-negative"),
        (([0, 1, 2], [0, 0, 0], np.vstack([ok[:2], np.zeros(3)])), "p_meas\\[2\\] is all zero"),
    ]
    for (ix, iy, p), message in bad:
        with pytest.raises(ValidationError, match=message):
            grid.update_cells(np.asarray(ix), np.asarray(iy), p)
        np.testing.assert_array_equal(grid.probabilities, before)
        assert not grid.explored.any()


@pytest.mark.parametrize("nx", [3, 40])  # a batch as large as the map, and one much smaller
def test_batch_update_of_a_loaded_map_with_exact_zeros(tmp_path, nx):
    grid = Grid2D(["a", "b", "c"], (nx, 1))
    grid.save(tmp_path / "m.npz")
    p = np.load(tmp_path / "m.npz")
    arrays = {k: p[k] for k in p.files}
    arrays["probabilities"][0, 0] = [1.0, 0.0, 0.0]  # a certain cell, as a file may hold it
    np.savez(tmp_path / "m.npz", **arrays)
    loaded = Grid2D.load(tmp_path / "m.npz")
    with pytest.raises(ValidationError, match="no material with non-zero probability in common"):
        loaded.update_cells(np.array([1, 0]), np.array([0, 0]), np.array([[0.2, 0.3, 0.5], [0.0, 0.5, 0.5]]))
    assert not loaded.explored.any()
    one = Grid2D.load(tmp_path / "m.npz")
    loaded.update_cells(np.array([0, 0]), np.array([0, 0]), np.array([[0.5, 0.5, 0.0], [0.0, 0.5, 0.5]]))
    one.update_cell(0, 0, np.array([0.5, 0.5, 0.0]))
    one.update_cell(0, 0, np.array([0.0, 0.5, 0.5]))  # fine once the first update clamped the cell above zero
    np.testing.assert_array_equal(loaded.probabilities, one.probabilities)
