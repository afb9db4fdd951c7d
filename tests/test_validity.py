"""The validity table (each fidelity against the FE reference) and ``auto``, which picks the cheapest fidelity the
table says is within the scenario's tolerance."""

from __future__ import annotations

import json
import math
import re

import numpy as np
import pytest

from palpate.core.errors import ValidationError
from palpate.core.session.sources import PressTarget, scenario_source_maker
from palpate.core.world.scenario_file import parse_scenario
from palpate.core.world.scene import Inclusion, Layer, Material, ObjectSpec, Scene
from palpate.sim.source import SimSource
from palpate.sim.validity.cases import quick_cases, validity_cases
from palpate.sim.validity.choice import Situation, choose, explain_fidelity, predicted_errors, situation
from palpate.sim.validity.report import claims
from palpate.sim.validity.table import TABLE_PATH, ValidityRow, ValidityTable, load_table, table_from_document

R = 0.008


def _row(family, feature, analytic, rigid=None, flex=None, poisson=0.3):
    return ValidityRow(case="c", family=family, poisson=poisson, thickness=0.03, depth=0.001, feature=feature,
                       a_over_h=0.1, reference_force=1.0, error={"analytic": analytic, "rigid": rigid, "flex": flex})


def _table(*rows):
    return ValidityTable(tip_radius=R, rungs=("analytic", "rigid", "flex"), rows=rows, cost={})


def test_cases_cover_the_issues_ranges_and_the_quick_set_is_a_subset():
    cases = validity_cases()
    thick = [c for c in cases if c.family == "thickness"]
    assert {c.sample.thickness for c in thick} == {0.002, 0.005, 0.01, 0.02, 0.05, 0.1}
    assert {c.sample.bulk.poisson for c in thick} == {0.3, 0.45, 0.49}
    assert min(min(c.depths) for c in cases) == pytest.approx(2e-4) and max(max(c.depths) for c in cases) == 4e-3
    assert {c.family for c in cases} == {"thickness", "skin", "lump", "edge"}
    names = {c.name for c in cases}
    assert {c.name for c in quick_cases()} <= names and len(names) == len(cases)
    case = next(c for c in cases if c.name == "thick_10mm_nu0.3")
    assert case.feature(0.002) == pytest.approx(0.01 / math.sqrt(R * 0.002))


def test_the_cheapest_fidelity_within_tolerance_wins_and_the_reason_says_where():
    table = _table(_row("thickness", 2.0, 0.30, 0.02, 0.08), _row("thickness", 5.0, 0.01, 0.01, 0.09))
    thin = Situation(thickness=2.2, poisson=0.3)
    choice = choose(table, thin, 0.05, "Block")
    assert choice.fidelity == "rigid" and "Block" in choice.reason and "5% tolerance" in choice.reason
    assert "analytic: 30.0%" in choice.reason and choice.predicted["analytic"] == pytest.approx(0.30)
    # thicker than measured: fine
    assert choose(table, Situation(thickness=6.0, poisson=0.3), 0.05, "Block").fidelity == "analytic"
    choice = choose(table, thin, 0.01, "Block")
    assert choice.fidelity == "rigid" and "no fidelity is within the 1% tolerance" in choice.reason
    # thinner than anything measured: no prediction, said as such
    errs = predicted_errors(table, Situation(thickness=0.5, poisson=0.3))
    assert all(math.isinf(v) for v in errs.values())
    # geometry rules a fidelity out whatever the table says
    choice = choose(table, Situation(thickness=6.0, poisson=0.3, excluded={"analytic": "a mesh top"}), 0.05, "Ball")
    assert choice.fidelity == "rigid" and "analytic ruled out: a mesh top" in choice.reason


def test_every_applicable_family_counts_and_the_worst_decides():
    table = _table(_row("thickness", 5.0, 0.01, 0.01, 0.02), _row("lump", 1.0, 0.12, 0.12, 0.03))
    assert choose(table, Situation(thickness=5.0, poisson=0.3, lump=1.0), 0.05, "Block").fidelity == "flex"


