"""``palpate calibrate realism``: moments, objective and search, and the fit recovering the parameters of a table
it generated itself (physics marker: it simulates a few thousand presses)."""

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from palpate.core.cli import main
from palpate.core.errors import ValidationError
from palpate.core.perception.param_stats import PressTable, table_from_csv
from palpate.core.world.scenario_file import load_scenario
from palpate.sim.realism.calibrate import (
    MOMENTS,
    SCALES,
    SCALES_WITH_A2_SIGN,
    calibrate,
    objective,
    real_moments,
    simulate_seed,
    table_moments,
)
from palpate.sim.realism.parameters import (
    FREE_PARAMETERS,
    current_values,
    free_parameters,
    with_scenario,
    with_values,
)
from palpate.sim.realism.profile import LAB
from palpate.sim.realism.profile_file import load_profile

REPO = Path(__file__).resolve().parent.parent
SEED_TABLE = REPO / "models" / "realism" / "seed000_tables_6_3_to_6_5.csv"
SCENARIO = REPO / "scenarios" / "thesis_ch6.toml"


def test_moments_of_a_table_are_its_statistics():
    rows = np.array([[10, -1, 0, 2, 1, 0], [12, 2, 0, 3, -1, 0], [14, 3, 0, 4, -2, 0], [16, -4, 0, 3, 5, 0]], float)
    m = table_moments(PressTable(("m",), (rows,)), ["m"], np.array([0.7]), smooth=False)[0]
    expected = {"log_mean_n1": np.log(13.0), "log_mean_a1": np.log(3.0),
                "log_cv_n1": np.log(np.std(rows[:, 0], ddof=1) / 13.0),
                "log_cv_a1": np.log(np.std(rows[:, 3], ddof=1) / 3.0), "negative_n2": 0.5, "negative_a2": 0.5,
                "loo_self": 0.7, "intercept_n": 0.0, "intercept_a": 0.75 / 3.0}
    np.testing.assert_allclose(m, [expected[k] for k in MOMENTS], atol=1e-8)
    smooth = table_moments(PressTable(("m",), (rows,)), ["m"], np.array([0.7]), smooth=True)[0]
    assert 0.3 < smooth[MOMENTS.index("negative_n2")] < 0.7


def test_the_seed_tables_moments_include_table_6_7():
    table = table_from_csv(SEED_TABLE)
    m = real_moments(table, table.materials)
    loo = m[:, MOMENTS.index("loo_self")]
    assert loo[0] == pytest.approx(0.809, abs=0.005) and loo[1] > 0.99 and loo[2] > 0.99
    np.testing.assert_allclose(m[:, MOMENTS.index("negative_n2")], [0.1, 0.4, 0.8])
    # seed 000's mean intercepts over its mean slopes (Tables 6.3-6.5)
    np.testing.assert_allclose(m[:, MOMENTS.index("intercept_n")], [13.92 / 75.24, 9.63 / 432.62, -2.69 / 1683.28],
                               rtol=0.01)
    np.testing.assert_allclose(m[:, MOMENTS.index("intercept_a")], [13.46 / 3.02, 3.52 / 2.88, -69.68 / 10.91],
                               rtol=0.01)
    assert objective(m, m) == 0.0
    shifted = m.copy()
    shifted[0, 0] += SCALES[0]
    assert objective(shifted, m) == pytest.approx(1.0)
    # a2's sign weighs only when asked for (--fit-a2-sign), with n2's tolerance
    flipped = m.copy()
    flipped[1, MOMENTS.index("negative_a2")] += 0.3
    assert objective(flipped, m) == 0.0
    assert objective(flipped, m, SCALES_WITH_A2_SIGN) == pytest.approx((0.3 / 0.15) ** 2)
    assert objective(shifted, m, SCALES_WITH_A2_SIGN) == pytest.approx(1.0)


