"""Outputs are never written through a symbolic link: an ``--out`` folder or an output file (``--record``,
``palpate import ... --out``) that is a link is refused with one line naming the option, even with ``--force``,
and nothing lands in the link's target."""

from __future__ import annotations

from pathlib import Path

import pytest

from palpate.core.cli import main

REPO = Path(__file__).resolve().parent.parent
V1 = REPO / "tests" / "data" / "recording_v1"
TINY = REPO / "scenarios" / "sweeps" / "tiny_base.toml"


def _error_line(err: str) -> str:
    lines = [line for line in err.strip().splitlines() if line.startswith("palpate: ")]
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


@pytest.mark.parametrize("force", [False, True], ids=["plain", "force"])
def test_a_symlinked_out_folder_is_refused(tmp_path, capsys, force):
    target = tmp_path / "target"
    target.mkdir()
    link = tmp_path / "out"
    link.symlink_to(target)
    code = main(["replay", str(V1 / "run.mcap"), "--memory", str(V1 / "memory.json"), "--out", str(link),
                 "--no-figures", "--quiet", *(["--force"] if force else [])])
    line = _error_line(capsys.readouterr().err)
    assert code == 2 and "--out" in line and str(link) in line and "symbolic link" in line, line
    assert list(target.iterdir()) == [] and link.is_symlink()


@pytest.mark.parametrize("force", [False, True], ids=["plain", "force"])
def test_a_symlinked_record_file_is_refused(tmp_path, capsys, force):
    target = tmp_path / "elsewhere.mcap"
    target.write_bytes(b"keep")
    link = tmp_path / "rec.mcap"
    link.symlink_to(target)
    code = main(["run", str(TINY), "--out", str(tmp_path / "run"), "--record", str(link), "--quiet",
                 *(["--force"] if force else [])])
    line = _error_line(capsys.readouterr().err)
    assert code == 2 and "--record" in line and str(link) in line and "symbolic link" in line, line
    assert target.read_bytes() == b"keep" and not (tmp_path / "run").exists()


def test_a_dangling_symlinked_import_output_is_refused(tmp_path, capsys):
    link = tmp_path / "rec.mcap"
    link.symlink_to(tmp_path / "nowhere" / "x.mcap")
    code = main(["import", "tekscan", str(REPO / "tests" / "data" / "tekscan_press.csv"), "--out", str(link),
                 "--force"])
    line = _error_line(capsys.readouterr().err)
    assert code == 2 and "--out" in line and "symbolic link" in line, line
    assert not (tmp_path / "nowhere").exists()