def test_a_press_is_placed_by_what_it_feels():
    soft, hard = Material("soft", 2e4), Material("hard", 2e6)
    wide = ObjectSpec("w", "box", (0.2, 0.2, 0.03), (0.0, 0.0), soft)
    sit = situation(wide, 0.0, 0.0, 0.03, 0.002, R)
    assert sit.families() == ("thickness",) and sit.thickness == pytest.approx(0.03 / 0.004)
    near_edge = situation(wide, 0.098, 0.0, 0.03, 0.002, R)
    assert near_edge.edge is not None and "analytic" in near_edge.excluded
    skin = ObjectSpec("s", "box", (0.2, 0.2, 0.03), (0.0, 0.0), hard, layers=(Layer(soft, 0.002),))
    assert situation(skin, 0.0, 0.0, 0.03, 0.002, R).skin == pytest.approx(0.5)
    lump = ObjectSpec("l", "box", (0.2, 0.2, 0.03), (0.0, 0.0), soft,
                      inclusions=(Inclusion(hard, "sphere", (0.0, 0.0, 0.02), (0.005,)),))
    on_axis = situation(lump, 0.0, 0.0, 0.03, 0.002, R)
    assert on_axis.lump == pytest.approx(0.005 / 0.004, rel=0.15) and not on_axis.notes
    off_axis = situation(lump, 0.006, 0.0, 0.03, 0.002, R)
    assert off_axis.lump is not None and any("off the press axis" in n for n in off_axis.notes)


def test_the_shipped_table_supports_the_issues_claims_for_the_closed_form_fidelities():
    table = load_table()
    assert {r.family for r in table.rows} == {"thickness", "skin", "lump", "edge"}
    for c in claims(table):
        if c.fidelity in ("analytic", "rigid"):
            assert c.holds, c


@pytest.mark.parametrize("edit, match", [
    (lambda d: d.update(format="x"), "not a palpate-validity"),
    (lambda d: d["rows"][0].update(family="volcano"), r"rows\[0\].family"),
    (lambda d: d["rows"][0].update(feature=float("nan")), "NaN is not a number"),
    (lambda d: d["rows"][0].update(feature="wide"), r"rows\[0\].feature"),
    (lambda d: d["rows"][0]["error"].update(fem=0.1), r"rows\[0\].error"),
    (lambda d: d["rows"][0].update(reference_force=None), r"rows\[0\].reference_force"),
    (lambda d: d["cost"]["rigid"].update(wall_s="long"), r"cost.rigid.wall_s"),
    (lambda d: d["rungs"].append(["rigid"]), "key 'rungs'"),
    (lambda d: d.update(failures=[{"case": "x", "fidelity": "flex"}]), r"failures\[0\].error"),
])
def test_a_bad_table_is_refused_naming_the_key(tmp_path, edit, match):
    doc = json.loads(TABLE_PATH.read_text())
    edit(doc)
    path = tmp_path / "t.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(ValidationError, match=match):
        load_table(path)
    with pytest.raises(ValidationError, match="not found"):
        load_table(tmp_path / "none.json")


def test_the_table_reads_back_as_written():
    doc = json.loads(TABLE_PATH.read_text())
    table = load_table()
    assert table.to_dict() == doc  # nothing in the file is lost or changed by reading it
    assert table_from_document(table.to_dict()) == table


def test_auto_on_a_thick_block_is_analytic_and_the_press_records_why():
    block = ObjectSpec("Block", "box", (0.1, 0.1, 0.03), (0.0, 0.0), Material("m", 2e5))
    src = SimSource(Scene((block,)), fidelity="auto")
    choice = src.explain(PressTarget(0.0, 0.0, depth=0.002))
    assert choice.fidelity == "analytic" and "validity table" in choice.reason
    rec = src.press(PressTarget(0.0, 0.0, depth=0.002))
    assert rec.meta["fidelity"] == "analytic" and rec.meta["fidelity_reason"] == choice.reason
    # a force-only target is placed at the depth the law gives that force
    assert "validity table" in src.explain(PressTarget(0.0, 0.0, depth=None, force=1.0)).reason
    assert explain_fidelity(block, PressTarget(0.0, 0.0, depth=0.002), R).fidelity == "analytic"


def test_the_scenario_tolerance_reaches_the_source():
    raw = {"scenario": {"name": "t", "tolerance_pct": 2.5}, "exploration": {"policy": "raster"},
           "materials": [{"name": "a", "young_kpa": 20.0}, {"name": "b", "young_kpa": 200.0}],
           "objects": [{"name": "o", "shape": "box", "size_mm": [50.0, 50.0, 20.0], "position_mm": [0.0, 0.0],
                        "material": "a"}]}
    sc = parse_scenario(raw)
    assert sc.fidelity_tolerance == pytest.approx(0.025)
    src = scenario_source_maker(sc)((sc.objects[0].spec,), 0, "robot")
    assert src.tolerance == pytest.approx(0.025)
    raw["scenario"]["tolerance_pct"] = 0.0
    with pytest.raises(ValidationError, match="tolerance_pct"):
        parse_scenario(raw)


