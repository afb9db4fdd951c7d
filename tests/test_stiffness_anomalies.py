"""Spots harder or softer than the map says: presses over a lump under one material make one spot where it lies; a
wall at the surface that the map shows makes none; bad input is refused by name."""

from __future__ import annotations

import numpy as np
import pytest

from palpate.core.boundary.moduli import MaterialModuli
from palpate.core.boundary.reading import BoundaryReading
from palpate.core.errors import ValidationError
from palpate.core.mapping import anomalies
from palpate.core.mapping.anomalies import stiffness_anomalies
from palpate.core.mapping.geometry import MapGeometry, plane_probabilities

MATERIALS = ("soft", "medium", "hard")
MODULI = MaterialModuli(MATERIALS, np.array([0.0, 1.7, 3.1]), np.array([0.15, 0.15, 0.15]))
GEOMETRY = MapGeometry("grid2d", MATERIALS, (0.0, 0.0), 0.01, (8, 6))


def _reading(log_plain: float, p_plain: float = 0.9) -> BoundaryReading:
    return BoundaryReading(p_boundary=1.0 - p_plain, angle=0.0, angle_sd=0.1, offset=0.0, offset_sd=1e-3,
                           contrast=2.0, reach=5.5e-3, posterior=np.full((1, 1), 1.0 - p_plain), p_plain=p_plain,
                           angles=np.zeros(1), offsets=np.zeros(1), log_plain=log_plain)


def _map(labels: np.ndarray) -> np.ndarray:
    p = np.full(labels.shape + (3,), 0.05)
    for m in range(3):
        p[labels == m, m] = 0.9
    return p


def _raster(log_plain_at, p_plain_at=lambda x, y: 0.9):
    """One press at every cell centre: (location, reading)."""
    out = []
    for iy in range(6):
        for ix in range(8):
            x, y = 0.005 + 0.01 * ix, 0.005 + 0.01 * iy
            out.append(((x, y), _reading(log_plain_at(x, y), p_plain_at(x, y))))
    return out


def test_presses_over_a_buried_lump_make_one_harder_spot_where_it_lies():
    labels = np.ones((6, 8), dtype=int)  # the map names medium everywhere
    lump = {(0.035, 0.025), (0.045, 0.025), (0.035, 0.035)}  # three presses read 4-5 spreads harder
    readings = _raster(lambda x, y: 1.7 + (0.7 if (round(x, 3), round(y, 3)) in lump else 0.05 * np.sin(40 * x)),
                       lambda x, y: 0.1 if (round(x, 3), round(y, 3)) in lump else 0.9)  # asymmetric images
    spots = stiffness_anomalies(GEOMETRY, _map(labels), readings, MODULI)
    assert len(spots) == 1
    spot = spots[0]
    assert spot.sign == "harder" and spot.material == "medium" and spot.presses == 3
    assert spot.z == pytest.approx(0.7 / 0.15)
    assert spot.centroid_m == pytest.approx((0.115 / 3, 0.085 / 3))
    # a softer lump elsewhere is a spot of its own; on the map's rim a softer press is the object's free edge
    inner, rim = 4 * 8 + 1, 0  # cells (1, 4) and (0, 0)
    readings[inner] = (readings[inner][0], _reading(1.0))
    readings[rim] = (readings[rim][0], _reading(1.0))
    spots = stiffness_anomalies(GEOMETRY, _map(labels), readings, MODULI)
    assert sorted((s.sign, s.centroid_m) for s in spots)[1] == ("softer", pytest.approx((0.015, 0.045)))
    assert len(spots) == 2
    readings[rim] = (readings[rim][0], _reading(2.4))
    assert len(stiffness_anomalies(GEOMETRY, _map(labels), readings, MODULI)) == 3  # a harder one there counts