def test_free_parameters_are_set_in_file_units_and_validated():
    free = free_parameters(["finger.stiffness_n_per_mm", "press.tilt_deg", "pose.latency_ms"])
    p = with_values(LAB, free, [0.8, 3.0, -5.0], name="x")
    assert p.name == "x" and p.finger.stiffness == pytest.approx(800.0)
    assert p.press.tilt_std == pytest.approx(np.deg2rad(3.0)) and p.pose.latency == pytest.approx(-0.005)
    assert current_values(p, free) == pytest.approx([0.8, 3.0, -5.0])
    assert p.taxels == LAB.taxels  # everything not free is the start's
    # the press's stop rule is fitted in file units too, and a value the profile refuses is refused
    push = free_parameters(["press.push_force_n", "press.push_depth_scale", "press.push_stiffness_n_per_mm"])
    q = with_values(LAB, push, [1.2, 3.0, 0.8])
    assert (q.press.push_force, q.press.push_depth_scale, q.press.push_stiffness) == \
        pytest.approx((1.2, 3.0, 800.0))
    assert current_values(q, push) == pytest.approx([1.2, 3.0, 0.8])
    with pytest.raises(ValidationError, match="push_depth_scale"):
        with_values(LAB, push, [1.2, 0.5, 0.8])
    for f in free:
        assert f.value(f.position(f.lo)) == pytest.approx(f.lo) and f.value(1.0) == pytest.approx(f.hi)
    with pytest.raises(ValidationError, match="unknown free parameter.*finger.stiffnes"):
        free_parameters(["finger.stiffnes"])
    with pytest.raises(ValidationError, match="repeat"):
        free_parameters(["press.tilt_deg", "press.tilt_deg"])


def test_the_pad_is_fitted_on_the_scenario_not_the_profile():
    scenario = load_scenario(SCENARIO)
    shipped = load_profile(REPO / "models" / "realism" / "thesis_ch6.toml")
    free = free_parameters(["pad.pitch_mm", "pad.fill", "taxels.sensitivity", "young.Material_1"],
                           scenario.references)
    tip = scenario.fingertip
    assert current_values(shipped, free, scenario) == pytest.approx(
        [tip.pitch * 1e3, tip.sensel_size / tip.pitch, shipped.taxels.sensitivity, 1.0])
    values = [2.0, 0.9, 7.0, 1.5]
    sc, prof = with_scenario(scenario, free, values), with_values(shipped, free, values)
    assert (sc.fingertip.pitch, sc.fingertip.sensel_size) == pytest.approx((0.002, 0.0018))
    assert sc.fingertip.radius == tip.radius and (sc.fingertip.rows, sc.fingertip.cols) == (tip.rows, tip.cols)
    old, new = scenario.materials["Material_1"].material, sc.materials["Material_1"].material
    assert new.young == pytest.approx(1.5 * old.young)
    assert prof.taxels.sensitivity == pytest.approx(7.0) and prof.finger == shipped.finger
    # the profile alone cannot say where the pad is; the scenario without pad values keeps its pad
    with pytest.raises(ValidationError, match="pad.pitch_mm.*scenario"):
        current_values(shipped, free)
    assert with_scenario(scenario, free[2:], values[2:]).fingertip == tip
    # every box end is a pad the scenario's fingertip accepts (a sensel no wider than the pitch)
    for key in ("pad.pitch_mm", "pad.fill"):
        box = free_parameters([key])[0]
        for v in (box.lo, box.hi):
            assert current_values(shipped, [box], with_scenario(scenario, [box], [v])) == pytest.approx([v])


def test_every_search_box_end_is_a_profile_the_file_accepts():
    # a box end the profile refuses would score every candidate there as failed (taxels.sensitivity's top was 100,
    # which the profile's [0.01, 100) refuses)
    shipped = load_profile(REPO / "models" / "realism" / "thesis_ch6.toml")
    for box in FREE_PARAMETERS.values():
        if box.key.startswith("young."):
            continue  # the scenario's moduli, not the profile's
        for v in (box.lo, box.hi):
            assert current_values(with_values(shipped, [box], [v]), [box]) == pytest.approx([v]), box.key