def test_predicted_errors_are_finite_where_the_table_has_rows():
    table = load_table()
    block = ObjectSpec("b", "box", (0.2, 0.2, 0.02), (0.0, 0.0), Material("m", 2e5, 0.45))
    errs = predicted_errors(table, situation(block, 0.0, 0.0, 0.02, 0.002, R))
    assert np.isfinite(errs["analytic"]) and errs["analytic"] < 0.05


def _flex_error(name: str, depths) -> np.ndarray:
    """Flex's force error against the cached FE reference on validity case ``name`` at ``depths`` (m)."""
    pytest.importorskip("mujoco")
    from palpate.sim.validity.measure import loading_force, press_case
    from palpate.sim.validity.reference import load_reference, reference_force

    case = next(c for c in validity_cases() if c.name == name)
    ref = reference_force(load_reference(), case)
    keep = np.isin(np.round(case.depths, 6), np.round(depths, 6))
    assert keep.sum() == len(depths)
    trace = press_case(case, "flex").trace
    return loading_force(trace.indentation, trace.force, np.asarray(case.depths)[keep]) / ref[keep] - 1.0


@pytest.mark.physics
@pytest.mark.parametrize("name, depths", [("skin_stiff_1mm", (0.5e-3, 1e-3, 2e-3, 4e-3)),
                                          ("edge_15mm", (0.5e-3, 1e-3, 2e-3, 3e-3))])
def test_flex_is_within_ten_percent_of_the_fe_reference_on_held_out_skins_and_an_edge(name, depths):
    """On cases flex was not tuned on (tuned: skin_*_2mm, lump_*_3mm, edge_10mm), against the cached FE
    reference: a 1 mm stiff skin (it bends: its own cells with incompatible modes) from 0.5 to 4 mm (at 4 mm it was
    +12.5% in the plate's wide window before the plate's kappa), and a cylinder whose free side is 15 mm from the
    press (meshed whole), from 0.5 to 3 mm. The soft skins: the next test."""
    err = _flex_error(name, depths)
    assert np.all(np.abs(err) < 0.10), err


@pytest.mark.physics
@pytest.mark.parametrize("name", ["skin_soft_1mm", "skin_soft_2mm", "skin_soft_4mm"])
def test_flex_is_within_ten_percent_of_the_fe_reference_on_soft_skins_from_half_a_mm_to_four(name):
    """A soft skin mixed into its 5 mm cells (the mixing correction: +30% and +17% at 0.5 and 2 mm on the
    4 mm skin before it), with the mesh correction read where the window's contact is as wide as the calibration
    block's (the mixed column's contact is 5-14% wider than a block's; read at sqrt(R d), the 1 and 2 mm skins were
    -8.6 / -8.3% at 1 mm and -9.0 / -10.7% at 4 mm). Tuned on skin_soft_2mm (nothing fitted), the 1 and 4 mm skins
    held out."""
    err = _flex_error(name, (0.5e-3, 1e-3, 2e-3, 4e-3))
    assert np.all(np.abs(err) < 0.10), err


@pytest.mark.physics
@pytest.mark.parametrize("name", ["skin_stiff_1mm", "skin_stiff_2mm", "skin_stiff_4mm"])
def test_a_stiff_skin_is_within_five_percent_from_half_a_mm_to_four(name):
    """The default 30 mm window's pinned sides stiffened a stiff skin (a plate spreads its load far) by
    +25 / +30 / +40% at 4 mm on the 1 / 2 / 4 mm skins; the plate's wide graded window (sim/flex/grid.py, chosen on
    skin_stiff_2mm) left +12.5% at 4 mm on the 1 mm skin and -12.7% at 1 mm on the 4 mm one (the block's kappa
    over-corrects a plate); with the plate's kappa (sim/flex/plate.py, measured on calibration plates, none of
    them these three, which are all held out from it) each is within 3.6% at 0.5-4 mm; in the 60 mm plate window
    with the table remeasured on it (half the cost), within 2.3%."""
    err = _flex_error(name, (0.5e-3, 1e-3, 2e-3, 4e-3))
    assert np.all(np.abs(err) < 0.05), err


@pytest.mark.physics
@pytest.mark.parametrize("name", ["lump_hard_1mm", "lump_hard_3mm", "lump_hard_6mm", "lump_soft_1mm",
                                  "lump_soft_3mm"])