def test_a_wall_the_map_shows_makes_no_spot_and_nor_does_a_material_read_as_itself():
    labels = np.ones((6, 8), dtype=int)
    labels[:, 4:] = 2  # medium | hard wall at x = 40 mm
    # presses beside the wall read in between (a wall's image), those elsewhere as their own material
    readings = _raster(lambda x, y: 2.4 if 0.03 < x < 0.05 else (1.7 if x < 0.04 else 3.1),
                       lambda x, y: 0.0 if 0.03 < x < 0.05 else 0.9)
    assert stiffness_anomalies(GEOMETRY, _map(labels), readings, MODULI) == []
    # the same in-between reading where the map shows no wall and the image looks like one material is a spot
    readings = _raster(lambda x, y: 2.4 if 0.03 < x < 0.05 else (1.7 if x < 0.04 else 3.1))
    assert {s.sign for s in stiffness_anomalies(GEOMETRY, _map(labels), readings, MODULI)} == {"harder", "softer"}


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"probabilities": np.zeros((6, 8, 2))}, r"\(6, 8, 3\)"),
    ({"z_min": 0.0}, "z_min"),
    ({"pool_z_min": 0.0}, "pool_z_min"),
    ({"pool_z_min": float("nan")}, "pool_z_min"),
    ({"probabilities": np.full((6, 8, 3), np.nan)}, "finite"),
    ({"geometry": MapGeometry("voxel", MATERIALS, (0.0, 0.0), 0.01, (8, 6, 2), z_top=0.03)}, "2-D"),
    ({"edge_reach": -1e-3}, "edge_reach"),
    ({"edge_reach": float("inf")}, "edge_reach"),
])
def test_bad_input_is_refused_by_name(kwargs, match):
    args = {"geometry": GEOMETRY, "probabilities": _map(np.ones((6, 8), dtype=int)), "readings": [],
            "moduli": MODULI} | kwargs
    with pytest.raises(ValidationError, match=match):
        stiffness_anomalies(**args)


def test_the_run_report_names_the_strongest_spots_and_counts_the_rest():
    from palpate.core.cli.run import _fine_map_lines

    spots = [{"sign": "harder" if k % 2 else "softer", "centroid_m": [0.01 * k, 0.02], "z": 9.0 - k}
             for k in range(6)]
    (line,) = _fine_map_lines({"stiffness_anomalies": spots}, most=4)
    assert line.count(" at (") == 4 and "and 2 more" in line and "softer at (0.0, 2.0) cm" in line
    spots[1]["lump"] = {"material": "hard", "top_m": 0.0031}
    (line,) = _fine_map_lines({"stiffness_anomalies": spots}, most=4)
    assert "harder at (1.0, 2.0) cm (hard from 3.1 mm down)" in line and line.count("mm down") == 1
    assert _fine_map_lines({"stiffness_anomalies": []}) == []


def test_spots_are_recorded_as_scene_entities_that_a_replay_reads_past(tmp_path):
    import json

    from mcap.reader import make_reader

    from palpate.core.io.mcap_reader import read_recording
    from palpate.core.io.mcap_writer import RecordingWriter

    spots = [{"sign": "harder", "material": "medium", "presses": 3, "centroid_m": [0.035, 0.025], "z": 4.7,
              "lump": {"material": "hard", "top_m": 0.0025, "shape": "layer", "radius_m": 0.0, "rms_log": 0.05,
                       "rms_log_plain": 0.4}},
             {"sign": "softer", "material": "medium", "presses": 1, "centroid_m": [0.015, 0.045], "z": -4.7}]
    path = tmp_path / "spots.mcap"
    with RecordingWriter(path, {"scenario": "spots"}) as writer:
        writer.write_spots(2.0, "slab", spots, 0.03)
    with open(path, "rb") as f:
        (msg,) = [(c.topic, s.name, json.loads(m.data)) for s, c, m in make_reader(f).iter_messages()]
    topic, schema, update = msg
    assert (topic, schema) == ("/spots/slab", "foxglove.SceneUpdate")
    harder, softer = update["entities"]
    assert harder["id"] == "spot/slab/0" and harder["cubes"][0]["pose"]["position"]["x"] == pytest.approx(0.035)
    assert harder["cubes"][0]["color"]["r"] > harder["cubes"][0]["color"]["b"]  # red
    assert softer["cubes"][0]["color"]["b"] > softer["cubes"][0]["color"]["r"]  # blue
    assert softer["texts"][0]["text"] == "softer -4.7" and len(softer["cubes"]) == 1
    # the lump a spot reads: its material and depth in the text, a second marker at its top
    assert harder["texts"][0]["text"] == "harder +4.7, hard from 2.5 mm"
    assert harder["cubes"][1]["pose"]["position"]["z"] == pytest.approx(0.03 - 0.0025 - 0.001)
    assert read_recording(path).frames == []  # a view: the reader skips it


