"""Calibrated maps: what one press may claim, how sure an extrapolated cell may be, and the calibration error."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from palpate.core.errors import ValidationError
from palpate.core.mapping.calibration import (
    DEFAULT_CALIBRATION,
    SEED_CALIBRATION,
    MapCalibration,
    binned_calibration,
    calibration_sample,
    press_evidence,
    reliability_table,
    wall_tempered,
)
from palpate.core.mapping.extrapolation import extrapolate_unexplored
from palpate.core.mapping.grids import Grid2D
from palpate.core.mapping.probability import entropy
from palpate.core.world.scenario_file import parse_scenario


def test_press_evidence_mixes_in_a_uniform_misreading_and_tempers_the_likelihood():
    p = np.array([0.999, 0.0009, 0.0001])
    assert press_evidence(p) == pytest.approx(p)  # the seeds' setting: as the memory says
    r = press_evidence(p, reliability=0.94)
    assert r == pytest.approx(0.94 * p + 0.02)
    assert r.sum() == pytest.approx(1.0)
    t = press_evidence(p, temperature=0.5)
    assert t == pytest.approx(np.sqrt(p) / np.sqrt(p).sum())
    # a likelihood of exactly 0 stays 0 when tempered, and the floor lifts it
    z = press_evidence(np.array([1.0, 0.0]), temperature=0.5, reliability=0.9)
    assert z == pytest.approx([0.95, 0.05])


@pytest.mark.parametrize("kw, match", [
    ({"reliability": 0.0}, "press reliability must be a number in \\(0, 1\\]"),
    ({"temperature": 1.5}, "press temperature must be"),
    ({"reliability": float("nan")}, "press reliability"),
])
def test_press_evidence_refuses_bad_settings(kw, match):
    with pytest.raises(ValidationError, match=match):
        press_evidence(np.array([0.5, 0.5]), **kw)


def test_one_uncertain_press_never_makes_a_certain_neighbour():
    # one press of 70% fills its neighbours: with the seed's eq. 6.15 they copy it exactly, with certainty < 1
    # they are strictly less sure, and a second pass away less sure again
    p = np.full((1, 5, 2), 0.5)
    explored = np.zeros((1, 5), dtype=bool)
    p[0, 0], explored[0, 0] = (0.7, 0.3), True
    seed = extrapolate_unexplored(p, explored)
    assert seed[0, 1] == pytest.approx([0.7, 0.3])
    cal = extrapolate_unexplored(p, explored, passes=2, certainty=0.9)
    assert cal[0, 1] == pytest.approx([0.9 * 0.7 + 0.05, 0.9 * 0.3 + 0.05])
    h = entropy(cal[0, :3])
    assert h[0] < h[1] < h[2]
    # argmax is kept: certainty changes how sure, never what
    assert (cal[0, :3].argmax(-1) == 0).all()
    with pytest.raises(ValidationError, match="extrapolation certainty must be a number in \\(0, 1\\]"):
        extrapolate_unexplored(p, explored, certainty=0.0)


def test_grid_postprocessing_takes_the_certainty():
    g = Grid2D(["a", "b"], (3, 1))
    g.update_cell(0, 0, [0.99, 0.01])
    assert g.postprocessed().probabilities[0, 1] == pytest.approx(g.probabilities[0, 0])
    assert g.postprocessed(certainty=0.8).probabilities[0, 1, 0] == pytest.approx(0.8 * 0.99 + 0.1)


def test_a_wall_between_two_pressed_cells_lowers_both_by_hand():
    g = Grid2D(["a", "b"], (3, 1))
    g.update_cell(0, 0, [0.9, 0.1])
    g.update_cell(1, 0, [0.2, 0.8])
    # total-variation distance 0.7: each keeps 1 - (1 - 0.5) * 0.7 = 0.65 of itself, the rest uniform
    post = g.postprocessed(wall_reliability=0.5).probabilities
    assert post[0, 0] == pytest.approx([0.65 * 0.9 + 0.175, 0.65 * 0.1 + 0.175])
    assert post[0, 1] == pytest.approx([0.65 * 0.2 + 0.175, 0.65 * 0.8 + 0.175])
    # eq. 6.15 then copies the lowered cell (its only pressed neighbour) into the unpressed one
    assert post[0, 2] == pytest.approx(post[0, 1])
    # each cell keeps its most probable material; the unpressed cell counts for nothing (no wall there)
    assert (post[0, :2].argmax(-1) == g.probabilities[0, :2].argmax(-1)).all()
    assert np.array_equal(g.postprocessed(wall_reliability=0.5, certainty=0.9).probabilities[0, 0], post[0, 0])


def test_agreeing_neighbours_and_the_seed_setting_keep_the_seed_maps():
    g = Grid2D(["a", "b", "c"], (3, 2))
    for ix in range(3):
        g.update_cell(ix, 0, [0.9, 0.05, 0.05])  # one material along the row: no wall
    g.update_cell(0, 1, [0.1, 0.1, 0.8])  # a wall above cell (0, 0) only
    seed = g.postprocessed(certainty=0.95).probabilities
    post = g.postprocessed(certainty=0.95, wall_reliability=0.6).probabilities
    assert np.array_equal(post[0, 1:], seed[0, 1:])  # cells whose pressed neighbours agree are untouched
    assert post[0, 0].max() < seed[0, 0].max() and post[1, 0].max() < seed[1, 0].max()
    # every setting 1 (SEED_CALIBRATION) is the seeds' eq. 2 / 6.15 to the bit
    assert SEED_CALIBRATION.wall_reliability == 1.0
    assert np.array_equal(g.postprocessed(wall_reliability=SEED_CALIBRATION.wall_reliability).probabilities,
                          g.postprocessed().probabilities)
    p = g.probabilities
    assert wall_tempered(p, g.explored, 1.0) is p


@pytest.mark.parametrize("bad", [0.0, 1.5, float("nan"), True, "0.5"])
def test_bad_wall_reliability_is_refused(bad):
    with pytest.raises(ValidationError, match="wall_reliability must be a number in \\(0, 1\\]"):
        MapCalibration(wall_reliability=bad)
    with pytest.raises(ValidationError, match="wall reliability must be a number in \\(0, 1\\]"):
        Grid2D(["a", "b"], (2, 1)).postprocessed(wall_reliability=bad)


def test_reliability_table_against_a_hand_computed_example():
    conf = np.array([0.95, 0.95, 0.95, 0.95, 0.55, 0.55, 0.85])
    right = np.array([1, 1, 1, 0, 1, 0, 1], dtype=bool)
    t = reliability_table(conf, right, bins=10)
    # bins: [0.9, 1.0]: 4 cells, 75% right at 0.95; [0.5, 0.6): 2 cells, 50% at 0.55; [0.8, 0.9): 1 cell, 100% at 0.85
    assert t.count[9] == 4 and t.count[5] == 2 and t.count[8] == 1 and t.count.sum() == 7
    assert t.accuracy[9] == pytest.approx(0.75) and t.confidence[9] == pytest.approx(0.95)
    expected = (4 * 0.2 + 2 * 0.05 + 1 * 0.15) / 7
    assert t.ece == pytest.approx(expected)
    assert t.to_dict()["ece"] == pytest.approx(expected)
    # a perfectly calibrated sample: ECE 0
    assert reliability_table(np.full(10, 0.7), np.arange(10) < 7).ece == pytest.approx(0.0)
    with pytest.raises(ValidationError, match="same length"):
        reliability_table(conf, right[:3])


def test_calibration_sample_leaves_out_ties_and_cells_without_truth():
    p = np.array([[[0.9, 0.1], [0.5, 0.5], [0.2, 0.8]]])
    truth = np.array([[0, 1, -1]])
    conf, right, undecided = calibration_sample(p, truth)
    assert conf.tolist() == [0.9] and right.tolist() == [True] and undecided == 1
    with pytest.raises(ValidationError, match="truth must have the map's cell shape"):
        calibration_sample(p, truth[:, :2])


def test_map_calibration_round_trips_and_names_bad_keys():
    assert MapCalibration.from_dict(DEFAULT_CALIBRATION.to_dict()) == DEFAULT_CALIBRATION
    assert MapCalibration.from_dict({}) == SEED_CALIBRATION  # a recording from before: the seeds' maps
    with pytest.raises(ValidationError, match="rec.mcap: unknown calibration key\\(s\\) \\['trust'\\]"):
        MapCalibration.from_dict({"trust": 1.0}, "rec.mcap")
    with pytest.raises(ValidationError, match="rec.mcap: press_reliability must be a number in"):
        MapCalibration.from_dict({"press_reliability": 2.0}, "rec.mcap")
    with pytest.raises(ValidationError, match="rec.mcap: wall_reliability must be a number in"):
        MapCalibration.from_dict({"wall_reliability": 0.0}, "rec.mcap")
    # a recording made before the setting existed: the seeds' wall reliability
    old = {k: v for k, v in DEFAULT_CALIBRATION.to_dict().items() if k != "wall_reliability"}
    assert MapCalibration.from_dict(old).wall_reliability == 1.0


RAW = {"scenario": {"name": "c", "seed": 1, "fidelity": "analytic"},
       "materials": [{"name": "soft", "young_kpa": 20.0}, {"name": "hard", "young_kpa": 450.0}],
       "exploration": {"policy": "raster", "budget": 2},
       "objects": [{"name": "o", "size_mm": [30.0, 20.0, 30.0], "position_mm": [15.0, 10.0], "material": "soft"}]}


def test_scenario_calibration_keys_default_to_calibrated_and_are_validated():
    assert parse_scenario(copy.deepcopy(RAW), "c.toml").exploration.calibration == DEFAULT_CALIBRATION
    raw = copy.deepcopy(RAW)
    raw["exploration"].update(press_reliability=1.0, extrapolation_certainty=1.0, wall_reliability=1.0)
    assert parse_scenario(raw, "c.toml").exploration.calibration == SEED_CALIBRATION
    raw["exploration"]["wall_reliability"] = 0.0
    with pytest.raises(ValidationError, match="c.toml: exploration.wall_reliability: must be > 0.0"):
        parse_scenario(raw, "c.toml")
    raw["exploration"]["wall_reliability"] = 1.0
    raw["exploration"]["press_temperature"] = 0.0
    with pytest.raises(ValidationError, match="c.toml: exploration.press_temperature: must be > 0.0"):
        parse_scenario(raw, "c.toml")
    raw["exploration"]["press_temperature"] = 1.2
    with pytest.raises(ValidationError, match="exploration.press_temperature: must be <= 1.0"):
        parse_scenario(raw, "c.toml")


def test_bins_summed_over_samples_give_the_ece_of_the_samples_pooled():
    rng = np.random.default_rng(5)
    samples = [(rng.uniform(0.3, 1.0, n), rng.random(n) < 0.8) for n in (40, 300, 7)]
    tables = [reliability_table(c, r) for c, r in samples]
    count = sum(t.count for t in tables)
    conf_sum = sum(t.count * t.confidence for t in tables)
    right_sum = sum(t.count * t.accuracy for t in tables)
    pooled = reliability_table(np.concatenate([c for c, _ in samples]), np.concatenate([r for _, r in samples]))
    mean_conf, acc, ece = binned_calibration(count, conf_sum, right_sum)
    np.testing.assert_allclose(mean_conf, pooled.confidence, rtol=1e-12)
    np.testing.assert_allclose(acc, pooled.accuracy, rtol=1e-12)
    assert ece == pytest.approx(pooled.ece, rel=1e-12)
    assert ece != pytest.approx(np.mean([t.ece for t in tables]), rel=1e-3)  # not the mean of the samples' ECEs
    assert binned_calibration(np.zeros(10), np.zeros(10), np.zeros(10))[2] == 0.0
