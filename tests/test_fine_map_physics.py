"""The fine map on the shipped heterogeneous scene with physics presses (the image rung near walls)."""

from __future__ import annotations

import numpy as np
import pytest

from palpate.api import load_scenario
from palpate.core.session.run import run_scenario

pytestmark = pytest.mark.physics


def test_heterogeneous_scene_fine_map_beats_the_cell_map(tmp_path):
    summary = run_scenario(load_scenario("heterogeneous"), tmp_path / "run")
    (obj,) = summary["objects"]
    fine = obj["fine_map"]
    assert fine["walls_read"] >= 8
    area = fine["area_accuracy"]
    assert area["fine_map"] >= 0.88 and area["fine_map"] >= area["cell_map"] + 0.05
    err = fine["boundary_error_m"]
    assert err["fine_map"]["median"] <= 1e-3 < err["cell_map"]["median"]
    # the buried lump (20 x 20 mm, its top 1 mm under the foam band) is a region of the fine map of about its
    # footprint, centred within 5 mm of it (it is felt through the foam, so as whichever material that feels like)
    lump = load_scenario("heterogeneous").objects[0].spec.inclusions[0]
    footprint = lump.size[0] * lump.size[1]
    found = [r for r in fine["material_regions"] if 0.25 * footprint <= r["area_m2"] <= 2 * footprint
             and np.hypot(*(np.array(r["centroid_m"]) - lump.center[:2])) <= 5e-3]
    assert len(found) == 1


def test_the_boundary_policy_maps_the_heterogeneous_scene_with_a_quarter_of_the_presses(tmp_path):
    from palpate.api import with_settings

    sc = with_settings(load_scenario("heterogeneous"), exploration={"policy": "boundary", "budget": 24})
    (obj,) = run_scenario(sc, tmp_path / "run")["objects"]
    assert obj["presses"] == 24 and obj["policy"] == "boundary"
    fine = obj["fine_map"]
    area = fine["area_accuracy"]
    # a full raster (96 presses) gets 0.91 of the area; the cell map of these 24 presses about 0.66
    assert area["fine_map"] >= 0.75 and area["fine_map"] >= area["cell_map"] + 0.08
    # the walls it read: the fine map's median boundary error well under the cell map's (measured 5.0 against 9.0 mm)
    err = fine["boundary_error_m"]
    assert err["fine_map"]["median"] < 0.65 * err["cell_map"]["median"]


def test_the_heterogeneous_lump_feels_like_rubber_by_the_3d_fe_and_the_law_agrees():
    # why the map names the buried box Material_2: it rides on 9 mm of foam, so a press over its middle gives
    # about a rubber block's force, not the hard material's (the map's Material_2 region over it is right)
    from palpate.sim.validity.offaxis import buried_box_press

    sc = load_scenario("heterogeneous")
    obj = sc.objects[0].spec
    press = buried_box_press(obj, obj.inclusions[0], sc.fingertip.radius, np.array([1.0, 2.0, 3.0, 4.0]) * 1e-3,
                             {m: sc.materials[m].material for m in ("Material_2", "Material_3")})
    # the FE's block: the hard box in the foam band around it, its top 1 mm under the same foam (no other skin)
    assert press.block.material.name == "foam_A" and press.block.skin is None
    assert press.block.lump.material.name == "hard_C" and press.block.lump.depth == pytest.approx(1e-3)
    np.testing.assert_allclose(press.law, press.fe, rtol=0.06)
    rubber, hard = (np.mean(np.log(press.fe / press.plain[m])) for m in ("Material_2", "Material_3"))
    assert abs(rubber) < 0.5 < abs(hard)
