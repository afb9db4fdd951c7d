"""`palpate devices scan dynamixel` and `palpate record dynamixel` as a user runs them, against the emulator."""

from __future__ import annotations

import json

import numpy as np
import pytest

from palpate.core.cli import main


def test_scan_json_lists_the_emulated_ids(capsys):
    assert main(["devices", "scan", "dynamixel", "--emulate", "1,3", "--max-id", "4", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["baud"] == 1_000_000
    assert [(s["id"], s["model_number"], s["model"]) for s in out["servos"]] == [
        (1, 1020, "XM430-W350"), (3, 1020, "XM430-W350")]


def test_scan_table_and_empty_bus_exit_code(capsys):
    assert main(["devices", "scan", "dynamixel", "--emulate", "5", "--max-id", "2"]) == 1
    assert "0 servo(s)" in capsys.readouterr().out


def test_scan_wrong_port_is_one_line_error(capsys, tmp_path):
    port = str(tmp_path / "ttyACM7")
    assert main(["devices", "scan", "dynamixel", "--port", port]) == 2
    err = capsys.readouterr().err
    assert "ttyACM7" in err and "Traceback" not in err


def test_scan_needs_a_port(capsys):
    assert main(["devices", "scan", "dynamixel"]) == 2
    assert "--port is required" in capsys.readouterr().err


def test_record_with_a_press_writes_joints_poses_and_annotations(tmp_path, repo_dir, capsys):
    recording = pytest.importorskip("palpate.core.io.mcap_reader")
    out = tmp_path / "rec.mcap"
    finger = str(repo_dir / "models" / "fingers" / "planar2.toml")
    code = main(["record", "dynamixel", "--emulate", "--finger", finger, "--seconds", "0.3", "--out", str(out),
                 "--press", "0.07", "--speed", "0.05", "--depth", "0.002"])
    assert code == 0, capsys.readouterr().err
    rec = recording.read_recording(out)
    assert len(rec.joints) == len(rec.poses) > 10
    assert rec.joints[0].names == ("mcp", "pip")
    assert [a.kind for a in rec.annotations] == ["press_start", "press_end", "recording_end"]
    assert rec.annotations[-1].data == {"stop_reason": "duration", "samples": len(rec.joints)}
    z = np.array([p.position[2] for p in rec.poses])
    assert z.min() == pytest.approx(0.03 - 0.002, abs=2e-4)  # pressed 2 mm into the surface at z = 0.03 m
    assert np.max(np.abs(np.stack([j.current for j in rec.joints]))) > 0  # the surface loaded the joints
    assert rec.metadata["sources"]["dynamixel"]["finger"] == "planar2"


def test_record_refuses_an_unreachable_press_before_opening_the_port(tmp_path, repo_dir, capsys):
    finger = str(repo_dir / "models" / "fingers" / "planar2.toml")
    code = main(["record", "dynamixel", "--port", str(tmp_path / "nope"), "--finger", finger, "--seconds", "1",
                 "--out", str(tmp_path / "r.mcap"), "--press", "0.5"])
    assert code == 2
    assert "out of reach" in capsys.readouterr().err
    assert not (tmp_path / "r.mcap").exists()
