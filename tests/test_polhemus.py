"""Polhemus Liberty: wire protocol, resynchronising parser, and the driver against the pty emulator through pyserial."""

from __future__ import annotations

import os
import signal
import struct
import subprocess
import sys
import time

import numpy as np
import pytest
from child_process import interruptible

from palpate.core.errors import DeviceError, ValidationError
from palpate.hardware.polhemus.driver import LibertyDriver, station_sensor_id
from palpate.hardware.polhemus.emulator import Faults, LibertyEmulator, press_motion
from palpate.hardware.polhemus.parser import RecordParser
from palpate.hardware.polhemus.protocol import (
    DEFAULT_ITEMS,
    ErrorEvent,
    Record,
    decode_ascii_line,
    encode_ascii,
    encode_binary,
    format_command,
    output_list_command,
    payload_size,
)
from palpate.hardware.polhemus.transport import SerialTransport

pytest.importorskip("serial")

RATE = 500.0  # Hz: 2 ms frames, distinct 1-ms device timestamps, a few hundred records in well under a second


def _records(items):
    return [i for i in items if isinstance(i, Record)]


def _events(items, kind=None):
    return [i for i in items if isinstance(i, ErrorEvent) and (kind is None or i.kind == kind)]


def _stream_bytes(n, rng, items=DEFAULT_ITEMS, station=1):
    pos = rng.normal(0.0, 30.0, (n, 3))
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    ts = np.arange(n, dtype=np.uint32) * 4
    data = encode_binary(items, np.full(n, station), "C", pos, q, ts, np.arange(n))
    return data, pos, q, ts


# ------------------------------------------------------------------------------------------------ protocol


def test_binary_record_layout_matches_the_manual_byte_for_byte():
    # Header 'L','Y', station, command, error, reserved, int16 LE size; then LE float32/uint32 in list order.
    pos, quat = (1.5, -2.25, 30.0), (0.5, 0.5, -0.5, 0.5)
    expected_payload = struct.pack("<3f4fII2s", *pos, *quat, 1234, 77, b"\r\n")
    expected = b"LY" + bytes([2, ord("C"), 0, 0]) + struct.pack("<h", len(expected_payload)) + expected_payload
    got = encode_binary((2, 7, 8, 9, 1), 2, "C", np.array(pos), np.array(quat), 1234, 77)
    assert got == expected
    assert payload_size((2, 7, 8, 9, 1)) == 38 == len(expected_payload)


def test_commands_are_formatted_as_the_liberty_expects():
    assert format_command("P") == b"P"  # single-byte commands act at once, no CR
    assert format_command("C") == b"C"
    assert format_command("F", 1) == b"F1\r"
    assert format_command("U", 1) == b"U1\r"
    assert output_list_command((2, 7, 8, 9, 1)) == b"O*,2,7,8,9,1\r"
    assert output_list_command((2, 7, 1), station=3) == b"O3,2,7,1\r"


def test_unknown_output_item_is_rejected_naming_it():
    with pytest.raises(ValidationError, match="item 5 is not supported"):
        output_list_command((2, 5, 1))
    with pytest.raises(ValidationError, match="must end with item 1"):
        RecordParser((2, 7, 8), binary=False)


def test_binary_parser_round_trips_any_chunking(rng):
    data, pos, q, ts = _stream_bytes(300, rng)
    parser = RecordParser()
    out = []
    cuts = np.sort(rng.integers(0, len(data), 60))
    for a, b in zip(np.r_[0, cuts], np.r_[cuts, len(data)], strict=True):
        out += parser.feed(data[a:b])
    recs = _records(out)
    assert _events(out) == [] and parser.flush() == []
    assert len(recs) == 300
    np.testing.assert_allclose([r.position for r in recs], pos, rtol=1e-6)  # float32 on the wire
    np.testing.assert_allclose([r.quaternion for r in recs], q, rtol=1e-6, atol=1e-7)
    assert [r.timestamp_ms for r in recs] == ts.tolist()
    assert [r.frame for r in recs] == list(range(300))


def test_parser_resynchronises_after_garbage_and_cut_records(rng):
    data, pos, _, ts = _stream_bytes(20, rng)
    size = len(data) // 20
    rec = [data[i * size : (i + 1) * size] for i in range(20)]
    junk = b"\x00\x13LYxx\xff"  # contains 'LY' that is not a plausible header
    stream = b"".join(
        [rec[0], junk, rec[1], rec[2][:17], rec[3], b"L", rec[4], *rec[5:9], rec[9][: size - 1], *rec[10:]]
    )
    parser = RecordParser(stations=(1,))
    out = []
    for i in range(0, len(stream), 13):
        out += parser.feed(stream[i : i + 13])
    out += parser.flush()
    got = [r.timestamp_ms for r in _records(out)]
    assert got == [t for i, t in enumerate(ts.tolist()) if i not in (2, 9)]
    assert len(_events(out, "partial")) == 2
    assert sum(e.nbytes for e in _events(out, "garbage")) == len(junk) + 1
    assert parser.bytes_dropped == len(junk) + 17 + 1 + size - 1


