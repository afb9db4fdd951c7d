"""The lump layer: a read lump written into cubes under a voxel map's surface, beside the seed's voxel map."""

import numpy as np
import pytest
from scipy.stats import norm

from palpate.core.errors import ValidationError
from palpate.core.mapping.fine import FineMap
from palpate.core.mapping.lump_layer import lump_layer
from palpate.core.mapping.regions import volume_regions

MATERIALS = ("soft", "medium", "hard")
#: a 20 x 10 mm surface at 1 mm: "soft" on the left half, "medium" on the right, each 0.9 sure
SURFACE = np.full((10, 20, 3), 0.05)
SURFACE[:, :10, 0] = SURFACE[:, 10:, 1] = 0.9
FINE = FineMap((0.0, 0.0), 1e-3, SURFACE, MATERIALS)


def _spot(presses, top=3e-3, sd=1e-3, p=0.8, material="hard"):
    return {"centroid_m": list(np.mean(presses, axis=0)), "press_locations_m": [list(xy) for xy in presses],
            "lump": {"material": material, "top_m": top, "top_sd_m": sd, "p_material": p}}


def test_without_lumps_the_layer_is_the_surface_reaching_down():
    layer = lump_layer(FINE, 0.05, 8e-3, 5e-3, [{"centroid_m": [0.005, 0.005], "lump": None}])
    assert layer.probabilities.shape == (20, 10, 8, 3) and layer.lumps == 0 and not layer.footprint.any()
    for iz in range(8):
        np.testing.assert_array_equal(layer.probabilities[:, :, iz], np.transpose(SURFACE, (1, 0, 2)))


def test_a_read_lump_fills_the_cubes_under_its_presses_below_its_top():
    presses = [(0.0025, 0.0025), (0.0075, 0.0025)]  # two presses, 5 mm cells: x 0-10 mm, y 0-5 mm
    layer = lump_layer(FINE, 0.05, 8e-3, 5e-3, [_spot(presses, top=3e-3, sd=1e-3, p=0.8)])
    p = layer.probabilities
    np.testing.assert_allclose(p.sum(axis=-1), 1.0)
    assert layer.lumps == 1
    footprint = np.zeros((20, 10), dtype=bool)
    footprint[:10, :5] = True  # x 0-10 mm, y 0-5 mm
    np.testing.assert_array_equal(layer.footprint, footprint)
    depth = (np.arange(8) + 0.5) * 1e-3
    inside = 0.8 * norm.cdf((depth - 3e-3) / 1e-3)
    # under the presses: the surface's distribution, less the lump's share, plus the lump's share as "hard"
    np.testing.assert_allclose(p[4, 2, :, 2], 0.05 * (1 - inside) + inside)
    np.testing.assert_allclose(p[4, 2, :, 0], 0.9 * (1 - inside))
    # beside them (y 5-10 mm; x 10-20 mm) and above the top, the surface as it was
    np.testing.assert_array_equal(p[4, 7], np.tile(SURFACE[7, 4], (8, 1)))
    np.testing.assert_array_equal(p[14, 2], np.tile(SURFACE[2, 14], (8, 1)))
    assert np.argmax(p[4, 2, 1]) == 0 and np.argmax(p[4, 2, 6]) == 2
    # one region of "hard": 10 x 5 mm from below its top to the bottom, centred under the presses
    (hard,) = [r for r in volume_regions(p, layer.origin, layer.z_top, 1e-3, MATERIALS) if r.material == "hard"]
    assert hard.voxels == 10 * 5 * 5 and hard.top_depth_m == pytest.approx(3e-3)
    np.testing.assert_allclose(hard.centroid_m[:2], (0.005, 0.0025))


def test_a_sure_shallow_lump_reaches_the_surface_and_an_unsure_one_never_wins():
    presses = [(0.0125, 0.0075)]
    sure = lump_layer(FINE, 0.05, 6e-3, 5e-3, [_spot(presses, top=0.0, sd=1e-6, p=1.0)]).probabilities
    assert np.all(np.argmax(sure[10:15, 5:10], axis=-1) == 2)
    unsure = lump_layer(FINE, 0.05, 6e-3, 5e-3, [_spot(presses, top=0.0, sd=1e-6, p=0.45)]).probabilities
    assert np.all(np.argmax(unsure[10:15, 5:10], axis=-1) == 1)


@pytest.mark.parametrize("bad", [{"material": "steel"}, {"top_m": float("nan")}, {"top_sd_m": 0.0},
                                 {"p_material": 1.5}, {"top_m": None}])
def test_a_bad_lump_is_refused_by_name(bad):
    spot = _spot([(0.0025, 0.0025)])
    spot["lump"] |= bad
    with pytest.raises(ValidationError, match="lump_layer"):
        lump_layer(FINE, 0.05, 8e-3, 5e-3, [spot])


@pytest.mark.parametrize("depth,cell", [(0.0, 5e-3), (8e-3, float("inf")), (float("nan"), 5e-3)])
def test_a_bad_depth_or_cell_is_refused(depth, cell):
    with pytest.raises(ValidationError, match="lump_layer"):
        lump_layer(FINE, 0.05, depth, cell, [])


def test_the_figure_cuts_the_layer_at_its_depths_above_the_truth(tmp_path):
    from palpate.core.io.fine_figures import LAYER_SLICES, lump_layer_figure, plot_lump_layer

    layer = lump_layer(FINE, 0.05, 8e-3, 5e-3, [_spot([(0.0025, 0.0025)])])
    truth = np.zeros(layer.probabilities.shape[:3], dtype=int)
    truth[:5, :5, 3:] = 2
    fig = lump_layer_figure("block", layer, truth, [((0.0025, 0.0025), "harder")])
    titles = [ax.get_title() for ax in fig.axes]
    assert len(titles) == 2 * LAYER_SLICES and titles[0] == "lump layer, 1.5 mm down" and titles[-1].startswith("truth")
    assert len(lump_layer_figure("block", layer, None).axes) == LAYER_SLICES
    path = plot_lump_layer(tmp_path / "lumps.png", "block", layer, truth)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
