"""The flex mesh correction for plates (sim/flex_plate.py): its table, its limit and its held-out stiff skins."""

from __future__ import annotations

import json

import numpy as np
import pytest

from palpate.core.errors import ValidationError
from palpate.core.world.scene import Layer, Material, ObjectSpec
from palpate.sim.flex_plate import (
    PLATE_CALIBRATION_PATH,
    PLATE_HEIGHTS,
    PLATE_RATIOS,
    PLATE_SKINS,
    PlateSkin,
    load_plate_calibration,
    plate_curve,
    plate_skin,
)

CELL_OVER_RADIUS = 0.625  # the shipped 5 mm cells under the 8 mm tip


def test_the_shipped_plate_table_loads_with_its_calibration_plates():
    table = load_plate_calibration()
    assert np.allclose(table.modulus_ratio, PLATE_RATIOS) and np.allclose(table.skin, PLATE_SKINS)
    assert np.allclose(table.height, PLATE_HEIGHTS)
    assert table.factor.shape == (len(PLATE_RATIOS), len(PLATE_SKINS), len(PLATE_HEIGHTS),
                                  len(table.contact_over_cell))
    assert np.all(np.isfinite(table.factor)) and np.all(table.factor > 0)
    # none of the calibration plates is a validity-table stack (20x, 1 / 2 / 4 mm, 30 mm): those are held out
    assert 20.0 not in PLATE_RATIOS and not set(np.round(table.skin * 1e3, 6)) & {1.0, 2.0, 4.0}
    assert 0.03 not in PLATE_HEIGHTS


def _write(tmp_path, edit):
    raw = json.loads(PLATE_CALIBRATION_PATH.read_text())
    edit(raw)
    path = tmp_path / "plate.json"
    path.write_text(json.dumps(raw))
    return path


@pytest.mark.parametrize("edit, match", [
    (lambda r: r.update(version=99), "not a palpate-flex-plate-calibration file of version 1"),
    (lambda r: r.update(factor=r["factor"][:-1]), "factor must be modulus_ratio x skin x height"),
    (lambda r: r.update(skin=r["skin"][::-1]), "needs increasing"),
    (lambda r: r.update(modulus_ratio=[0.5] + r["modulus_ratio"][1:]), r"modulus_ratio \(> 1\)"),
    (lambda r: r["factor"][0][0][0].__setitem__(3, -1.0), "factors > 0"),
    (lambda r: r.update(height="tall"), "height must be numbers"),
])
def test_a_bad_plate_table_is_refused_naming_the_key(tmp_path, edit, match):
    with pytest.raises(ValidationError, match=match):
        load_plate_calibration(_write(tmp_path, edit))
    with pytest.raises(ValidationError, match="benchmarks/flex_plate.py --calibrate"):
        load_plate_calibration(tmp_path / "missing.json")


def test_the_plate_correction_goes_to_the_blocks_as_the_skin_goes_to_its_base():
    """A skin as stiff as its base is a block, whose kappa is the block table's: q -> 1 as the ratio -> 1. The
    first measured row (2x) is the plate window's own difference from a block (node planes, bending cells and the
    graded 90 mm window on a near-homogeneous stack): measured within 11% of 1 where a press reads it."""
    table = load_plate_calibration()
    ratios = [1.0 + 1e-9, 1.01, 1.2, 1.6, 2.0]
    dev = [np.abs(plate_curve(table, PlateSkin(0.002, r), 0.03, CELL_OVER_RADIUS).factor - 1.0).max() for r in ratios]
    assert dev[0] < 1e-6 and dev[1] < dev[-1]
    read = table.contact_over_cell >= 0.25  # flex resolves presses from a / cell 0.25
    assert np.all(np.abs(table.factor[0][..., read] - 1.0) < 0.11)