@pytest.mark.parametrize("seed", range(6))
def test_random_damage_loses_exactly_the_damaged_records_in_any_chunking(seed):
    rng = np.random.default_rng(seed)
    n = 300
    data, _, _, ts = _stream_bytes(n, rng, station=int(rng.integers(1, 17)))
    size = len(data) // n
    parts, kept, wasted = [], [], 0
    for i in range(n):
        rec = data[i * size : (i + 1) * size]
        if rng.random() < 0.1:
            junk = rng.integers(0, 256, int(rng.integers(1, 60)), dtype=np.uint8)
            junk[junk == ord("L")] = 0
            parts.append(junk.tobytes())
            wasted += junk.size
        if rng.random() < 0.1:
            rec = rec[: int(rng.integers(1, size))]
            wasted += len(rec)
        else:
            kept.append(int(ts[i]))
        parts.append(rec)
    stream = b"".join(parts)
    parser = RecordParser()
    out = []
    cuts = np.sort(rng.integers(0, len(stream), int(rng.integers(1, 400))))
    for a, b in zip(np.r_[0, cuts], np.r_[cuts, len(stream)], strict=True):
        out += parser.feed(stream[a:b])
    out += parser.flush()
    assert [r.timestamp_ms for r in _records(out)] == kept
    assert parser.bytes_dropped == wasted == sum(e.nbytes for e in _events(out))


def test_parser_drops_a_well_framed_record_whose_values_are_not_a_pose(rng):
    data, _, _, ts = _stream_bytes(5, rng)
    size = len(data) // 5
    bad = bytearray(data)
    bad[2 * size + 8 + 12 : 2 * size + 8 + 16] = struct.pack("<f", np.nan)  # quaternion w of record 2 -> NaN
    out = RecordParser().feed(bytes(bad))
    assert [r.timestamp_ms for r in _records(out)] == [t for i, t in enumerate(ts.tolist()) if i != 2]
    assert len(_events(out, "implausible")) == 1
    for r in _records(out):
        assert np.all(np.isfinite(r.position)) and np.all(np.isfinite(r.quaternion))


def test_device_error_byte_is_reported_and_later_records_kept(rng):
    items = DEFAULT_ITEMS
    q = np.array([1.0, 0, 0, 0])
    data = b"".join(
        encode_binary(items, 1, "C", np.zeros(3), q, i, i, error=(0x45 if i == 3 else 0)) for i in range(6)
    )
    out = RecordParser().feed(data)
    assert [r.frame for r in _records(out)] == [0, 1, 2, 4, 5]
    (ev,) = _events(out, "device_error")
    assert ev.record.error == 0x45 and ev.record.frame == 3 and "error code 69" in ev.message


def test_garbage_alone_does_not_grow_the_parser_buffer(rng):
    parser = RecordParser()
    junk = rng.integers(0, 256, 200_000, dtype=np.uint8)
    junk[junk == ord("L")] = 0
    out = parser.feed(junk.tobytes())
    assert len(parser._pending) < 8
    assert sum(e.nbytes for e in out) == 200_000 - len(parser._pending)


def test_ascii_records_round_trip_and_bad_lines_are_named():
    line = encode_ascii(DEFAULT_ITEMS, 2, "P", np.array([1.25, -3.5, 40.0]), np.array([0.6, 0.8, 0.0, 0.0]), 99, 7)
    assert line.endswith(b"\r\n") and line.startswith(b"02P ")
    rec = decode_ascii_line(line[:-2], DEFAULT_ITEMS)
    assert rec.station == 2 and rec.command == "P" and rec.error == 0
    np.testing.assert_allclose(rec.position, [1.25, -3.5, 40.0])
    assert (rec.timestamp_ms, rec.frame) == (99, 7)
    parser = RecordParser(binary=False)
    out = parser.feed(line + b"01C  1.0 2.0 oops\r\n" + line)
    assert len(_records(out)) == 2
    (bad,) = _events(out, "bad_line")
    assert "oops" in bad.message or "expected" in bad.message


# ------------------------------------------------------------------------------------------------ driver