def test_the_area_factors_box_reaches_serinas_area():
    shipped = load_profile(REPO / "models" / "realism" / "thesis_ch6.toml")
    box = FREE_PARAMETERS["finger.area_factor"]
    # Serina et al. 1998: ~1 cm^2 at 1 N. On a rigid surface the patch is pi R area_factor delta (R: the
    # scenario's 8 mm fingertip), delta the shipped pulp's compression at 1 N; the box must hold that factor.
    delta = float(shipped.finger.compression(np.array([1.0]))[0])
    serina = 100e-6 / (np.pi * 8e-3 * delta)
    assert 6.0 < serina <= box.hi and box.lo <= 2.0  # 2: the shipped geometric flattening stays inside


def test_calibration_refuses_what_it_cannot_do(tmp_path):
    scenario = load_scenario(SCENARIO)
    table = table_from_csv(SEED_TABLE)
    free = free_parameters(["press.tilt_deg"])
    with pytest.raises(ValidationError, match="disjoint"):
        calibrate(table, scenario, LAB, free, tune_seeds=[1, 2], report_seeds=[2, 3], budget=4)
    other = PressTable(("Sponge",), (table.of("Material_1"),))
    with pytest.raises(ValidationError, match="'Sponge'.*not reference materials"):
        calibrate(other, scenario, LAB, free, tune_seeds=[1], report_seeds=[2], budget=4)
    out = tmp_path / "p.toml"
    out.write_text("x")
    assert main(["calibrate", "realism", str(SEED_TABLE), "--scenario", str(SCENARIO), "--out", str(out)]) == 2


def _write_table(path: Path, runs) -> None:
    lines = ["material,n1,n2,phi_n,a1,a2,phi_a"]
    for name in runs[0].table.materials:
        for run in runs:
            lines += [name + "," + ",".join(f"{v:.9g}" for v in r) for r in run.table.of(name)]
    path.write_text("\n".join(lines) + "\n")


@pytest.mark.physics
def test_calibration_recovers_the_parameters_of_a_table_it_generated(tmp_path):
    scenario = replace(load_scenario(SCENARIO), fidelity="analytic")
    free = free_parameters(["finger.stiffness_cv", "taxels.sensitivity"])
    truth = with_values(LAB, free, [0.4, 4.0], name="truth")
    table_path = tmp_path / "generated.csv"
    # 40 presses per material in one session, from a seed the fit never sees: a 10-press table's CVs scatter by
    # ~25%, which a fit would chase; 40 pin the statistics the parameters are identified by
    forty = replace(scenario, training=replace(scenario.training, presses_per_material=40))
    _write_table(table_path, [simulate_seed(forty, truth, 900, "analytic")])
    start = with_values(LAB, free, [0.1, 1.5], name="start")
    result = calibrate(table_from_csv(table_path), scenario, start, free, tune_seeds=[11, 12, 13],
                       report_seeds=[21], budget=30)
    stiffness_cv, sensitivity = current_values(result.profile, free)
    # the pad's sensitivity sets every location: tight; the pulp's spread only the CVs of n1: within 50%
    assert sensitivity == pytest.approx(4.0, rel=0.15)
    assert stiffness_cv == pytest.approx(0.4, rel=0.5)
    assert result.profile.provenance["free"]["taxels.sensitivity"] == pytest.approx(sensitivity)
    # and on a report seed it was not tuned on, the fitted profile's n1 locations match the table's
    n1 = MOMENTS.index("log_mean_n1")
    np.testing.assert_allclose(result.report[:, n1], result.real[:, n1], atol=2 * SCALES[n1])


@pytest.mark.physics
def test_the_quick_command_writes_a_profile_that_loads(tmp_path, capsys):
    out = tmp_path / "fit.toml"
    assert main(["calibrate", "realism", str(SEED_TABLE), "--scenario", str(SCENARIO), "--out", str(out), "--quick",
                 "--free", "press.tilt_deg,taxels.sensitivity"]) == 0
    p = load_profile(out)
    assert p.name == "fit" and p.provenance["tune_seeds"] == [101, 102] and p.provenance["evaluations"] == 6
    assert "loo_self" in capsys.readouterr().out
