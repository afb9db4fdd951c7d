"""Progress output: tqdm bars on a terminal, one line per finished stage in a log, nothing with --quiet/--json."""

from __future__ import annotations

import io
import tomllib
from pathlib import Path

from palpate.core.cli import main
from palpate.core.session.progress import Progress


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_a_log_gets_one_line_per_finished_stage():
    log = io.StringIO()
    p = Progress(stream=log)
    p.start("training soft", 3)
    for k in range(1, 4):
        p.update(k)
    p.start("reading rec.mcap", 3 * 2**20, unit="B")
    p.update(3 * 2**20)
    p.message("fidelity analytic: because")
    lines = log.getvalue().splitlines()
    assert len(lines) == 3 and "\r" not in log.getvalue()
    assert lines[0].startswith("training soft: 3/3 in ") and lines[0].endswith(" s")
    assert lines[1].startswith("reading rec.mcap: 3.0 MiB in ")
    assert lines[2] == "fidelity analytic: because"


def test_a_terminal_gets_a_live_bar_and_disabled_progress_prints_nothing():
    term = _Terminal()
    p = Progress(stream=term)
    p.start("exploring slab", 4)
    p.update(2, "cell 3,1")
    p.message("between")
    p.update(4)
    out = term.getvalue()
    assert "exploring slab" in out and "\r" in out and "4/4" in out and "between\n" in out
    quiet = _Terminal()
    q = Progress(enabled=False, stream=quiet)
    q.start("x", 2)
    q.update(2)
    q.message("y")
    assert quiet.getvalue() == ""


def test_run_json_keeps_stderr_empty(tmp_path, capsys):
    small = (Path(__file__).parent / "test_run.py").read_text().split('SMALL = """', 1)[1].split('"""', 1)[0]
    raw = small.replace("render_3d = false", "render_3d = false\nfigures = false\nhaptic_material = false")
    scenario = tmp_path / "small.toml"
    scenario.write_text(raw)
    assert tomllib.loads(raw)["outputs"]["figures"] is False
    assert main(["run", str(scenario), "--out", str(tmp_path / "out"), "--json"]) == 0
    captured = capsys.readouterr()
    assert captured.err == "" and captured.out.lstrip().startswith("{")