@pytest.fixture
def liberty():
    """Open an emulator and a driver on it through pyserial; closes both."""
    opened = []

    def make(stations=(1,), driver_stations=None, units="cm", binary=True, baud=115200, emu_baud=115200,
             timeout=0.3, configure=True, **emu_kwargs):
        emu = LibertyEmulator(rate=emu_kwargs.pop("rate", RATE), stations=stations, baud=emu_baud, **emu_kwargs)
        opened.append(emu)
        transport = SerialTransport(emu.port, baud, timeout=0.02)
        opened.append(transport)
        drv = LibertyDriver(transport, stations=driver_stations or stations, units=units, binary=binary,
                            timeout=timeout)
        if configure:
            drv.configure()
        return emu, drv

    yield make
    for thing in reversed(opened):
        thing.close()


def _sent_after_configure(emu, n_configure_records):
    return emu.log[n_configure_records:]


def test_continuous_stream_matches_the_emulated_press_in_metres(liberty):
    motion = press_motion(depth=0.005, period=0.4, origin=(0.02, -0.01, 0.05), tilt=0.3)
    noise = 2e-4
    emu, drv = liberty(noise=noise, seed=3, motion=motion)
    # configure() sends P twice (once to stop a stream, once to check the answer): two records.
    assert emu.commands == ["P", "F1", "U1", "O*,2,7,8,9,1", "P"] and emu.units == "cm" and emu.binary
    poses = list(drv.stream(seconds=0.4))
    poses += drv.stop()
    sent = emu.log[2:]
    assert len(poses) == len(sent) > 50  # everything sent was received
    t = np.array([p.t for p in poses])
    assert np.allclose(t, [ts / 1000.0 for _, ts, _, _ in sent])
    assert np.allclose(np.diff(t), 1.0 / RATE, atol=1.01e-3)  # device clock, 1 ms resolution
    expected = np.array([motion(ti, 1)[0] for ti in t])
    err = np.array([p.position for p in poses]) - expected
    assert np.all(np.abs(err) < 5 * noise + 1e-6)  # cm -> m: a factor-100 mistake would be 0.005 m or more
    assert 0.3 * noise < err.std() < 2 * noise  # and the noise is really there
    z = np.array([p.position[2] for p in poses])
    assert z.min() < 0.05 - 0.004  # the press is visible
    q_expected = np.array([motion(ti, 1)[1] for ti in t])
    np.testing.assert_allclose([p.quaternion for p in poses], q_expected, atol=1e-6)
    assert drv.stats.errors == [] and drv.stats.stop_reason == "duration"
    assert {p.sensor_id for p in poses} == {station_sensor_id(1)}


def test_single_record_in_inches_is_converted_to_metres(liberty):
    emu, drv = liberty(units="in", motion=press_motion(depth=0.0, origin=(0.1, 0.2, 0.3)))
    assert emu.units == "in"
    (pose,) = drv.single()
    np.testing.assert_allclose(pose.position, [0.1, 0.2, 0.3], atol=1e-6)
    assert emu.log[-1][1] / 1000.0 == pose.t  # time is the device clock


def test_ascii_mode_two_stations(liberty):
    emu, drv = liberty(stations=(1, 2), binary=False, motion=press_motion(depth=0.003, period=0.3))
    assert not emu.binary
    poses = list(drv.stream(seconds=0.25)) + drv.stop()
    by = {s: [p for p in poses if p.sensor_id == station_sensor_id(s)] for s in (1, 2)}
    assert len(by[1]) == len(by[2]) == len(emu.log[4:]) // 2 > 20
    for s in (1, 2):
        for p in by[s][::10]:
            # ASCII carries 4 decimals of cm: 1e-6 m.
            np.testing.assert_allclose(p.position, press_motion(depth=0.003, period=0.3)(p.t, s)[0], atol=1.5e-6)
    assert drv.stats.errors == []


def test_corrupt_bytes_and_partial_records_lose_only_the_damaged_records(liberty):
    faults = Faults(corrupt_every=5, corrupt_bytes=9, partial_every=7)
    emu, drv = liberty(faults=faults)
    poses = list(drv.stream(seconds=0.3)) + drv.stop()
    sent = emu.log[2:]
    good = [ts for _, ts, f, _ in sent if "partial" not in f]
    assert [round(p.t * 1000) for p in poses] == good
    assert len(good) < len(sent)
    # Every byte that belongs to no good record is accounted for as dropped, and nothing else is.
    assert drv._parser.bytes_dropped == sum(w for *_, w in sent)
    kinds = drv.stats.error_counts()
    assert kinds["partial"] == sum("partial" in f for _, _, f, _ in sent)
    assert kinds["garbage"] >= 1


