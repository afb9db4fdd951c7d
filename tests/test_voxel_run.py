"""Seed 001 in simulation: a voxel map from presses, evidence per layer, and an exact replay."""

import json
import tomllib
from pathlib import Path

import numpy as np
import pytest

from palpate.core.cli import main
from palpate.core.mapping.grids import VoxelGrid
from palpate.core.perception.layered_memory import layer_fits
from palpate.core.session.run import run_scenario
from palpate.core.world.scenario_file import parse_scenario

SCENARIO = Path(__file__).resolve().parent.parent / "scenarios" / "volumetric.toml"


@pytest.fixture(scope="module")
def voxel_run(tmp_path_factory):
    raw = tomllib.loads(SCENARIO.read_text())
    raw["exploration"]["budget"] = 24
    raw["outputs"] = {"figures": False, "haptic_material": False, "render_3d": False}
    scenario = parse_scenario(raw, str(SCENARIO))
    out = tmp_path_factory.mktemp("voxels")
    return scenario, run_scenario(scenario, out, record=out / "rec.mcap"), out


def test_presses_fill_columns_down_to_their_depth_and_read_as_the_soft_material(voxel_run):
    scenario, summary, out = voxel_run
    grid = VoxelGrid.load(out / "maps" / "Object_1.npz")
    explored = np.asarray(grid.explored)
    cols = explored.any(axis=2)
    assert cols.sum() == 24  # the random policy prefers unexplored columns
    # columns are explored from their first explored layer down, without gaps, and (but for a press where the soft
    # object's edges leave too little contact in the first layer for a cutaneous fit) from the surface
    tops = 0
    for ix, iy in np.argwhere(cols):
        col = explored[ix, iy].astype(int)
        first = int(np.argmax(col))
        assert not np.any(np.diff(col[first:]) > 0)
        tops += bool(col[0])
    # the object is 20 mm across and a 10 mm press's contact is ~16 mm wide, so from every column it reaches the
    # sides, which the contact law feels (softer, less contact); most columns still start at the surface
    assert tops >= 0.8 * cols.sum()
    obj = summary["objects"][0]
    assert obj["accuracy"]["explored_before_postprocessing"] >= 0.95
    ent = obj["mean_entropy_after_each_press"]
    assert ent[len(ent) // 2 - 1] > ent[-1]  # the entropy falls from 50% to 100% of the exploration
    # where the map says the materials lie, in 3-D: the largest region is the object's, from the surface down
    largest = obj["material_regions"][0]
    assert largest["material"] == obj["true_materials"][0] and largest["top_depth_m"] == 0.0
    assert largest["voxels"] <= int(np.sum(np.ptp(VoxelGrid.load(out / "maps" / "Object_1_postprocessed.npz")
                                                  .probabilities, axis=-1) > 0))


def test_replay_rebuilds_the_voxel_map_exactly(voxel_run, tmp_path):
    _, _, out = voxel_run
    assert main(["replay", str(out / "rec.mcap"), "--memory", str(out / "memory.json"), "--out", str(tmp_path),
                 "--quiet", "--no-figures"]) == 0
    a = VoxelGrid.load(out / "maps" / "Object_1.npz")
    b = VoxelGrid.load(tmp_path / "maps" / "Object_1.npz")
    np.testing.assert_array_equal(a.probabilities, b.probabilities)
    run, replayed = (json.loads((d / "summary.json").read_text())["objects"][0] for d in (out, tmp_path))
    assert replayed["material_regions"] == run["material_regions"] and run["material_regions"]
    # the surface layer's fine map and its stiffness spots, replayed from the recorded presses' images
    assert run["fine_map"]["presses_read"] == replayed["fine_map"]["presses_read"] == 24
    assert replayed["fine_map"]["stiffness_anomalies"] == run["fine_map"]["stiffness_anomalies"]
    with np.load(out / "maps" / "Object_1_fine.npz") as ran, np.load(tmp_path / "maps" / "Object_1_fine.npz") as again:
        np.testing.assert_array_equal(again["probabilities"], ran["probabilities"])
        assert ran["probabilities"].shape[:2] == (16, 16)  # 20 mm at the fine raster's 1.25 mm (of 2.5 mm voxels)
    # the lump layer under it: 15 mm deep in cubes of the fine raster's side
    ran_layer, replayed_layer = run["fine_map"]["lump_layer"], replayed["fine_map"]["lump_layer"]
    truth_only = ("volume_accuracy", "below_surface_accuracy", "calibration_ece")
    assert replayed_layer == {k: v for k, v in ran_layer.items() if k not in truth_only}
    # against the truth (a run only): no spot, so the layer is the plain block the surface says, as the map
    assert ran_layer["lumps"] == 0 and "below_surface_accuracy" not in ran_layer
    assert ran_layer["volume_accuracy"] == {"voxel_map": 1.0, "lump_layer": 1.0}
    assert ran_layer["calibration_ece"]["all"] < 0.01 and "under_spots" not in ran_layer["calibration_ece"]
    lumps = "maps/Object_1_lumps.npz"
    with np.load(out / lumps) as ran, np.load(tmp_path / lumps) as again:
        np.testing.assert_array_equal(again["probabilities"], ran["probabilities"])
        assert ran["probabilities"].shape[:3] == (16, 16, 12)


def test_layer_fits_cut_the_press_at_each_layer():
    # a synthetic press following c_P = 20 (c_D mm)^1.5 exactly, with a growing contact area
    c_D = np.linspace(0.0, 0.006, 61)
    c_P = 20.0 * (c_D * 1e3) ** 1.5
    c_A = 1e-5 + 2e-3 * c_D
    fits = layer_fits(np.arange(61) * 0.02, c_P, c_A, c_D, cell=0.0025, n_layers=6)
    assert len(fits) == 3  # 6 mm reaches layers 0, 1 and 2 of 2.5 mm
    for params in fits:
        assert params is not None and params[0] == pytest.approx(20.0, rel=1e-6)


def test_a_lump_layer_beyond_the_cube_limit_is_skipped_with_its_reason(monkeypatch):
    from palpate.core.mapping.fine import FineMap
    from palpate.core.mapping.geometry import MapGeometry
    from palpate.core.session.boundaries import voxel_lump_layer

    geometry = MapGeometry("voxel", ("a", "b"), (0.0, 0.0), 5e-3, (4, 4, 2), z_top=0.05)
    fine = FineMap((0.0, 0.0), 1e-3, np.full((20, 20, 2), 0.5), ("a", "b"))
    layer, summary = voxel_lump_layer(geometry, fine, {"stiffness_anomalies": []})
    assert layer.probabilities.shape == (20, 20, 10, 2) and summary["lumps"] == 0
    monkeypatch.setenv("PALPATE_LIMITS", "map_cells=3999")
    layer, summary = voxel_lump_layer(geometry, fine, {"stiffness_anomalies": []})
    assert layer is None and "4000 cubes, beyond the limit map_cells" in summary["skipped"]
