"""``palpate memory train | crossval | show`` through palpate.core.cli.main."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from palpate.core.cli import main
from palpate.core.perception.crossval import leave_one_out
from palpate.core.perception.memory import HapticMemory
from palpate.core.perception.params_table import read_params_csv

THESIS_CSV = Path(__file__).resolve().parent.parent / "models" / "realism" / "seed000_tables_6_3_to_6_5.csv"


def _table_rows(text: str, title: str, n: int) -> dict[str, list[float]]:
    """Parse the n rows under the header line following ``title`` into {material: numbers}."""
    lines = text.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith(title)) + 2
    return {line.split()[0]: [float(v) for v in line.split()[1:]] for line in lines[start : start + n]}


def test_crossval_prints_confusion_and_mean_posterior(capsys):
    assert main(["memory", "crossval", str(THESIS_CSV), "--ddof", "1"]) == 0
    out = capsys.readouterr().out
    conf = _table_rows(out, "MAP confusion", 3)
    post = _table_rows(out, "Mean posterior", 3)
    # MAP fractions, presses, accuracy
    assert conf["Material_1"] == [0.8, 0.2, 0.0, 10, 0.8]
    assert conf["Material_3"] == [0.0, 0.0, 1.0, 10, 1.0]
    # the mean posterior is what seed 000 prints as Table 6.7 (0.82 / 0.18)
    assert post["Material_1"] == [0.819, 0.181, 0.0]
    assert "Overall accuracy: 28/30 = 0.933" in out
    # columns are aligned: every table line has its numbers ending at the same offsets
    lines = out.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("true \\ perceived"))
    assert len({len(line) for line in lines[start : start + 4]}) == 1


def test_crossval_json_matches_library(capsys):
    assert main(["memory", "crossval", str(THESIS_CSV), "--json", "--prior", "1,1,2"]) == 0
    doc = json.loads(capsys.readouterr().out)
    params, labels, _ = read_params_csv(THESIS_CSV)
    cv = leave_one_out(params, labels, prior=[0.25, 0.25, 0.5])
    assert doc["materials"] == ["Material_1", "Material_2", "Material_3"]
    np.testing.assert_array_equal(doc["confusion"], cv.confusion)
    np.testing.assert_array_equal(doc["mean_posterior"], cv.mean_posterior)
    assert doc["counts"] == cv.counts.astype(int).tolist()


def test_train_then_show(tmp_path, capsys):
    out_path = tmp_path / "memory.json"
    assert main(["memory", "train", str(THESIS_CSV), "-o", str(out_path), "--ddof", "1", "--prior", "2,1,1"]) == 0
    assert "trained on 30 presses of 3 materials" in capsys.readouterr().out
    mem = HapticMemory.load(out_path)
    assert mem.ddof == 1
    np.testing.assert_allclose(mem.prior, [0.5, 0.25, 0.25])

    assert main(["memory", "show", str(out_path)]) == 0
    out = capsys.readouterr().out
    assert "trained on 30 presses" in out and "ddof=1" in out
    n_rows = _table_rows(out, "N = (n1, n2)", 3)
    assert n_rows["Material_2"][0] == pytest.approx(432.62)
    assert n_rows["Material_1"][2] == pytest.approx(mem.covs_N[0, 0, 0], rel=1e-5)
    summary = _table_rows(out, "Haptic memory", 3)
    assert summary["Material_1"] == [0.5, 10, 0, 0]  # prior, presses, loading N, loading A

    assert main(["memory", "show", str(out_path), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    np.testing.assert_array_equal(doc["covs_A"], mem.covs_A)
    assert doc["training_size"] == {"Material_1": 10, "Material_2": 10, "Material_3": 10}
    assert "regularisation" in doc


def test_show_reports_regularisation(tmp_path, capsys):
    csv = tmp_path / "line.csv"
    rows = ["material,n1,n2,a1,a2"]
    rows += [f"line,{100 + 10 * i},{5 - i},{3 + 0.1 * i},{10 + i}" for i in range(3)]
    rows += [f"blob,{v[0]},{v[1]},{v[2]},{v[3]}" for v in np.random.default_rng(3).normal(5, 2, (4, 4))]
    csv.write_text("\n".join(rows) + "\n")
    mem_path = tmp_path / "m.json"
    assert main(["memory", "train", str(csv), "-o", str(mem_path)]) == 0
    assert "regularised (relative diagonal loading): line N" in capsys.readouterr().out
    assert main(["memory", "show", str(mem_path)]) == 0
    summary = _table_rows(capsys.readouterr().out, "Haptic memory", 2)
    assert summary["line"][2] > 0 and summary["line"][3] > 0
    assert summary["blob"][2:] == [0, 0]


def test_bad_csv_exit_2_names_line_and_column(tmp_path, capsys):
    bad = tmp_path / "params.csv"
    text = THESIS_CSV.read_text().splitlines()
    header = text[0].split(",")
    fields = text[6].split(",")  # file line 7: Material_1, run 6
    fields[header.index("a1")] = "abc"
    text[6] = ",".join(fields)
    bad.write_text("\n".join(text) + "\n")
    for cmd in (["crossval", str(bad)], ["train", str(bad), "-o", str(tmp_path / "m.json")]):
        assert main(["memory", *cmd]) == 2
        err = capsys.readouterr().err
        assert "params.csv:7: column 'a1': 'abc' is not a number" in err
    assert not (tmp_path / "m.json").exists()


def test_bad_inputs_exit_2(tmp_path, capsys):
    assert main(["memory", "crossval", str(THESIS_CSV), "--prior", "1,x,1"]) == 2
    assert "--prior '1,x,1'" in capsys.readouterr().err
    assert main(["memory", "crossval", str(THESIS_CSV), "--prior", "1,1"]) == 2
    assert "prior has 2 values but there are 3 materials" in capsys.readouterr().err
    assert main(["memory", "show", str(tmp_path / "absent.json")]) == 2
    assert "absent.json" in capsys.readouterr().err
    broken = tmp_path / "broken.json"
    doc = json.loads(HapticMemory.from_table(THESIS_CSV).to_json())
    del doc["covs_A"]
    broken.write_text(json.dumps(doc))
    assert main(["memory", "show", str(broken)]) == 2
    assert "missing key 'covs_A'" in capsys.readouterr().err


@pytest.mark.parametrize("cmd", [[], ["train"], ["crossval"], ["show"]])
def test_help_everywhere(cmd, capsys):
    with pytest.raises(SystemExit) as info:
        main(["memory", *cmd, "--help"])
    assert info.value.code == 0
    out = capsys.readouterr().out
    assert out.startswith("usage: palpate memory")
    assert len(out.splitlines()) > 4
