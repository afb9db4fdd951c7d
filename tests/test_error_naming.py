"""Errors that name their file: a disk that fills up, a recording whose times are negative or whose presses hold
no frames, out-of-range options of ``palpate import session`` and ``palpate sweep`` and hostile sweep names are
one-line errors (exit code 2) naming the file, option or key."""

from __future__ import annotations

import dataclasses
import errno
import os
from pathlib import Path

import numpy as np
import pytest

from palpate.core.cli import main
from palpate.core.io import foxglove_messages
from palpate.core.io.mcap_reader import read_recording
from palpate.core.io.mcap_writer import RecordingWriter

REPO = Path(__file__).resolve().parent.parent
V1 = REPO / "tests" / "data" / "recording_v1"


def _error_line(err: str) -> str:
    lines = [line for line in err.strip().splitlines() if line.startswith("palpate: ")]
    assert len(lines) == 1 and "Traceback" not in err, err
    assert lines[0].startswith("palpate: error: "), err
    return lines[0]


def _shifted(dst: Path, shift: float, monkeypatch) -> Path:
    """The shipped recording with its taxel frames ``shift`` s later (another tool's file: log times clamped at 0,
    the message times kept)."""
    rec = read_recording(V1 / "run.mcap")
    real = foxglove_messages.time_ns
    with monkeypatch.context() as m:
        m.setattr(foxglove_messages, "time_ns", lambda t, what: real(max(t, 0.0), what))
        with RecordingWriter(dst, dict(rec.metadata)) as w:
            for a in rec.annotations:
                w.write_annotation(a.t, a.kind, dict(a.data))
            for f in rec.frames:
                w.write_taxel(dataclasses.replace(f, t=f.t + shift))
            for p in rec.poses:
                w.write_pose(p)
    return dst


def _replay(rec: Path, out: Path, capsys) -> tuple[int, str]:
    code = main(["replay", str(rec), "--memory", str(V1 / "memory.json"), "--out", str(out), "--no-figures",
                 "--quiet"])
    return code, _error_line(capsys.readouterr().err)


def test_negative_taxel_times_are_an_error_naming_the_file_and_field(tmp_path, capsys, monkeypatch):
    rec = _shifted(tmp_path / "negative.mcap", -100.0, monkeypatch)
    code, line = _replay(rec, tmp_path / "out", capsys)
    assert code == 2 and str(rec) in line and "/taxels/" in line and "field 't'" in line, line


def test_a_press_without_taxel_frames_is_an_error_naming_the_file_and_the_press(tmp_path, capsys, monkeypatch):
    rec = _shifted(tmp_path / "late.mcap", 1000.0, monkeypatch)
    code, line = _replay(rec, tmp_path / "out", capsys)
    assert code == 2 and str(rec) in line and "press annotation" in line and "no taxel frames" in line, line
    assert "1058" in line  # where the frames are: the recording's taxel span


def test_a_negative_max_offset_is_refused_before_any_work(tmp_path, capsys):
    out = tmp_path / "s.mcap"
    code = main(["import", "session", "--taxels", str(REPO / "tests" / "data" / "tekscan_press.csv"), "--poses",
                 str(V1 / "run.mcap"), "--out", str(out), "--max-offset", "-1"])
    line = _error_line(capsys.readouterr().err)
    assert code == 2 and "--max-offset" in line and "-1" in line, line
    assert not out.exists()


def _sweep_file(tmp_path: Path, name: str) -> Path:
    path = tmp_path / "s.toml"
    base = (REPO / "scenarios" / "sweeps" / "tiny_base.toml").as_posix()
    path.write_text(f'[sweep]\nname = "{name}"\nbase = "{base}"\n\n[[axes]]\nkey = "scenario.seed"\n'
                    "values = [1]\n")
    return path


@pytest.mark.parametrize("name", ["a\\u0000b", "a\\nb", "x" * 100_000], ids=["NUL", "newline", "100000 chars"])
def test_a_sweep_name_that_cannot_be_a_name_is_refused(tmp_path, capsys, name):
    sweep = _sweep_file(tmp_path, name)
    code = main(["sweep", str(sweep), "--out", str(tmp_path / "out")])
    line = _error_line(capsys.readouterr().err)
    assert code == 2 and str(sweep) in line and "sweep.name" in line and len(line) < 600, line
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("workers", ["100000", "0", "-3"])
def test_sweep_workers_out_of_range_are_refused(tmp_path, capsys, workers):
    sweep = _sweep_file(tmp_path, "ok")
    code = main(["sweep", str(sweep), "--out", str(tmp_path / "out"), "--workers", workers])
    line = _error_line(capsys.readouterr().err)
    assert code == 2 and "--workers" in line and workers in line, line
    assert not (tmp_path / "out").exists()


def _disk_full(*_args, **_kwargs):
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


def _replay_ok(tmp_path: Path, capsys) -> tuple[int, str]:
    code = main(["replay", str(V1 / "run.mcap"), "--memory", str(V1 / "memory.json"), "--out",
                 str(tmp_path / "out"), "--no-figures", "--quiet"])
    return code, _error_line(capsys.readouterr().err)


def test_a_full_disk_while_writing_the_summary_names_the_file(tmp_path, capsys, monkeypatch):
    real = Path.write_text
    # the summary goes whole or not at all through a hidden file beside it (.summary.json.<pid>.tmp)
    monkeypatch.setattr(Path, "write_text", lambda self, *a, **k: _disk_full() if "summary.json" in self.name
                        else real(self, *a, **k))
    code, line = _replay_ok(tmp_path, capsys)
    assert code == 2 and str(tmp_path / "out" / "summary.json") in line and "No space left" in line, line


def test_a_full_disk_while_writing_a_map_names_the_file(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(np, "savez_compressed", _disk_full)
    code, line = _replay_ok(tmp_path, capsys)
    assert code == 2 and str(tmp_path / "out" / "maps" / "slab.npz") in line and "No space left" in line, line


class _FillingFile:
    """A file that takes ``room`` bytes, then fails as a full disk does."""

    def __init__(self, f, room: int):
        self.f, self.room = f, room

    def write(self, data) -> int:
        if len(data) > self.room:
            _disk_full()
        self.room -= len(data)
        return self.f.write(data)

    def __getattr__(self, name):
        return getattr(self.f, name)


def test_a_full_disk_while_writing_a_recording_names_the_file(tmp_path, capsys, monkeypatch):
    from palpate.core.io import mcap_writer

    monkeypatch.setattr(mcap_writer, "open", lambda *a, **k: _FillingFile(open(*a, **k), 600), raising=False)
    out = tmp_path / "press.mcap"
    code = main(["import", "tekscan", str(REPO / "tests" / "data" / "tekscan_press.csv"), "--out", str(out)])
    line = _error_line(capsys.readouterr().err)
    assert code == 2 and str(out) in line and "No space left" in line, line
    assert not out.exists()
