"""``palpate record session``: a live tactile array and a Liberty (their emulators, one fingertip pressing a block
every 2 s) recorded into one file on one host clock; the file replays to presses; a device going silent ends the
command with exit code 1 and a finished file."""

from __future__ import annotations

from palpate.core.alignment.clock import estimate_clock_map
from palpate.core.alignment.merge import session_pipeline
from palpate.core.cli import main
from palpate.core.io.mcap_reader import read_recording
from palpate.core.io.recording import recording_to_press_recording
from palpate.core.perception.pipeline import presses_from_recording
from palpate.hardware.rig import session_record
from palpate.hardware.tactile.emulator import TactileArrayEmulator, TactileFaults


def test_both_devices_on_one_host_clock_in_one_file(tmp_path, capsys):
    out = tmp_path / "session.mcap"
    assert main(["record", "session", "--emulate", "--seconds", "4.6", "--out", str(out)]) == 0
    assert "taxel frames (0 lost, 0 corrupt)" in capsys.readouterr().out
    rec = read_recording(out)
    assert len(rec.frames) > 150 and len(rec.poses) > 700
    assert rec.metadata["session"]["perception"] == {"press_axis_from_motion": True}
    # the two devices' clocks were never told about each other; on the host clock the presses line up
    cmap = estimate_clock_map(rec.frames, rec.poses, max_offset=0.5)  # a steady rhythm needs a bound
    assert cmap.presses >= 2 and abs(cmap.offset) < 0.005, cmap
    stream = recording_to_press_recording(rec)
    seg = presses_from_recording(stream, session_pipeline(rec.metadata))
    assert len(seg.presses) >= 2
    # 3 mm into the block (the perception's first-contact height runs a few tenths of a mm high at this pad's
    # low first counts, and moves with the millisecond the two devices' arrivals put between them)
    assert all(0.0025 < p.depth < 0.0045 for p in seg.presses)


def test_a_silent_tactile_array_ends_the_recording_with_exit_1_and_a_finished_file(tmp_path, capsys, monkeypatch):
    def silent_after_60(*args, **kwargs):
        return TactileArrayEmulator(*args, faults=TactileFaults(silent_after=60), **kwargs)

    monkeypatch.setattr(session_record, "TactileArrayEmulator", silent_after_60)
    out = tmp_path / "session.mcap"
    code = main(["record", "session", "--emulate", "--seconds", "20", "--out", str(out), "--timeout", "0.3"])
    err = capsys.readouterr().err
    assert code == 1 and "the tactile array went silent" in err and "Traceback" not in err
    rec = read_recording(out)  # finished
    end = rec.annotations[-1]
    assert end.kind == "session_end" and end.data["taxels"]["silent"]
    assert 0 < len(rec.frames) <= 60 and len(rec.poses) > 0
