"""The README's main job: scenarios/thesis_ch6.toml reproduces seed 000's experiment in simulation."""

from pathlib import Path

import numpy as np
import pytest

from palpate.core.session.run import run_scenario
from palpate.core.world.scenario_file import load_scenario

SCENARIO = Path(__file__).resolve().parent.parent / "scenarios" / "thesis_ch6.toml"


@pytest.fixture(scope="module")
def thesis(tmp_path_factory):
    scenario = load_scenario(SCENARIO)
    return scenario, run_scenario(scenario, tmp_path_factory.mktemp("thesis"))


def test_leave_one_out_reads_every_reference_material_mostly_as_itself_and_the_stiff_ones_surely(thesis):
    _, summary = thesis
    # Table 6.7's reading: the mean leave-one-out posterior favours the true material on every row, and the rubber
    # and the hard foam are read as themselves (>= 0.95): their a1 differ as the seed's do (2.9 and 10.9)
    mean_post = np.asarray(summary["crossval"]["mean_posterior"])
    assert np.all(mean_post.argmax(axis=1) == np.arange(3))
    assert np.all(np.diag(mean_post)[1:] >= 0.95), mean_post
    confusion = np.asarray(summary["crossval"]["confusion"])
    assert np.all(np.diag(confusion) >= 0.7), confusion


# Known failure: Material_1's cutaneous features (a1 ~1.9 against the rubber's ~3.4; the seed's real presses: 3.0 and
# 2.9) still separate it from the rubber, so it is never misread (1.0 against Table 6.7's 0.82). docs/realism.md has
# the diagnosis and what was tried. strict: when a realism profile makes this pass, the marker must go.
@pytest.mark.xfail(strict=True, reason="Material_1's leave-one-out stays at 1.0: its a1 is below the rubber's "
                   "(docs/realism.md)")
def test_leave_one_out_reads_material_1_as_table_6_7_does(thesis):
    _, summary = thesis
    mean_post = np.asarray(summary["crossval"]["mean_posterior"])
    assert 0.76 <= mean_post[0, 0] <= 0.88, mean_post


def _region_truths(entry, obj, scenario):
    from palpate.core.world.scene import material_index_at

    origin, cell = np.asarray(obj["grid"]["origin_m"]), obj["grid"]["cell_size_m"]
    names = [m.name for m in entry.spec.materials()]
    out = []
    for c, r in obj["regions"]:
        xy = origin + (np.array([c, r]) - 0.5) * cell
        idx = material_index_at(entry.spec, np.array([[*xy, entry.spec.height - 0.002]]), names)[0]
        out.append(scenario.materials[names[idx]].like)
    return out


def test_explored_regions_are_mostly_read_as_their_material(thesis):
    scenario, summary = thesis
    refs = summary["materials"]
    for entry, obj in zip(scenario.objects, summary["objects"], strict=True):
        assert obj["presses"] == 10  # five regions x two presses, Table 6.8
        final = np.asarray(obj["posterior_per_cycle"][-1])
        truths = _region_truths(entry, obj, scenario)
        read = [refs[int(np.argmax(p))] for p in final]
        assert sum(a == b for a, b in zip(read, truths, strict=True)) >= 3, (obj["name"], read, truths)
        # post-processing spreads the explored evidence: more cells correct, lower entropy
        acc = obj["accuracy"]
        assert acc["all_cells_after_postprocessing"] > acc["all_cells_before_postprocessing"]
        assert obj["mean_entropy_after_postprocessing"] < obj["mean_entropy_after_each_press"][-1]


def test_object_1_reads_the_rubber_strip_as_the_second_material(thesis):
    # As in the seed (Table 6.9): two of Object_1's regions, those over the rubber strip, read as Material_2.
    scenario, summary = thesis
    obj = summary["objects"][0]
    final = np.asarray(obj["posterior_per_cycle"][-1])
    truths = _region_truths(scenario.objects[0], obj, scenario)
    assert truths.count("Material_2") == 2
    for p, truth in zip(final, truths, strict=True):
        if truth == "Material_2":
            assert int(np.argmax(p)) == 1, (p, truths)


def test_the_run_reports_its_training_presses_against_the_seeds_tables(thesis):
    """The realism targets that the fitted profile meets on the main job's seed (6, never tuned on); the others are
    reported in docs/results.md with benchmarks/realism_targets.py's numbers over held-out seeds."""
    _, summary = thesis
    report = summary["sim_to_real"]
    assert report["real_table"].endswith("seed000_tables_6_3_to_6_5.csv")
    assert "figures/sim_vs_real.png" in summary["figures"]
    m = report["materials"]
    assert set(m) == {"Material_1", "Material_2", "Material_3"}
    # on this seed the rubber's spread of n1 holds too (it holds on 4 seeds of 6),
    # but the sponge's and the rubber's CV of a1 (0.70 and 0.58 of the real) and the hard foam's n2 < 0 (-4 presses)
    # do not; docs/results.md has the counts over the held-out seeds
    for name in ("Material_1", "Material_2", "Material_3"):
        assert 0.7 <= m[name]["cv_ratio_n1"] <= 1.3, name
    assert 0.7 <= m["Material_3"]["cv_ratio_a1"] <= 1.3
    for name in ("Material_1", "Material_2"):
        assert abs(m[name]["negative_n2_per_10_difference"]) <= 2, name
    # the simulated spread of n1 is now of the real one's order on every material (it was a third to a sixth)
    assert all(e["cv_ratio_n1"] > 0.5 for e in m.values())
