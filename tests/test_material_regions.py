"""Where each material lies on a map: connected regions with their area, centroid and probability, from cell maps
and fine maps alike; bad input is refused by name."""

from __future__ import annotations

import numpy as np
import pytest

from palpate.core.errors import ValidationError
from palpate.core.mapping.regions import material_regions


def _map(labels: np.ndarray, sure: float = 0.9) -> np.ndarray:
    p = np.full(labels.shape + (2,), 1.0 - sure)
    p[labels == 0, 0] = sure
    p[labels == 1, 1] = sure
    return p


def test_a_lump_and_the_bulk_around_it_are_two_regions_with_their_true_centroids_and_areas():
    labels = np.zeros((40, 60), dtype=int)
    labels[10:20, 30:45] = 1  # a 15 x 10 mm lump on a 1 mm raster whose corner is at (-0.01, 0.02) m
    regions = material_regions(_map(labels), (-0.01, 0.02), 1e-3, ("bulk", "lump"))
    assert [r.material for r in regions] == ["bulk", "lump"]
    lump = regions[1]
    assert lump.points == 150 and lump.area_m2 == pytest.approx(150e-6)
    assert lump.centroid_m == pytest.approx((-0.01 + 0.0375, 0.02 + 0.015))
    assert lump.probability == pytest.approx(0.9)
    assert regions[0].area_m2 == pytest.approx((2400 - 150) * 1e-6)


def test_regions_that_touch_only_at_a_corner_are_two_and_small_or_unknown_ones_are_left_out():
    labels = np.zeros((6, 6), dtype=int)
    labels[1, 1] = labels[2, 2] = 1  # diagonal neighbours: not connected
    labels[4, 4] = 1
    regions = material_regions(_map(labels), (0.0, 0.0), 0.01, ("a", "b"))
    assert sorted(r.points for r in regions if r.material == "b") == [1, 1, 1]
    known = np.ones((6, 6), dtype=bool)
    known[4, 4] = False
    assert len([r for r in material_regions(_map(labels), (0.0, 0.0), 0.01, ("a", "b"), known=known)
                if r.material == "b"]) == 2
    assert [r.material for r in material_regions(_map(labels), (0.0, 0.0), 0.01, ("a", "b"), min_points=2)] == ["a"]


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"probabilities": np.zeros((3, 3))}, r"\(ny, nx, 2\)"),
    ({"spacing": 0.0}, "spacing"),
    ({"probabilities": np.full((3, 3, 2), np.nan)}, "finite"),
    ({"known": np.ones((2, 2), dtype=bool)}, "known"),
])
def test_bad_maps_are_refused_by_name(kwargs, match):
    args = {"probabilities": np.full((3, 3, 2), 0.5), "origin": (0.0, 0.0), "spacing": 0.01,
            "materials": ("a", "b")} | kwargs
    with pytest.raises(ValidationError, match=match):
        material_regions(**args)


def test_the_summary_keeps_a_fine_maps_regions_of_a_quarter_cell_or_more_and_at_most_twenty():
    from palpate.core.mapping.regions import MAX_REGIONS, region_report

    labels = np.zeros((50, 200), dtype=int)
    labels[2:7, 2:7] = 1  # 25 points: a quarter of a 10 mm cell on a 1 mm raster
    labels[2:6, 20:26] = 1  # 24 points: a speck
    labels[20:22, 30:200:6] = 1  # 29 regions of 2 points (1 x 2)
    report = region_report(_map(labels), (0.0, 0.0), 1e-3, ("a", "b"), cell=0.01)
    assert [(r["material"], r["points"]) for r in report] == [("a", 10000 - 25 - 24 - 58), ("b", 25)]
    every = region_report(_map(labels), (0.0, 0.0), 1e-3, ("a", "b"))
    assert len(every) == MAX_REGIONS and every[0]["material"] == "a"


def _voxels(labels: np.ndarray, sure: float = 0.9) -> np.ndarray:
    p = np.full(labels.shape + (2,), 1.0 - sure)
    p[labels == 0, 0] = sure
    p[labels == 1, 1] = sure
    p[labels < 0] = 0.5  # never reached: uniform
    return p


def test_a_buried_lump_in_a_voxel_map_is_one_region_with_its_centroid_depths_and_volume():
    from palpate.core.mapping.regions import volume_regions

    labels = np.zeros((12, 10, 4), dtype=int)  # (nx, ny, nz), iz = 0 at the surface
    labels[3:6, 2:4, 1:3] = 1  # 3 x 2 voxels laterally, from one voxel down to three
    labels[:, :, 3] = -1  # the bottom layer never reached
    regions = volume_regions(_voxels(labels), (0.01, -0.02), 0.04, 0.005, ("bulk", "lump"))
    assert [r.material for r in regions] == ["bulk", "lump"]
    lump = regions[1]
    assert lump.voxels == 12 and lump.volume_m3 == pytest.approx(12 * 0.005**3)
    assert lump.centroid_m == pytest.approx((0.01 + 0.0225, -0.02 + 0.015, 0.04 - 0.010))
    assert (lump.top_depth_m, lump.bottom_depth_m) == pytest.approx((0.005, 0.015))
    assert lump.probability == pytest.approx(0.9)
    assert regions[0].voxels == 12 * 10 * 3 - 12  # the uniform layer is in no region
    assert regions[0].bottom_depth_m == pytest.approx(0.015)


def test_voxels_touching_only_along_an_edge_are_two_regions_and_bad_voxel_maps_are_refused():
    from palpate.core.mapping.regions import volume_regions

    labels = np.zeros((4, 4, 3), dtype=int)
    labels[1, 1, 0] = labels[2, 1, 1] = 1  # share an edge, not a face
    regions = volume_regions(_voxels(labels), (0.0, 0.0), 0.0, 0.01, ("a", "b"))
    assert sorted(r.voxels for r in regions if r.material == "b") == [1, 1]
    with pytest.raises(ValidationError, match=r"\(nx, ny, nz, 2\)"):
        volume_regions(np.full((3, 3, 2), 0.5), (0.0, 0.0), 0.0, 0.01, ("a", "b"))
    with pytest.raises(ValidationError, match="finite"):
        volume_regions(np.full((3, 3, 2, 2), np.nan), (0.0, 0.0), 0.0, 0.01, ("a", "b"))