def test_a_voxel_maps_read_lump_is_recorded_as_boxes_under_its_spots_presses(tmp_path):
    import json

    from mcap.reader import make_reader

    from palpate.core.io.mcap_writer import RecordingWriter

    spot = {"sign": "harder", "material": "medium", "presses": 2, "centroid_m": [0.0375, 0.025], "z": 4.7,
            "press_locations_m": [[0.035, 0.025], [0.04, 0.025]],
            "lump": {"material": "hard", "top_m": 0.003, "top_sd_m": 0.002, "p_material": 0.5, "shape": "sphere",
                     "radius_m": 0.008, "rms_log": 0.05, "rms_log_plain": 0.4}}
    path = tmp_path / "spots.mcap"
    with RecordingWriter(path, {"scenario": "spots"}) as writer:
        writer.write_spots(2.0, "block", [spot], 0.03, footprint=(0.005, 0.01))
        writer.write_spots(3.0, "slab", [spot], 0.03)
    with open(path, "rb") as f:
        voxel, plane = (json.loads(m.data)["entities"][0] for _, _, m in make_reader(f).iter_messages())
    boxes = voxel["cubes"][2:]
    assert len(boxes) == 2 and len(plane["cubes"]) == 2  # a 2-D map's spot keeps its two markers
    for box, (x, y) in zip(boxes, spot["press_locations_m"], strict=True):
        assert box["size"] == pytest.approx({"x": 0.005, "y": 0.005, "z": 0.007})  # from 3 mm down to 10 mm
        at = box["pose"]["position"]
        assert (at["x"], at["y"], at["z"]) == pytest.approx((x, y, 0.03 - 0.0065))
        assert box["color"]["a"] == pytest.approx(0.2)


def test_a_voxel_maps_spots_are_those_of_its_surface_layer_as_a_2d_map():
    labels = np.ones((6, 8), dtype=int)
    # a lump under the press at (45, 25) mm; the press at (35, 25) mm reads hard, as its surface voxel says
    read = {(0.045, 0.025): 2.4, (0.035, 0.025): 3.1}
    readings = _raster(lambda x, y: read.get((round(x, 3), round(y, 3)), 1.7))
    voxels = MapGeometry("voxel", MATERIALS, (0.0, 0.0), 0.01, (8, 6, 3), z_top=0.04)
    plane = voxels.plane()
    assert plane == GEOMETRY and GEOMETRY.plane() is GEOMETRY
    probs = np.zeros((8, 6, 3, 3))
    probs[:, :, 0] = np.transpose(_map(labels), (1, 0, 2))  # [ix, iy, iz]: the surface layer names medium
    probs[:, :, 1:] = _map(np.full((8, 6), 2))[:, :, None, :]  # deeper layers say hard: not the surface's
    probs[3, 2, 0] = [0.1, 0.1, 0.8]  # one surface voxel (ix 3, iy 2) names hard
    surface = plane_probabilities(probs)
    assert surface.shape == (6, 8, 3) and np.argmax(surface[2, 3]) == 2 and np.argmax(surface[3, 2]) == 1
    assert np.array_equal(plane_probabilities(surface), surface)  # a 2-D map is its own plane
    two_d = _map(labels)
    two_d[2, 3] = [0.1, 0.1, 0.8]
    assert np.array_equal(surface, two_d)
    spots = stiffness_anomalies(plane, surface, readings, MODULI)
    assert spots == stiffness_anomalies(GEOMETRY, two_d, readings, MODULI)
    # one spot, the lump's: a deeper layer or a transposed surface would make the hard press or every press one
    assert [(s.sign, s.presses, s.centroid_m) for s in spots] == [("harder", 1, pytest.approx((0.045, 0.025)))]
    with pytest.raises(ValidationError, match="2-D maps only"):
        stiffness_anomalies(voxels, probs, readings, MODULI)


def test_a_softer_press_within_a_contact_radius_of_the_maps_edge_is_the_objects_edge():
    labels = np.ones((6, 8), dtype=int)
    # one cell in from the rim (its centre 15 mm from the left edge) and one in the middle read softer
    read = {(0.015, 0.025): 1.0, (0.045, 0.035): 1.0, (0.045, 0.015): 2.4}
    readings = _raster(lambda x, y: read.get((round(x, 3), round(y, 3)), 1.7))
    signs = lambda **kw: sorted((s.sign, tuple(np.round(s.centroid_m, 6))) for s in stiffness_anomalies(  # noqa: E731
        GEOMETRY, _map(labels), readings, MODULI, **kw))
    assert signs() == signs(edge_reach=0.0149) == [("harder", (0.045, 0.015)), ("softer", (0.015, 0.025)),
                                                  ("softer", (0.045, 0.035))]
    # a press as deep as to reach 15 mm feels the edge: its softness is the edge's, not a lump's; harder still counts
    assert signs(edge_reach=0.0151) == [("harder", (0.045, 0.015)), ("softer", (0.045, 0.035))]
    assert signs(edge_reach=0.0351) == [("harder", (0.045, 0.015))]


