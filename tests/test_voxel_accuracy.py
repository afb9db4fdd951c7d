"""The accuracy objective on voxel maps: expected voxels set right by pressing a column, against a Monte Carlo
of presses on the map's own update."""

from __future__ import annotations

import numpy as np
import pytest

from palpate.core.errors import ValidationError
from palpate.core.mapping.accuracy import decided_labels
from palpate.core.mapping.grids import Grid2D, VoxelGrid
from palpate.core.mapping.probability import update
from palpate.core.planning.expected_accuracy import confusion_outcomes, expected_accuracy_gain, label_belief
from palpate.core.planning.info_gain import InfoGain
from palpate.core.planning.outcomes import outcome_posteriors, outcome_table
from palpate.core.planning.voxel_accuracy import voxel_accuracy_gain

MATS = ["m0", "m1", "m2"]


@pytest.fixture(scope="module")
def memory(three_material_memory):
    return three_material_memory


def _voxels(rng) -> VoxelGrid:
    g = VoxelGrid(MATS, (5, 4, 3), cell_size=0.005)
    for _ in range(14):
        ix, iy = int(rng.integers(5)), int(rng.integers(4))
        k = int(rng.integers(1, 4))
        for iz in range(k):
            g.update_voxel(ix, iy, iz, rng.dirichlet([0.4, 0.4, 0.4]))
    return g


def _monte_carlo(g: VoxelGrid, post: VoxelGrid, table, ix: int, iy: int, rng, n: int = 20000) -> float:
    """Draw a truth per voxel from the in-layer belief and a reading from the memory's confusion, fuse the
    reading with the map's own update, and count the voxel right after minus right now."""
    rep, conf = confusion_outcomes(table)
    p = np.asarray(g.probabilities)
    total = 0.0
    for iz in range(g.shape[2]):
        layer = Grid2D(MATS, (5, 4))._with_arrays(np.swapaxes(p[:, :, iz], 0, 1), np.asarray(g.explored)[:, :, iz].T)
        b = label_belief(layer, reach=2, correlation_cells=1.0)[iy, ix]
        label, decided = decided_labels(np.asarray(post.probabilities)[ix, iy, iz])
        t = rng.choice(3, size=n, p=b)
        o = np.array([rng.choice(3, p=conf[ti]) for ti in t])
        after = np.array([np.argmax(update(p[ix, iy, iz], rep[oi], p_min=g.p_min)) for oi in range(3)])[o]
        total += np.mean(after == t) - np.mean((t == label) & decided)
    return total


def test_voxel_accuracy_gain_matches_a_monte_carlo_of_presses(memory):
    rng = np.random.default_rng(8)
    table = outcome_table(outcome_posteriors(memory, 30, seed=2))
    g = _voxels(rng)
    post = g.postprocessed()
    gain = voxel_accuracy_gain(g, post, table)
    assert gain.shape == (4, 5) and np.all(np.isfinite(gain))
    for ix, iy in [(0, 0), (2, 1), (4, 3)]:
        assert gain[iy, ix] == pytest.approx(_monte_carlo(g, post, table, ix, iy, rng), abs=0.03)


def test_an_unpressed_column_is_worth_about_a_voxel_per_layer_and_a_certain_one_nothing(memory):
    table = outcome_table(outcome_posteriors(memory, 30, seed=2))
    g = VoxelGrid(MATS, (3, 1, 3), cell_size=0.005)
    for iz in range(3):
        g.update_voxel(0, 0, iz, [0.998, 0.001, 0.001])
    gain = voxel_accuracy_gain(g, g.postprocessed(), table)
    assert abs(gain[0, 0]) < 0.05  # known: a press changes nothing
    assert 1.5 < gain[0, 2] <= 3.0  # three unknown voxels, each read right most of the time
    assert voxel_accuracy_gain(g, g.postprocessed(), table, max_depth=0.005)[0, 2] < 1.0  # one layer reached
    # the policy with the accuracy objective presses an unknown column, down to its deepest unknown voxel
    t = InfoGain(memory, spread_stride=1).next_target(g)
    assert (t.ix, t.iy) in ((1, 0), (2, 0)) and t.depth == pytest.approx(0.015)


def test_a_2d_map_is_refused(memory):
    table = outcome_table(outcome_posteriors(memory, 10, seed=2))
    g = Grid2D(MATS, (3, 3))
    with pytest.raises(ValidationError, match="needs a voxel map"):
        voxel_accuracy_gain(g, g, table)


def test_with_lateral_filling_a_layer_is_scored_as_a_2d_map(memory):
    table = outcome_table(outcome_posteriors(memory, 30, seed=2))
    rng = np.random.default_rng(5)
    v = VoxelGrid(MATS, (6, 5, 1), cell_size=0.005)
    g = Grid2D(MATS, (6, 5), cell_size=0.005)
    for _ in range(8):
        ix, iy, p = int(rng.integers(6)), int(rng.integers(5)), rng.dirichlet([0.4, 0.4, 0.4])
        v.update_voxel(ix, iy, 0, p)
        g.update_cell(ix, iy, p)
    lateral = voxel_accuracy_gain(v, v.postprocessed(lateral=True), table, lateral=True)
    # one layer: the same expected gain as the same cells on a 2-D map (brute-force checked in
    # test_expected_accuracy), and a press also helps its unexplored neighbours, so it is worth more than alone
    assert lateral == pytest.approx(expected_accuracy_gain(g, g.postprocessed(), table, reach=2, correlation_cells=1.0))
    alone = voxel_accuracy_gain(v, v.postprocessed(), table)
    free = ~np.asarray(g.explored)
    assert lateral[free].sum() > alone[free].sum()


def test_scenario_lateral_extrapolation_is_for_voxel_maps_only():
    from palpate.core.world.scenario_file import parse_scenario

    raw = {"scenario": {"name": "v", "seed": 1, "fidelity": "analytic"},
           "materials": [{"name": "soft", "young_kpa": 20.0}, {"name": "hard", "young_kpa": 450.0}],
           "exploration": {"policy": "raster", "budget": 2, "map": "voxel", "lateral_extrapolation": True},
           "objects": [{"name": "o", "size_mm": [30.0, 20.0, 30.0], "position_mm": [15.0, 10.0], "material": "soft"}]}
    assert parse_scenario(raw, "v.toml").exploration.voxel_lateral
    raw["exploration"]["map"] = "grid2d"
    with pytest.raises(ValidationError, match="v.toml: exploration.lateral_extrapolation: fills voxels"):
        parse_scenario(raw, "v.toml")