def test_ascii_stream_recovers_from_garbage_and_cut_lines(liberty):
    emu, drv = liberty(binary=False, faults=Faults(corrupt_every=4, corrupt_bytes=11, partial_every=9))
    poses = list(drv.stream(seconds=0.3)) + drv.stop()
    sent = emu.log[2:]
    assert [round(p.t * 1000) for p in poses] == [ts for _, ts, f, _ in sent if "partial" not in f]
    assert drv._parser.bytes_dropped == sum(w for *_, w in sent)


def test_device_error_byte_is_reported_and_the_stream_goes_on(liberty):
    emu, drv = liberty(faults=Faults(error_every=4, error_code=0x42))
    poses = list(drv.stream(seconds=0.2)) + drv.stop()
    sent = emu.log[2:]
    flagged = [ts for _, ts, f, _ in sent if f == "device_error"]
    assert flagged
    assert [round(p.t * 1000) for p in poses] == [ts for _, ts, f, _ in sent if f == ""]
    events = [e for e in drv.stats.errors if e.kind == "device_error"]
    assert [e.record.timestamp_ms for e in events] == flagged
    assert all(e.record.error == 0x42 for e in events)


def test_device_going_silent_mid_stream_stops_cleanly_keeping_records(liberty):
    emu, drv = liberty(faults=Faults(silent_after=80), timeout=0.2)
    poses = list(drv.stream(seconds=30.0))  # would hang for 30 s if silence were not detected
    assert drv.stats.stop_reason == "silent"
    tail = drv.stop()
    assert tail == []
    assert [round(p.t * 1000) for p in poses] == [ts for _, ts, _, _ in emu.log[2:]]
    assert len(poses) == 78


def test_wrong_port_names_the_port():
    with pytest.raises(DeviceError, match="/dev/nonexistent-liberty"):
        SerialTransport("/dev/nonexistent-liberty", 115200)


def test_usb_without_pyusb_says_what_to_install(monkeypatch):
    from palpate.hardware.polhemus.transport import UsbTransport

    monkeypatch.setitem(sys.modules, "usb", None)  # import usb.core fails as when pyusb is absent
    monkeypatch.setitem(sys.modules, "usb.core", None)
    with pytest.raises(DeviceError, match="pyusb"):
        UsbTransport()


def test_without_the_timestamp_item_times_come_from_the_host_clock(liberty):
    emu, _ = liberty(configure=False)
    transport = SerialTransport(emu.port, 115200, timeout=0.02)
    try:
        drv = LibertyDriver(transport, items=(2, 7, 9, 1), timeout=0.3)
        drv.configure()
        assert drv.time_base == "host" and emu.items[1] == (2, 7, 9, 1)
        before = time.monotonic()
        poses = list(drv.stream(max_records=20))
        drv.stop()
    finally:
        transport.close()
    t = np.array([p.t for p in poses])
    assert len(t) == 20 and t[0] >= before and np.all(np.diff(t) >= 0) and t[-1] <= time.monotonic()


def test_wrong_baud_says_no_answer_at_that_baud(liberty):
    with pytest.raises(DeviceError, match=r"at 9600 baud.*baud rate"):
        liberty(baud=9600, emu_baud=115200, timeout=0.2)


def test_wrong_baud_with_a_device_left_streaming_reports_garbage_not_records(liberty):
    emu, drv = liberty(baud=38400, emu_baud=115200, timeout=0.2, configure=False)
    emu.start_continuous()
    with pytest.raises(DeviceError, match=r"no valid record.*baud"):
        drv.configure()
    assert emu.garbled_bytes_in > 0 and emu.commands == []


def test_a_station_without_sensor_is_named(liberty):
    with pytest.raises(DeviceError, match=r"station\(s\) \[2\]"):
        liberty(stations=(1,), driver_stations=(1, 2), timeout=0.2)


class _BytesTransport:
    """An in-memory link that replays canned device output (for clock edge cases an emulator cannot reach fast)."""

    description = "memory"

    def __init__(self, data: bytes, after_stop: bytes = b""):
        self.data = data
        self.after_stop = after_stop

    def read(self, n):
        out, self.data = self.data[:n], self.data[n:]
        if not out:
            time.sleep(0.005)  # as a serial read timeout would
        return out

    def write(self, data):
        if data == b"P":
            self.data += self.after_stop

    def reset_input(self):
        self.data = b""


