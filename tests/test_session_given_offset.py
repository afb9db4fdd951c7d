"""``palpate import session --clock-offset``: a given offset is checked against the presses, so a tracker recording
of other presses is refused (naming both files) instead of merged into a session of nonsense presses."""

from __future__ import annotations

import pytest
from clock_streams import human_streams

from palpate.core.alignment.clock import ClockMap
from palpate.core.alignment.clock_check import check_clock_map
from palpate.core.cli import main
from palpate.core.errors import ValidationError
from palpate.core.io.mcap_writer import RecordingWriter

OFFSET = -2.5  # s added to the tracker's times to put them on the pad's clock


def _write(path, frames=(), poses=()):
    with RecordingWriter(path, {"scenario": None}) as w:
        for f in frames:
            w.write_taxel(f)
        for p in poses:
            w.write_pose(p)


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("given")
    frames, poses, _ = human_streams(5, presses=10, offset=OFFSET)
    _, other, _ = human_streams(6, presses=10, offset=OFFSET)
    _write(d / "pad.mcap", frames=frames)
    _write(d / "liberty.mcap", poses=poses)
    _write(d / "other.mcap", poses=other)
    return d, frames, poses, other


def test_the_right_offset_is_confirmed_by_the_presses(files):
    _, frames, poses, _ = files
    assert check_clock_map(frames, poses, ClockMap(offset=OFFSET)) >= 9
    with pytest.raises(ValidationError, match="pairs 0 of"):  # a quarter-period off pairs no press
        check_clock_map(frames, poses, ClockMap(offset=OFFSET + 0.6))


def test_a_given_offset_with_a_recording_of_other_presses_is_refused(files, capsys):
    d, frames, _, other = files
    with pytest.raises(ValidationError, match="not of the same presses"):
        check_clock_map(frames, other, ClockMap(offset=OFFSET))
    args = ["import", "session", "--taxels", str(d / "pad.mcap"), "--clock-offset", str(OFFSET)]
    assert main([*args, "--poses", str(d / "other.mcap"), "--out", str(d / "bad.mcap")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "pad.mcap" in err and "other.mcap" in err
    assert not (d / "bad.mcap").exists()
    assert main([*args, "--poses", str(d / "liberty.mcap"), "--out", str(d / "good.mcap")]) == 0
    assert "(given)" in capsys.readouterr().out