@pytest.mark.parametrize("value", ["5 mm", -0.001, float("nan"), True, [0.01]])
def test_a_recordings_edge_reach_is_read_or_refused_by_name(value):
    from palpate.core.session.boundaries import EDGE_KEY, replay_edge_reach

    assert replay_edge_reach({}, "rec.mcap") == 0.0  # recorded before it was kept: the rim cells alone
    assert replay_edge_reach({EDGE_KEY: 0.0089}, "rec.mcap") == 0.0089
    with pytest.raises(ValidationError, match=f"rec.mcap: metadata {EDGE_KEY}"):
        replay_edge_reach({EDGE_KEY: value}, "rec.mcap")


def test_a_deeper_lump_that_moves_each_press_a_little_makes_a_spot_with_its_neighbours():
    labels = np.ones((6, 8), dtype=int)
    # six neighbouring presses read 2.3-2.9 spreads harder (none reaches Z_MIN alone), 0.3 of which every press
    # reads, as exploration presses may read a little apart from the training presses: that is no lump
    lump = {(0.025, 0.025): 2.0, (0.035, 0.025): 2.6, (0.045, 0.025): 2.2,
            (0.025, 0.035): 2.1, (0.035, 0.035): 2.4, (0.045, 0.035): 2.3}
    offset = 0.3 * 0.15
    readings = _raster(lambda x, y: 1.7 + offset + 0.15 * lump.get((round(x, 3), round(y, 3)),
                                                                   0.2 * np.sin(90 * x + 50 * y)))
    (spot,) = stiffness_anomalies(GEOMETRY, _map(labels), readings, MODULI)
    assert spot.sign == "harder" and spot.presses == 6 and spot.z == pytest.approx(2.6 + 0.3)
    assert spot.centroid_m == pytest.approx((0.035, 0.03), abs=1e-3)
    assert stiffness_anomalies(GEOMETRY, _map(labels), readings, MODULI, pool_z_min=np.inf) == []
    # one such press alone is not enough
    one = _raster(lambda x, y: 1.7 + offset + 0.15 * (2.0 if (round(x, 3), round(y, 3)) == (0.035, 0.025) else 0.0))
    assert stiffness_anomalies(GEOMETRY, _map(labels), one, MODULI) == []
    # a softer lump leaning as much is not pooled (softer leans make as many stray spots as lumps)
    soft = _raster(lambda x, y: 1.7 - 0.15 * lump.get((round(x, 3), round(y, 3)), 0.2 * np.sin(90 * x + 50 * y)))
    assert stiffness_anomalies(GEOMETRY, _map(labels), soft, MODULI) == []
    # on the map's rim a softer lean is the object's edge, pooled or not
    rim = _raster(lambda x, y: 1.7 - 0.15 * (2.0 if x < 0.02 else 0.0))
    assert stiffness_anomalies(GEOMETRY, _map(labels), rim, MODULI, edge_reach=0.0151) == []


def test_pooled_evidence_is_each_press_summed_with_its_same_material_neighbours():
    # against a plain double loop over presses: the pooled sum and count over neighbours within the radius
    rng = np.random.default_rng(7)
    for _ in range(40):
        n = int(rng.integers(2, 50))
        xy = rng.uniform(0.0, 0.05, (n, 2))
        xy[: n // 4] = xy[n // 4: 2 * (n // 4)]  # some presses repeated at one place
        named, z = rng.integers(0, 3, n), rng.normal(0.8, 1.5, n)
        eligible = rng.random(n) < 0.8
        centred = z.copy()
        for m in np.unique(named[eligible]):
            of = eligible & (named == m)
            if of.sum() >= anomalies.POOL_CENTRE_MIN:
                centred[of] -= np.median(z[of])
        want = np.zeros(n, dtype=bool)
        if eligible.sum() >= 2:
            for i in np.flatnonzero(eligible):
                near = [j for j in np.flatnonzero(eligible) if named[j] == named[i]
                        and np.hypot(*(xy[j] - xy[i])) <= 0.0075]
                evidence = centred[near].sum() / np.sqrt(len(near))
                want[i] = centred[i] >= anomalies.POOL_PRESS_Z and evidence >= 2.5 and z[i] > 0
        np.testing.assert_array_equal(anomalies._pooled(xy, named, z, eligible, 0.0075, 2.5), want)
