"""Ground-truth material lookup of plain scene descriptions."""

import numpy as np
import pytest

from palpate.core.errors import ValidationError
from palpate.core.world.scene import FingertipSpec, Inclusion, Layer, Material, ObjectSpec, material_index_at

SOFT = Material("soft", 20e3)
HARD = Material("hard", 2e6)
MID = Material("medium", 200e3)


def test_layers_and_inclusions_are_resolved_in_order():
    obj = ObjectSpec(
        "block", "box", (0.1, 0.1, 0.04), (0.0, 0.0), SOFT,
        layers=(Layer(MID, 0.01),),
        inclusions=(Inclusion(HARD, "sphere", (0.02, 0.0, 0.02), (0.005,)),),
    )
    names = ["soft", "medium", "hard"]
    pts = np.array([
        [0.0, 0.0, 0.035],   # in the top layer
        [0.0, 0.0, 0.02],    # bulk
        [0.02, 0.0, 0.02],   # inclusion centre
        [0.2, 0.0, 0.02],    # outside the footprint
        [0.0, 0.0, 0.05],    # above the top
    ])
    assert material_index_at(obj, pts, names).tolist() == [1, 0, 2, -1, -1]


def test_bad_descriptions_are_rejected_with_the_key():
    with pytest.raises(ValidationError, match="young"):
        Material("x", -1.0)
    with pytest.raises(ValidationError, match="poisson"):
        Material("x", 1e5, poisson=0.5)
    with pytest.raises(ValidationError, match="size"):
        ObjectSpec("o", "box", (0.1, 0.1), (0, 0), SOFT)
    with pytest.raises(ValidationError, match="sensel_size"):
        FingertipSpec(pitch=0.003, sensel_size=0.004)


def test_sensel_centres_are_symmetric_about_the_axis():
    c = FingertipSpec().sensel_centres()
    assert c.shape == (4, 4, 2)
    np.testing.assert_allclose(c.reshape(-1, 2).mean(axis=0), 0.0, atol=1e-15)
    assert c[0, 0, 1] > c[-1, 0, 1]  # row 0 is at +y


def test_a_material_map_sets_the_surface_material_and_its_materials_must_be_defined():
    from palpate.core.world.haptic_material import HapticMaterialMap

    p = np.zeros((1, 2, 2))
    p[0, 0] = [1, 0]
    p[0, 1] = [0, 1]
    hm = HapticMaterialMap((0.0, 0.0), 0.05, ["soft", "hard"], p)
    obj = ObjectSpec("o", "box", (0.1, 0.05, 0.02), (0.05, 0.025), MID, material_map=hm, map_materials=(SOFT, HARD))
    assert [m.name for m in obj.materials()] == ["medium", "soft", "hard"]
    idx = material_index_at(obj, np.array([[0.02, 0.02, 0.019], [0.07, 0.02, 0.019]]), ["soft", "medium", "hard"])
    assert idx.tolist() == [0, 2]
    # a map material the caller does not name is -1; where the map names nothing (unmeasured) the bulk stays
    hm = HapticMaterialMap((0.0, 0.0), 0.05, ["soft", "hard"], p, measured=np.array([[True, False]]))
    obj = ObjectSpec("o", "box", (0.1, 0.05, 0.02), (0.05, 0.025), MID, material_map=hm, map_materials=(SOFT, HARD))
    pts = np.array([[0.02, 0.02, 0.019], [0.07, 0.02, 0.019], [0.07, 0.02, 0.005], [0.2, 0.02, 0.019]])
    assert material_index_at(obj, pts, ["medium", "hard"]).tolist() == [-1, 0, 0, -1]
    with pytest.raises(ValidationError, match="map_materials"):
        ObjectSpec("o", "box", (0.1, 0.05, 0.02), (0.05, 0.025), MID, material_map=hm, map_materials=(SOFT,))