def test_device_clock_unwraps_past_2_to_the_32_ms():
    ts = np.array([2**32 - 4, 2**32 - 2, 0, 2], dtype=np.uint32)
    q = np.tile([1.0, 0, 0, 0], (4, 1))
    data = encode_binary(DEFAULT_ITEMS, np.ones(4, int), "C", np.zeros((4, 3)), q, ts, np.arange(4))
    drv = LibertyDriver(_BytesTransport(data), timeout=0.05)
    drv.streaming = True
    t = [p.t for p in drv.stream(max_records=4)]
    np.testing.assert_allclose(np.diff(t), 0.002, atol=1e-9)


def test_a_record_straddling_the_end_of_a_timed_stream_is_kept_by_stop():
    q = np.tile([1.0, 0, 0, 0], (4, 1))
    data = encode_binary(DEFAULT_ITEMS, np.ones(4, int), "C", np.zeros((4, 3)), q, np.arange(4) * 2, np.arange(4))
    cut = len(data) - 20  # the timed stream ends while the 4th record is half received
    drv = LibertyDriver(_BytesTransport(data[:cut], after_stop=data[cut:]), timeout=1.0)
    drv.streaming = True
    poses = list(drv.stream(seconds=0.05))
    # the third record is held until its successor can confirm it (the plausibility check)
    assert drv.stats.stop_reason == "duration" and len(poses) == 2
    tail = drv.stop()
    assert [p.t for p in tail] == [0.004, 0.006]
    assert drv.stats.errors == []


# ------------------------------------------------------------------------------------------------ CLI


def test_cli_records_emulated_stations_into_mcap(tmp_path, capsys):
    from palpate.core.cli import main
    from palpate.core.io.mcap_reader import read_recording

    out = tmp_path / "lib.mcap"
    rc = main(["record", "liberty", "--emulate", "--emulate-rate", "400", "--stations", "1,2",
               "--seconds", "0.3", "--out", str(out)])
    assert rc == 0
    text = capsys.readouterr().out
    assert "station 1:" in text and "station 2:" in text and "errors: none" in text
    rec = read_recording(out)
    ids = [p.sensor_id for p in rec.poses]
    n1, n2 = ids.count("liberty_station1"), ids.count("liberty_station2")
    assert n1 == n2 > 50 and n1 + n2 == len(ids)
    t1 = [p.t for p in rec.poses if p.sensor_id == "liberty_station1"]
    rate = (n1 - 1) / (t1[-1] - t1[0])
    assert abs(rate - 400.0) < 4.0  # 2.5 ms frames stamped to the ms
    assert f"{n1} at {rate:.1f} Hz" in text
    assert rec.metadata["sources"]["pose"]["stations"] == [1, 2]
    assert rec.metadata["sources"]["pose"]["time_base"] == "device"
    (end,) = [a for a in rec.annotations if a.kind == "liberty_stream_end"]
    assert end.data["records"] == {"1": n1, "2": n2}
    # Station 2 sits 5 cm along x from station 1 in the emulated press.
    x1 = np.mean([p.position[0] for p in rec.poses if p.sensor_id == "liberty_station1"])
    x2 = np.mean([p.position[0] for p in rec.poses if p.sensor_id == "liberty_station2"])
    assert abs((x2 - x1) - 0.05) < 1e-3


def test_cli_bad_arguments_exit_2_with_a_message(tmp_path, capsys):
    from palpate.core.cli import main

    assert main(["record", "liberty", "--seconds", "1", "--out", str(tmp_path / "x.mcap")]) == 2
    assert "--port" in capsys.readouterr().err
    assert main(["record", "liberty", "--emulate", "--stations", "1,0", "--seconds", "1",
                 "--out", str(tmp_path / "x.mcap")]) == 2
    assert "'0' is not a station" in capsys.readouterr().err


def test_cli_ctrl_c_keeps_what_was_recorded(tmp_path):
    from palpate.core.io.mcap_reader import read_recording

    out = tmp_path / "int.mcap"
    proc = subprocess.Popen(
        [sys.executable, "-c", "import sys; from palpate.core.cli import main; sys.exit(main())",
         "record", "liberty", "--emulate", "--emulate-rate", "300", "--seconds", "60", "--out", str(out)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=interruptible,
    )
    try:
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline and (not out.exists() or out.stat().st_size < 4000):
            time.sleep(0.1)
        proc.send_signal(signal.SIGINT)
        stdout, stderr = proc.communicate(timeout=20)
    finally:
        if proc.poll() is None:
            os.kill(proc.pid, signal.SIGKILL)
    assert proc.returncode == 130, stderr
    assert "interrupted" in stderr and "stopped: interrupted" in stdout
    rec = read_recording(out)  # finished properly: no salvage needed
    assert len(rec.poses) > 10 and not rec.salvaged
    assert [a.kind for a in rec.annotations] == ["liberty_stream_end"]