def test_flex_is_within_seven_percent_of_the_fe_reference_on_every_lump_from_half_a_mm_to_four(name):
    """A 5 mm sphere 1 to 6 mm under the top, mixed into the 5 mm cells around the press axis, against the
    cached FE reference. The lateral mixing correction (sim/flex/mixing.py, nothing fitted) took the hard lump 1 mm
    down from -25 / -18 / -17% at 0.5 / 1 / 2 mm and the soft one 3 mm down from -12% at 0.5 mm to within 10%, but
    left lump_soft_1mm +15.6% at 2 mm (the contact's edge reaching the next ring of surface vertices over the soft
    pocket); the lump correction (sim/flex/lump.py, measured on calibration lumps, none of these five, which are all
    held out from it) puts every row within 5.7% at 0.5-4 mm."""
    err = _flex_error(name, (0.5e-3, 1e-3, 2e-3, 4e-3))
    assert np.all(np.abs(err) < 0.07), err


@pytest.mark.physics
@pytest.mark.parametrize("name", ["thick_2mm_nu0.45", "thick_2mm_nu0.49"])
def test_flex_is_within_ten_percent_of_the_fe_reference_on_a_thin_nearly_incompressible_block(name):
    """A 2 mm block pressed 0.5 and 1 mm, thinner than the 3 mm calibration block whose mesh correction it
    used to get (-10% and -16% at 1 mm); the 1.7 mm calibration block puts it between two measured thicknesses."""
    err = _flex_error(name, (0.5e-3, 1e-3))
    assert np.all(np.abs(err) < 0.10), err


@pytest.mark.parametrize("height", [0.03, 0.04, 0.08])
def test_a_wall_reaching_the_surface_is_a_wall_whatever_the_objects_height(height):
    soft, hard = Material("soft", 2e4), Material("hard", 1e5, 0.45)

    def split(edge: float) -> ObjectSpec:  # the hard material fills x > edge, top to bottom
        return ObjectSpec("w", "box", (0.2, 0.2, height), (0.0, 0.0), soft,
                          inclusions=(Inclusion(hard, "column", ((edge + 0.1) / 2, 0.0, height / 2),
                                                (0.1 - edge, 0.2)),))

    assert situation(split(0.003), 0.0, 0.0, height, 0.004, R).image == "wall"
    # far beyond the image's reach, found only by a deep, wide ring: not a lump, and no image family
    assert situation(split(0.015), 0.0, 0.0, height, 0.004, R).image is None
    buried = ObjectSpec("l", "box", (0.2, 0.2, height), (0.0, 0.0), soft,
                        inclusions=(Inclusion(hard, "sphere", (0.004, 0.0, height - 0.006), (0.004,)),))
    assert situation(buried, 0.0, 0.0, height, 0.004, R).image == "lump"


def test_a_reason_that_names_flex_says_how_far_its_image_is_off():
    """flex's image is measured against the FE on plain blocks (the image table); a reason naming flex cites it, and
    says the image is unchecked where no table is at hand."""
    block = ObjectSpec("b", "box", (0.1, 0.1, 0.03), (0.0, 0.0), Material("m", 1e5, 0.45))
    scene = Scene(objects=(block,))
    flex = SimSource(scene, fidelity="flex").explain(PressTarget(0.0, 0.0, depth=0.002))
    assert re.search(r"up to \d+% of the peak off per sensel on plain blocks", flex.reason)
    assert "plain blocks" not in SimSource(scene, fidelity="analytic").explain(
        PressTarget(0.0, 0.0, depth=0.002)).reason
    table = _table(_row("thickness", 7.5, 0.2, 0.2, 0.01))
    chosen = choose(table, Situation(thickness=7.5, poisson=0.3), 0.05, "Block")
    assert chosen.fidelity == "flex" and "image is not checked" in chosen.reason


def test_the_validity_and_image_tables_are_read_once_per_file_version(tmp_path):
    from palpate.sim.validity.image_table import IMAGE_TABLE_PATH, load_image_table
    from palpate.sim.validity.table import TABLE_PATH, load_table

    for load, shipped in ((load_table, TABLE_PATH), (load_image_table, IMAGE_TABLE_PATH)):
        path = tmp_path / shipped.name
        text = shipped.read_text()
        path.write_text(text)
        first = load(path)
        assert load(path) is first and load(shipped) is load(shipped)
        path.write_text(text.replace('"rows"', '"rows" ', 1))  # the same table written again: read again
        assert load(path) is not first and load(path) == first
    with pytest.raises(TypeError):
        load_table().cost["analytic"] = None  # shared by every caller, so nobody may change it
