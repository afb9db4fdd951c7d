"""The sim-to-real report: table statistics against numpy, the energy distance's properties, the summary entry,
its printed form and its figure."""

import json
from pathlib import Path

import numpy as np
import pytest

from palpate.core.errors import ValidationError
from palpate.core.io.realism_figures import plot_sim_vs_real
from palpate.core.perception.param_stats import (
    STAT_COLUMNS,
    PressTable,
    column_stats,
    energy_distance,
    material_distance,
    table_from_csv,
)
from palpate.core.session.sim_to_real import format_sim_to_real, sim_to_real_summary

SEED_TABLE = Path(__file__).resolve().parent.parent / "models" / "realism" / "seed000_tables_6_3_to_6_5.csv"


def test_column_statistics_are_numpys():
    x = np.array([3.0, -1.0, 4.0, 1.0, -5.0])
    s = column_stats(x)
    assert s.mean == pytest.approx(np.mean(x)) and s.sd == pytest.approx(np.std(x, ddof=1))
    assert s.cv == pytest.approx(np.std(x, ddof=1) / abs(np.mean(x)))
    assert s.negative_fraction == pytest.approx(0.4) and s.n == 5
    assert column_stats([1.0, -1.0]).cv is None  # a zero mean has no CV (never NaN in a report)
    with pytest.raises(ValidationError):
        column_stats([1.0])


def test_the_seed_table_reads_with_its_residual_columns():
    t = table_from_csv(SEED_TABLE)
    assert t.materials == ("Material_1", "Material_2", "Material_3")
    m3 = t.of("Material_3")
    assert m3.shape == (10, 6)
    assert column_stats(m3[:, 1]).negative_fraction == pytest.approx(0.8)  # Table 6.5: n2 < 0 in 8 presses
    assert column_stats(m3[:, 2]).mean == pytest.approx(np.mean([5091.9, 69435.6, 31394.8, 26389.5, 671769.1,
                                                                13875.6, 19706.1, 8201.4, 19224.5, 410851.5]))


def test_a_table_without_residuals_is_refused(tmp_path):
    p = tmp_path / "t.csv"
    p.write_text("material,n1,n2,a1,a2\nm,1,2,3,4\nm,2,3,4,5\n")
    with pytest.raises(ValidationError, match="phi_n"):
        table_from_csv(p)


def test_energy_distance_is_zero_for_one_sample_and_grows_with_the_shift(rng):
    x = rng.normal(size=(40, 4))
    assert energy_distance(x, x, np.ones(4)) == pytest.approx(0.0, abs=1e-12)
    near = energy_distance(x, x + 0.2, np.ones(4))
    far = energy_distance(x, x + 2.0, np.ones(4))
    assert 0 < near < far
    # standardising by the scale makes it unit-free
    assert energy_distance(x * 100, (x + 2.0) * 100, np.full(4, 100.0)) == pytest.approx(far)
    # two samples of one distribution are close; a distribution 5x wider is not
    y = rng.normal(size=(40, 4))
    assert energy_distance(x, y, np.ones(4)) < energy_distance(x, 5 * y, np.ones(4))


def _sim_like(real: PressTable, factor: float) -> PressTable:
    return PressTable(real.materials, tuple(r * factor for r in real.rows))


def test_the_summary_entry_compares_every_column_and_is_json(tmp_path):
    real = table_from_csv(SEED_TABLE)
    sim = _sim_like(real, 1.0)
    doc = sim_to_real_summary(sim, real, SEED_TABLE)
    json.dumps(doc, allow_nan=False)
    m1 = doc["materials"]["Material_1"]
    assert set(m1["columns"]) == set(STAT_COLUMNS)
    assert m1["energy_distance"] == pytest.approx(0.0, abs=1e-12)
    assert m1["cv_ratio_n1"] == pytest.approx(1.0) and m1["negative_n2_per_10_difference"] == 0.0
    scaled = sim_to_real_summary(_sim_like(real, 2.0), real, SEED_TABLE)["materials"]["Material_3"]
    assert scaled["columns"]["n1"]["sim"]["mean"] == pytest.approx(2 * scaled["columns"]["n1"]["real"]["mean"])
    assert scaled["cv_ratio_n1"] == pytest.approx(1.0)
    assert scaled["energy_distance"] > 0.5
    assert material_distance(real.of("Material_3") * 2.0, real.of("Material_3")) == scaled["energy_distance"]
    text = format_sim_to_real(doc)
    assert "Material_2" in text and "energy distance" in text and "phi_a" in text


def test_the_figure_is_written(tmp_path):
    real = table_from_csv(SEED_TABLE)
    path = plot_sim_vs_real(tmp_path / "sim_vs_real.png", _sim_like(real, 0.5), real)
    assert path.stat().st_size > 10_000
