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
    from palpate.core.world.scene import ObjectSpec, material_at
    from palpate.sim.contact.stack import object_law
    from palpate.sim.reference.fe3d import BoxBlock, BoxLump
    from palpate.sim.reference.fe3d_solve import fe3d_press

    sc = load_scenario("heterogeneous")
    obj = sc.objects[0].spec
    lump = obj.inclusions[0]
    (cx, cy, cz), (sx, sy, sz) = lump.center, lump.size
    top = obj.height - cz - sz / 2
    (foam,) = material_at(obj, np.array([[cx + sx / 2 + 3e-3, cy, cz]]))
    assert foam.name == "foam_A"
    depths = np.array([1.0, 2.0, 3.0, 4.0]) * 1e-3
    tip = sc.fingertip.radius
    fe = fe3d_press(BoxBlock(foam, obj.height, 0.03, 0.03, BoxLump(lump.material, -sx / 2, sx, sy, top, sz)),
                    tip, depths).force
    law = object_law(obj, cx, cy, obj.height, tip, float(depths[-1])).force_at(depths)
    np.testing.assert_allclose(law, fe, rtol=0.06)

    def plain(name):
        block = ObjectSpec("plain", "box", (0.06, 0.06, obj.height), (0.0, 0.0), sc.materials[name].material)
        return object_law(block, 0.0, 0.0, obj.height, tip, float(depths[-1])).force_at(depths)

    rubber, hard = (np.mean(np.log(fe / plain(m))) for m in ("Material_2", "Material_3"))
    assert abs(rubber) < 0.5 < abs(hard)
