"""Tekscan ASCII/CSV movie import: both Frame-line variants, CRLF, B cells, regions, units, errors, CLI -> MCAP.

``tests/data/tekscan_press.csv`` is a hand-written 6x6 hand-map export (CRLF, ``B`` in the four corners) holding one
press on the 4x4 pad at rows 1..4, cols 1..4 (region ``1:5,1:5``): in frame k the pad's centre 2x2 reads a_k and
its 12-cell ring reads max(0, a_k - 40), with a_k = PRESS_AMPLITUDE[k]; cells outside the pad hold noise <= 3
(NOISE_THRESHOLD 3). Sensel area 0.0645 cm^2, 0.01 s per frame.

``tests/data/tekscan_newframe.csv`` is the newer variant (``Frame 10, 0.000, 0.0 ms``), LF ends, spreadsheet padding,
free key spellings, kPa with SATURATION_PRESSURE 510 kPa: frame k holds p_k on the centre 2x2 and p_k/2 at (0, 0).
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from palpate.core.cli import main
from palpate.core.errors import ValidationError
from palpate.core.io.mcap_reader import read_recording
from palpate.hardware.tekscan.importer import import_tekscan, parse_start_time
from palpate.hardware.tekscan.reader import (
    TekscanWarning,
    parse_region,
    parse_tekscan,
    read_tekscan,
    select_region,
)

PRESS_AMPLITUDE = np.array([0, 20, 60, 120, 160, 120, 60, 20, 0])
NEW_PRESSURE_KPA = np.array([0.0, 100.0, 255.0])


def _expected_pad(a: int) -> np.ndarray:
    pad = np.full((4, 4), max(0, a - 40))
    pad[1:3, 1:3] = a
    return pad


def test_press_file_crlf_b_cells_and_header(data_dir):
    raw = (data_dir / "tekscan_press.csv").read_bytes()
    assert b"\r\n" in raw and b"B," in raw  # the fixture really exercises CRLF and B cells
    movie = read_tekscan(data_dir / "tekscan_press.csv")
    assert movie.counts.shape == (9, 6, 6) and movie.counts.dtype == np.uint8
    assert np.array_equal(movie.frame_numbers, np.arange(1, 10))
    assert np.allclose(movie.t, 0.01 * np.arange(9), rtol=0, atol=1e-12)
    assert movie.sensel_area == pytest.approx(0.0645e-4, rel=1e-12)
    assert movie.row_spacing == pytest.approx(2.54e-3) and movie.col_spacing == pytest.approx(2.54e-3)
    corners = np.zeros((6, 6), bool)
    corners[[0, 0, 5, 5], [0, 5, 0, 5]] = True
    assert np.array_equal(movie.mask, ~corners)
    assert np.all(movie.counts[:, corners] == 0)
    assert movie.noise_threshold == 3 and movie.units == "RAW" and movie.header["SENSOR_TYPE"] == "4256E-hand"


def test_region_selects_the_pad_with_the_known_press(data_dir):
    pad = select_region(read_tekscan(data_dir / "tekscan_press.csv"), "1:5,1:5")
    assert pad.shape == (4, 4) and pad.region == (1, 5, 1, 5) and pad.mask.all()
    for k, a in enumerate(PRESS_AMPLITUDE):
        assert np.array_equal(pad.counts[k], _expected_pad(a))
    # c_P: sum of counts; c_A: sensels above the noise threshold x sensel area (eq. 6.2, 6.3 of seed 000).
    c_P = pad.counts.reshape(9, -1).sum(axis=1, dtype=np.int64)
    c_A = (pad.counts > pad.noise_threshold).reshape(9, -1).sum(axis=1) * pad.sensel_area
    ring = np.maximum(PRESS_AMPLITUDE - 40, 0)
    assert np.array_equal(c_P, 4 * PRESS_AMPLITUDE + 12 * ring)
    assert np.allclose(c_A, (4 * (PRESS_AMPLITUDE > 3) + 12 * (ring > 3)) * 0.0645e-4, rtol=1e-12)
    assert int(np.argmax(c_P)) == 4  # peak of the press in the middle frame
    # a sub-region of a region keeps file coordinates
    inner = select_region(pad, (1, 3, 1, 3))
    assert inner.region == (2, 4, 2, 4) and np.array_equal(inner.counts[:, 0, 0], PRESS_AMPLITUDE)


def test_newer_frame_line_variant_and_pressure_units(data_dir):
    movie = read_tekscan(data_dir / "tekscan_newframe.csv")
    assert np.array_equal(movie.frame_numbers, [10, 11, 12])
    assert np.allclose(movie.t, [0.0, 0.005, 0.010], atol=1e-12)
    assert movie.sensel_area == pytest.approx(0.258e-4) and movie.row_spacing == pytest.approx(5.08e-3)
    # count = round(255 p / p_sat), p_sat = 510 kPa
    expect = np.rint(255 * NEW_PRESSURE_KPA / 510.0)
    assert np.array_equal(movie.counts[:, 1, 1], expect) and np.array_equal(movie.counts[:, 2, 2], expect)
    assert np.array_equal(movie.counts[:, 0, 0], np.rint(255 * NEW_PRESSURE_KPA / 2 / 510.0))
    assert movie.noise_threshold == round(255 * 4 / 510) and movie.mask.all()


def _export(frames: list[np.ndarray], *, variant: str = "classic", header: str | None = None, eol="\r\n") -> str:
    rows, cols = frames[0].shape
    head = header if header is not None else (
        f"ROWS {rows}\nCOLS {cols}\nSENSEL_AREA 0.26 cm2\nSECONDS_PER_FRAME 0.01\nUNITS RAW\nASCII_DATA @@\n")
    body = ""
    for k, f in enumerate(frames):
        line = f"Frame {k + 1}" if variant == "classic" else f"Frame {k + 1}, {0.01 * k:.3f}, 0, 0"
        body += "\n" + line + "\n" + "\n".join(",".join(str(v) for v in r) for r in f) + "\n"
    return (head + body).replace("\n", eol)


def test_both_frame_variants_give_identical_frames(rng):
    frames = [rng.integers(0, 256, (5, 7)) for _ in range(6)]
    a = parse_tekscan(_export(frames, variant="classic"))
    b = parse_tekscan(_export(frames, variant="new", eol="\n"))
    assert np.array_equal(a.counts, np.array(frames)) and np.array_equal(a.counts, b.counts)
    assert np.array_equal(a.t, b.t)


HEADER = "ROWS 2\nCOLS 3\nSENSEL_AREA 0.26 cm2\nSECONDS_PER_FRAME 0.01\nUNITS RAW\nASCII_DATA @@\n"


@pytest.mark.parametrize(("text", "message"), [
    (HEADER.replace("ROWS 2\n", ""), r"grip.csv: header has no ROWS line"),
    (HEADER.replace("ROWS 2", "ROWS two"), r"grip.csv:1: ROWS must be a whole number, got 'two'"),
    (HEADER.replace("COLS 3\n", "COLS 3\nCOLS 4\n"), r"grip.csv:3: header key COLS given twice \(first on line 2\)"),
    (HEADER.replace("0.26 cm2", "0.26 (furlong2)"), r"grip.csv:3: SENSEL_AREA must be a positive area with a unit"),
    (HEADER.replace("0.26 cm2", "0.26"), r"grip.csv:3: SENSEL_AREA must be a positive area with a unit"),
    (HEADER.replace("0.01", "0"), r"grip.csv:4: SECONDS_PER_FRAME must be > 0"),
    (HEADER.replace("RAW", "furlongs"), r"grip.csv:5: UNITS 'furlongs' not understood"),
    (HEADER.replace("RAW", "kPa"), r"grip.csv:5: UNITS 'kPa' is not RAW and the header has no SATURATION_PRESSURE"),
    (HEADER + "\nFrame 1\n1,2,3\n4,5\n", r"grip.csv:10: expected 3 values, got 2"),
    (HEADER + "\nFrame 1\n1,2,3\n4,5,6,7\n", r"grip.csv:10: expected 3 values, got 4"),
    (HEADER + "\nFrame 1\n1,2,3\n", r"grip.csv:8: Frame 1 has 1 rows of values, expected ROWS = 2"),
    (HEADER + "\nFrame 1\n1,2,3\n4,x,6\n", r"grip.csv:10: value 2 is 'x', expected a number or B"),
    (HEADER + "\nFrame 1\n1,2,3\n4,,6\n", r"grip.csv:10: value 2 is '', expected a number or B"),
    (HEADER + "\nFrame 1\n1,2,3\n4,nan,6\n", r"grip.csv:10: value 2 is 'nan', expected a finite number"),
    (HEADER + "\nFrame 1\n1,2,300\n4,5,6\n", r"grip.csv:9: value 3 is 300, expected a RAW count 0..255"),
    (HEADER + "\nFrame 1\n1,2,3\n4,5,6.5\n", r"grip.csv:10: value 3 is 6.5, expected a RAW count"),
    (HEADER + "\nFrame 2\n1,2,3\n4,5,6\n\nFrame 1\n1,2,3\n4,5,6\n", r"grip.csv:12: Frame 1 follows Frame 2"),
    (HEADER + "\n1,2,3\nFrame 1\n1,2,3\n4,5,6\n", r"grip.csv:8: values before the first 'Frame N' line"),
    ("FRAMES 2\n" + HEADER + "\nFrame 1\n1,2,3\n4,5,6\n", r"grip.csv:1: FRAMES says 2 frames, the file has 1"),
    (HEADER, r"grip.csv: no 'Frame N' line after the header"),
    ("hello there\n", r"grip.csv: no 'ASCII_DATA @@' line"),
    ("ROWS 2\n42 is not a key\nASCII_DATA @@\n", r"grip.csv:2: expected a header line 'KEY value'"),
])
def test_errors_name_file_and_line(text, message):
    with pytest.raises(ValidationError, match=message):
        parse_tekscan(text, "grip.csv")


def test_pressure_export_needs_full_scale_and_clips_with_warning():
    text = HEADER.replace("RAW", "psi") + "\nFrame 1\n0,1,2\n3,4,50\n"
    with pytest.warns(TekscanWarning, match="1 values above the saturation pressure"):  # 4 psi full scale
        movie = parse_tekscan(text, "p.csv", full_scale_pa=4 * 6894.757293168)
    assert np.array_equal(movie.counts[0], np.rint(np.array([[0, 1, 2], [3, 4, 4]]) * 255 / 4))
    # a per-sensel force export is divided by the sensel area first: 0.26 cm^2 at 1 N -> 38.46 kPa
    force = parse_tekscan(HEADER.replace("RAW", "N") + "\nFrame 1\n0,1,0\n0,0,0\n", full_scale_pa=100e3)
    assert force.counts[0, 0, 1] == round(255 * (1 / 0.26e-4) / 100e3)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # nothing clipped -> no warning
        parse_tekscan(HEADER.replace("RAW", "kPa") + "\nFrame 1\n0,1,2\n3,4,5\n", full_scale_pa=1e4)


def test_region_parsing_and_bounds(data_dir):
    assert parse_region(" 1:5 , 2:6 ") == (1, 5, 2, 6)
    for bad in ("1:5", "5:1,0:4", "a:b,c:d", "1:5;1:5", ""):
        with pytest.raises(ValidationError, match="region"):
            parse_region(bad)
    movie = read_tekscan(data_dir / "tekscan_press.csv")
    with pytest.raises(ValidationError, match=r"tekscan_press.csv: region 3:7,0:4 lies outside the 6x6 map"):
        select_region(movie, "3:7,0:4")


def test_start_time_parsing():
    assert parse_start_time(None) == 0.0
    assert parse_start_time("1970-01-02T00:00:00Z") == 86400.0
    assert parse_start_time("1970-01-02T01:00:00+01:00") == 86400.0
    assert parse_start_time("1970-01-02T00:00:00") == 86400.0  # no zone: UTC
    with pytest.raises(ValidationError, match="not an ISO 8601"):
        parse_start_time("yesterday")


def test_cli_import_to_mcap_and_back(data_dir, tmp_path, capsys):
    out = tmp_path / "press.mcap"
    code = main(["import", "tekscan", str(data_dir / "tekscan_press.csv"), "--out", str(out),
                 "--region", "1:5,1:5", "--start-time", "2024-05-02T14:30:00Z", "--sensor-id", "index"])
    assert code == 0
    printed = capsys.readouterr().out
    assert "9 frames of 4x4" in printed and f"peak c_P {4 * 160 + 12 * 120}" in printed
    rec = read_recording(out)
    t0 = parse_start_time("2024-05-02T14:30:00Z")
    assert [f.sensor_id for f in rec.frames] == ["index"] * 9
    assert np.allclose([f.t - t0 for f in rec.frames], 0.01 * np.arange(9), atol=1e-6)
    for f, a in zip(rec.frames, PRESS_AMPLITUDE, strict=True):
        assert np.array_equal(f.counts, _expected_pad(a)) and f.sensel_area == pytest.approx(0.0645e-4)
    src = rec.metadata["sources"][0]
    assert src["kind"] == "tekscan_ascii" and src["region"] == [1, 5, 1, 5] and len(src["sha256"]) == 64
    assert rec.metadata["tekscan"]["noise_threshold_counts"] == 3
    end = rec.annotations[-1]
    assert end.kind == "tekscan_import" and end.data["frames"] == 9 and end.data["frame_numbers"] == [1, 9]
    assert end.data["sensor_mask"] == [[1] * 4] * 4  # the B cells of the 6x6 map are outside the pad


def test_cli_bad_file_prints_error_and_exits_2(tmp_path, capsys):
    bad = tmp_path / "grip.csv"
    bad.write_text(HEADER + "\nFrame 1\n1,2,3\n4,5\n")
    code = main(["import", "tekscan", str(bad), "--out", str(tmp_path / "x.mcap")])
    err = capsys.readouterr().err
    assert code == 2 and "grip.csv:10: expected 3 values, got 2" in err and "Traceback" not in err
    assert main(["import", "tekscan", str(tmp_path / "missing.csv"), "--out", str(tmp_path / "y.mcap")]) == 2
    assert "cannot read Tekscan export" in capsys.readouterr().err
    good = tmp_path / "good.csv"
    good.write_text(HEADER + "\nFrame 1\n1,2,3\n4,5,6\n")
    assert main(["import", "tekscan", str(good), "--out", str(tmp_path / "no_dir" / "z.mcap")]) == 2
    assert "cannot open for writing" in capsys.readouterr().err


def test_import_function_summary(data_dir, tmp_path):
    summary = import_tekscan(data_dir / "tekscan_press.csv", tmp_path / "all.mcap")
    assert summary.frames == 9 and summary.shape == (6, 6) and summary.b_cells == 4
    assert summary.duration == pytest.approx(0.08) and summary.start_time == 0.0
    assert summary.peak_active == 16  # the 4x4 pad at the peak; outside noise stays at or below the threshold
