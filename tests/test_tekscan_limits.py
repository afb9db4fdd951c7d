"""Tekscan exports read as streams in bounded memory, and what no real export holds refused with one clear line:
devices and links to them, files over the size limit, maps larger than any sensor, frame numbers, periods and start
times a recording cannot hold. A failed import leaves no file behind and never overwrites the export."""

from __future__ import annotations

import os

import numpy as np
import pytest

from palpate.core.cli import main
from palpate.core.errors import ValidationError
from palpate.core.io.mcap_reader import read_recording
from palpate.hardware.tekscan import stream
from palpate.hardware.tekscan.importer import import_tekscan
from palpate.hardware.tekscan.reader import parse_tekscan, read_tekscan
from palpate.hardware.tekscan.stream import ExportStream

HEADER = "ROWS 2\nCOLS 3\nSENSEL_AREA 0.26 cm2\nSECONDS_PER_FRAME 0.01\nUNITS RAW\nASCII_DATA @@\n"


def _export(n: int, rng: np.random.Generator, eol: str = "\r\n") -> tuple[str, np.ndarray]:
    counts = rng.integers(0, 256, (n, 2, 3))
    text = HEADER + "".join(f"\nFrame {k + 1}\n" + "\n".join(",".join(map(str, r)) for r in c) + "\n"
                            for k, c in enumerate(counts))
    return text.replace("\n", eol), counts


@pytest.mark.parametrize("eol", ["\r\n", "\n", "\r"])
def test_any_split_into_pieces_and_blocks_reads_the_same_frames(rng, monkeypatch, eol):
    text, counts = _export(40, rng, eol)
    whole = parse_tekscan(text, "grip.csv")
    np.testing.assert_array_equal(whole.counts, counts)
    monkeypatch.setattr(stream, "BLOCK_BYTES", 37)  # blocks of a frame or two
    for _ in range(5):
        cuts = np.sort(rng.choice(np.arange(1, len(text)), size=30, replace=False))
        pieces = iter(np.split(np.array(list(text)), cuts))
        s = ExportStream(("".join(p) for p in pieces), "grip.csv")
        blocks = list(s.blocks())
        assert len(blocks) > 5
        np.testing.assert_array_equal(np.concatenate([b.values for b in blocks]), counts)
        np.testing.assert_array_equal(np.concatenate([b.numbers for b in blocks]), np.arange(1, 41))
    # an error in a later block still names its line
    bad = text.replace(f"Frame 31{eol}", f"Frame 29{eol}")
    with pytest.raises(ValidationError, match=r"grip.csv:\d+: Frame 29 follows Frame 30"):
        list(ExportStream(iter([bad]), "grip.csv").blocks())


def test_devices_links_and_folders_are_not_read(tmp_path):
    link = tmp_path / "grip.csv"
    os.symlink("/dev/zero", link)
    with pytest.raises(ValidationError, match=r"grip.csv: cannot read Tekscan export: not a regular file .*link"):
        read_tekscan(link)
    with pytest.raises(ValidationError, match="not a regular file"):
        import_tekscan(tmp_path, tmp_path / "x.mcap")
    assert not (tmp_path / "x.mcap").exists()


def test_a_file_over_the_size_limit_is_refused_and_the_limit_can_be_raised(tmp_path, rng, capsys):
    path = tmp_path / "grip.csv"
    text, _ = _export(50, rng)
    path.write_text(text, newline="")
    size = path.stat().st_size
    with pytest.raises(ValidationError, match=r"more than the .* MB read by default; raise the limit with "
                                              r"--max-bytes"):
        read_tekscan(path, max_bytes=size - 1)
    assert main(["import", "tekscan", str(path), "--out", str(tmp_path / "a.mcap"), "--max-bytes",
                 str(size - 1)]) == 2
    assert "--max-bytes" in capsys.readouterr().err
    assert main(["import", "tekscan", str(path), "--out", str(tmp_path / "a.mcap"), "--max-bytes", str(size)]) == 0


@pytest.mark.parametrize(("text", "message"), [
    (HEADER.replace("ROWS 2", "ROWS 20000").replace("COLS 3", "COLS 20000"), r"a 20000 x 20000 map is larger"),
    (HEADER.replace("ROWS 2", "ROWS 99999999999999999999"), r"grip.csv:1: ROWS 9+\.\.\. is too large"),
    (HEADER.replace("0.01", "1e300"), r"frame period of 1e\+300 s is longer than 3600 s"),
    (HEADER + "\nFrame 99999999999999999999\n1,2,3\n4,5,6\n", r"grip.csv:8: frame number 9+ is too large"),
    (HEADER + "\nFrame " + "9" * 5000 + "\n1,2,3\n4,5,6\n", r"grip.csv:8: frame number 9+ is too large"),
])
def test_sizes_no_sensor_has_are_one_line_errors(text, message):
    with pytest.raises(ValidationError, match=message):
        parse_tekscan(text, "grip.csv")


def test_times_a_recording_cannot_hold_are_refused_naming_the_frame_and_leave_nothing(tmp_path, capsys):
    path = tmp_path / "grip.csv"
    # legal on its own (an hour per frame, frame 2^52) but 1.6e19 s after 1970: past what MCAP log times hold
    path.write_text(HEADER.replace("0.01", "3600") + "\nFrame 1\n1,2,3\n4,5,6\n\nFrame 4503599627370496\n"
                    "1,2,3\n4,5,6\n")
    out = tmp_path / "x.mcap"
    assert main(["import", "tekscan", str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "grip.csv:12: Frame 4503599627370496 falls" in err and "Traceback" not in err
    assert not out.exists() and not list(tmp_path.glob("*.partial"))
    good = tmp_path / "good.csv"
    good.write_text(HEADER + "\nFrame 1\n1,2,3\n4,5,6\n")
    assert main(["import", "tekscan", str(good), "--out", str(out), "--start-time", "9999-12-31T23:59:59Z"]) == 2
    assert "after 2554-07-21, which MCAP log times" in capsys.readouterr().err
    assert main(["import", "tekscan", str(good), "--out", str(out), "--start-time", "2554-07-01T00:00:00Z"]) == 0


def test_the_export_is_never_its_own_output(tmp_path, capsys):
    path = tmp_path / "grip.csv"
    path.write_text(HEADER + "\nFrame 1\n1,2,3\n4,5,6\n")
    before = path.read_bytes()
    assert main(["import", "tekscan", str(path), "--out", str(path), "--force"]) == 2
    assert "is an input of this command" in capsys.readouterr().err
    with pytest.raises(ValidationError, match="is the Tekscan export being imported"):
        import_tekscan(path, path)
    assert path.read_bytes() == before
    assert main(["import", "tekscan", str(path), "--out", str(tmp_path / "r.mcap")]) == 0
    assert len(read_recording(tmp_path / "r.mcap").frames) == 1
