"""Which cells a press reads without feeling a second material (core/world/workspace.clear_of_walls), checked
against a brute-force distance to the nearest other material on a fine grid."""

from dataclasses import replace

import numpy as np
import pytest

from palpate.core.world.scenario_file import load_scenario
from palpate.core.world.workspace import (
    clear_of_walls,
    contact_radius,
    ground_truth_cells,
    ground_truth_map,
    object_geometry,
)


@pytest.fixture()
def heterogeneous(repo_dir):
    sc = load_scenario(repo_dir / "scenarios" / "heterogeneous.toml")
    return sc, sc.objects[0], object_geometry(sc, sc.objects[0])


def _distance_to_another_material(sc, entry, geometry, step=0.25e-3):
    """Per cell, the distance from its centre to the nearest point of a 0.25 mm grid over the map (and off it)
    whose truth is another reference material, m."""
    x0, y0 = geometry.origin
    nx, ny = geometry.plane_shape
    pad = 0.01
    xs = np.arange(x0 - pad, x0 + nx * geometry.cell_size + pad, step) + step / 2
    ys = np.arange(y0 - pad, y0 + ny * geometry.cell_size + pad, step) + step / 2
    gx, gy = np.meshgrid(xs, ys)
    pts = np.column_stack([gx.ravel(), gy.ravel()])
    fine = ground_truth_cells(entry, sc, pts, np.full(len(pts), entry.spec.height - sc.exploration.depth / 2))
    truth = ground_truth_map(entry, sc, geometry)
    out = np.full(truth.shape, np.inf)
    for (iy, ix), centre in zip(np.ndindex(truth.shape), geometry.cell_centres().reshape(-1, 2), strict=True):
        other = (fine != truth[iy, ix]) & (fine >= 0)
        if other.any():
            out[iy, ix] = np.hypot(*(pts[other] - centre).T).min()
    return out


def test_cells_are_clear_exactly_where_no_other_material_lies_within_the_radius(heterogeneous):
    sc, entry, geometry = heterogeneous
    r = contact_radius(sc)
    assert r == pytest.approx(np.sqrt(8e-3 * 5e-3))
    clear = clear_of_walls(entry, sc, geometry, r)
    dist = _distance_to_another_material(sc, entry, geometry)
    sure = np.abs(dist - r) > 0.5e-3  # a wall within the sampling spacing of the radius could go either way
    assert sure.sum() >= 0.8 * dist.size
    np.testing.assert_array_equal(clear[sure], (dist > r)[sure])
    # the scene has both kinds, and a wider radius only removes cells
    assert 0 < clear.sum() < clear.size
    assert not (clear_of_walls(entry, sc, geometry, 2 * r) & ~clear).any()
    assert clear_of_walls(entry, sc, geometry, 0.0).all()


def test_a_homogeneous_block_is_clear_everywhere_and_voxel_maps_and_bad_radii_are_handled(heterogeneous, repo_dir):
    sc, entry, geometry = heterogeneous
    block = load_scenario(repo_dir / "scenarios" / "explore_info_gain.toml")
    plain = replace(block.objects[0], spec=replace(block.objects[0].spec, inclusions=(), layers=(), material_map=None))
    assert clear_of_walls(plain, block, object_geometry(block, plain), contact_radius(block)).all()
    voxel = replace(sc, exploration=replace(sc.exploration, map="voxel"))
    assert clear_of_walls(entry, voxel, object_geometry(voxel, entry), 0.005) is None
    for bad in (-1e-3, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="radius"):
            clear_of_walls(entry, sc, geometry, bad)