def test_the_plate_curve_is_the_table_at_its_nodes_and_between_them_in_log():
    table = load_plate_calibration()
    i, j, k = 2, 1, 1
    node = plate_curve(table, PlateSkin(PLATE_SKINS[j], PLATE_RATIOS[i]), PLATE_HEIGHTS[k], CELL_OVER_RADIUS)
    assert np.allclose(node.factor, table.factor[i, j, k]) and not node.outside
    # halfway in log skin thickness between two nodes: the mean of their rows
    mid = float(np.sqrt(PLATE_SKINS[1] * PLATE_SKINS[2]))
    half = plate_curve(table, PlateSkin(mid, PLATE_RATIOS[i]), PLATE_HEIGHTS[k], CELL_OVER_RADIUS)
    assert np.allclose(half.factor, 0.5 * (table.factor[i, 1, k] + table.factor[i, 2, k]))
    # past the stiffest ratio, another cell size or outside the heights: held, and flagged
    for skin, h, c in ((PlateSkin(0.002, 200.0), 0.03, CELL_OVER_RADIUS), (PlateSkin(0.002, 10.0), 0.03, 0.4),
                       (PlateSkin(0.002, 10.0), 0.2, CELL_OVER_RADIUS)):
        assert plate_curve(table, skin, h, c).extrapolated(0.5)
    assert not plate_curve(table, PlateSkin(0.002, 10.0), 0.03, CELL_OVER_RADIUS).extrapolated(1.0)
    with pytest.raises(ValidationError, match="stiffer than its base"):
        plate_curve(table, PlateSkin(0.002, 0.5), 0.03, CELL_OVER_RADIUS)


def test_the_plate_is_the_top_layer_stiffer_than_what_lies_under_it():
    base, stiff, soft = Material("b", 1e5, 0.45), Material("s", 2e6, 0.4), Material("f", 2e4, 0.3)

    def obj(*layers):
        return ObjectSpec("o", "box", (0.2, 0.2, 0.03), (0.0, 0.0), base, layers=tuple(layers))

    assert plate_skin(obj()) is None and plate_skin(obj(Layer(soft, 0.002))) is None
    assert plate_skin(obj(Layer(soft, 0.001), Layer(stiff, 0.002))) is None  # a soft top: no table for it
    assert plate_skin(obj(Layer(stiff, 0.002))) == PlateSkin(0.002, 20.0)
    # the ratio is to the layer right under the skin, not the bulk
    assert plate_skin(obj(Layer(stiff, 0.002), Layer(Material("m", 4e5, 0.45), 0.005))) == PlateSkin(0.002, 5.0)


@pytest.mark.physics
@pytest.mark.parametrize("skin, ratio, height, nus", [
    (0.003, 20.0, 0.03, (0.4, 0.45)),   # a 3 mm skin (-14% at 1 mm with the block's kappa)
    (0.002, 40.0, 0.03, (0.4, 0.45)),   # another modulus ratio (+14% at 4 mm)
    (0.002, 20.0, 0.015, (0.4, 0.45)),  # another base thickness (+25% at 4 mm)
    (0.0015, 40.0, 0.02, (0.3, 0.49)),  # other Poisson ratios too (+24% at 4 mm)
])
def test_flex_is_within_eight_percent_of_the_layered_law_on_held_out_stiff_skins(skin, ratio, height, nus):
    """Issue 12: stiff skins the plate table never saw (benchmarks/flex_plate.py), against the exact layered contact
    law (within 0.5% of the FE reference on the validity table's skins), at 0.5 / 1 / 2 / 4 mm: with the block's
    kappa alone up to 25% off; with the plate's within 6.2% (measured 2026-11-24)."""
    pytest.importorskip("mujoco")
    from palpate.sim.contact.law import solve_contact_law
    from palpate.sim.flex import reference_press
    from palpate.sim.flex_calibrate import plate_sample
    from palpate.sim.validity.measure import loading_force

    depths = np.array([0.5, 1.0, 2.0, 4.0]) * 1e-3
    sample = plate_sample(skin, ratio, height, skin_poisson=nus[0], base_poisson=nus[1])
    trace = reference_press(young=sample.bulk.young, poisson=sample.bulk.poisson, height=height, depth=4.12e-3,
                            width=max(0.2, 4.0 * (height + 0.02)), layers=sample.layers)
    assert trace.meta["plate_corrected"] and not trace.meta["calibration_extrapolated"]
    law = solve_contact_law(sample, 0.008, 4.2e-3)
    err = loading_force(trace.indentation, trace.force, depths) / law.force_at(depths) - 1.0
    assert np.all(np.abs(err) < 0.08), err
