"""Seed 002 haptic-material maps: quantisation, round trip, validation, and the seed's Table 3 inconsistencies."""

import json

import numpy as np
import pytest

from palpate.core.errors import ValidationError
from palpate.core.world.haptic_material import (
    ABSENT_FEATURES,
    CONTACT_AREA_SPREAD_RATE,
    LOCAL_INDENTATION,
    MEASURED_FEATURES,
    RATE_HARDNESS,
    HapticMaterialMap,
)

MATERIALS = ["Material_1", "Material_2", "Material_3"]


def _random_map(rng, ny=7, nx=9):
    p = rng.dirichlet(np.ones(3), size=(ny, nx))
    feats = {
        "rate_hardness": rng.uniform(0, 10000, (ny, nx)),
        "contact_area_spread_rate": rng.uniform(0, 25.5e4, (ny, nx)),  # SI: Pa (N/m^2)
        "local_indentation": rng.uniform(-5e-3, 5e-3, (ny, nx)),
    }
    measured = rng.random((ny, nx)) > 0.3
    return HapticMaterialMap((0.01, -0.02), 0.005, MATERIALS, p, feats, measured, meta={"object": "o1"})


def test_round_trip_within_one_quantisation_step(tmp_path, rng):
    hm = _random_map(rng)
    hm.write(tmp_path / "hm")
    back = HapticMaterialMap.read(tmp_path / "hm")
    assert back.materials == MATERIALS
    assert back.shape == hm.shape
    np.testing.assert_array_equal(back.measured, hm.measured)
    assert back.origin == pytest.approx(hm.origin) and back.cell_size == pytest.approx(hm.cell_size)
    # Probabilities: each stored to 1/255, then renormalised; half a step per entry, a few entries per cell.
    assert np.max(np.abs(back.probabilities - hm.probabilities)) <= 2.0 / 255.0
    for name, spec in MEASURED_FEATURES.items():
        step_si = spec.resolution * spec.si_scale
        err = np.abs(back.features[name] - hm.features[name])[hm.measured]
        assert err.max() <= step_si / 2 + 1e-12, name


def test_image_is_a_top_view(tmp_path):
    from PIL import Image

    p = np.full((2, 3, 3), 1 / 3)
    p[1, 0] = [1.0, 0.0, 0.0]  # largest y, smallest x -> top-left pixel
    HapticMaterialMap((0.0, 0.0), 0.01, MATERIALS, p).write(tmp_path)
    img = np.asarray(Image.open(tmp_path / "material_probability_Material_1.png"))
    assert img[0, 0] == 255 and img[1, 0] == 85


def test_material_lookup_by_position():
    p = np.zeros((2, 2, 3))
    p[..., 0] = 1.0
    p[1, 1] = [0.0, 0.2, 0.8]
    measured = np.array([[True, True], [False, True]])
    hm = HapticMaterialMap((0.0, 0.0), 0.01, MATERIALS, p, measured=measured)
    names = hm.material_names_at(np.array([[0.005, 0.005], [0.015, 0.015], [0.005, 0.015], [0.5, 0.5]]))
    assert names == ["Material_1", "Material_3", None, None]


def test_table3_ranges_fit_in_eight_bits():
    for spec in (RATE_HARDNESS, CONTACT_AREA_SPREAD_RATE, LOCAL_INDENTATION):
        assert spec.levels <= 256, spec.name
    # Seed 002 Table 3 writes 0-25.6 N/cm^2 in 0.1 steps: 257 codes, one more than 8 bits hold.
    assert round(25.6 / 0.1) + 1 == 257
    assert CONTACT_AREA_SPREAD_RATE.hi == pytest.approx(25.5)
    # ...and the local surface orientation at 0.002 deg over 180 deg would need 90001 codes, not 256.
    assert round(180 / 0.002) + 1 > 256
    assert "0.002" in ABSENT_FEATURES["local_surface_orientation"]["resolution_in_seed"]


def test_values_outside_the_range_are_clipped_and_counted(tmp_path):
    feats = {"local_indentation": np.array([[0.008, 0.001]])}
    hm = HapticMaterialMap((0.0, 0.0), 0.01, [], None, feats)
    hm.write(tmp_path)
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    assert manifest["maps"]["local_indentation"]["clipped_cells"] == 1
    back = HapticMaterialMap.read(tmp_path)
    assert back.features["local_indentation"][0, 0] == pytest.approx(0.005)
    assert set(manifest["absent"]) >= {"kinetic_friction", "static_friction", "relative_temperature"}


def test_bad_folders_are_rejected_with_the_key(tmp_path, rng):
    with pytest.raises(ValidationError, match="manifest.json"):
        HapticMaterialMap.read(tmp_path)
    _random_map(rng).write(tmp_path)
    mpath = tmp_path / "manifest.json"
    manifest = json.loads(mpath.read_text())
    manifest["version"] = 99
    mpath.write_text(json.dumps(manifest))
    with pytest.raises(ValidationError, match="version"):
        HapticMaterialMap.read(tmp_path)
    manifest["version"] = 1
    manifest["shape"] = [3, 3]
    mpath.write_text(json.dumps(manifest))
    with pytest.raises(ValidationError, match="does not match manifest shape"):
        HapticMaterialMap.read(tmp_path)
    mpath.write_text("{not json")
    with pytest.raises(ValidationError, match="manifest.json:1: not valid JSON"):
        HapticMaterialMap.read(tmp_path)


def test_nan_never_enters_a_map():
    with pytest.raises(ValidationError, match="NaN"):
        HapticMaterialMap((0, 0), 0.01, [], None, {"rate_hardness": np.array([[np.nan]])})
    with pytest.raises(ValidationError, match="finite"):
        HapticMaterialMap((0, 0), 0.01, ["a"], np.array([[[np.inf]]]))
