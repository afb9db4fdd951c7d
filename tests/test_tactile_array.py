"""The live tactile array: its wire format (binary frame with sync, counter, counts and CRC; CSV line with an XOR
checksum) parsed in any chunking, and the emulator on a pty read through pyserial with lost and corrupted frames
counted, never invented, each frame timed by its counter."""

from __future__ import annotations

import time

import numpy as np
import pytest

from palpate.core.errors import ValidationError
from palpate.hardware.clock import FastClock, read_arrived
from palpate.hardware.polhemus.transport import SerialTransport
from palpate.hardware.tactile.emulator import TactileArrayEmulator, TactileFaults
from palpate.hardware.tactile.protocol import FrameParser, crc16, encode_binary, encode_csv
from palpate.hardware.tactile.reader import TactileArrayReader

AREA = 4.84e-6


def test_crc_is_ccitt_false():
    assert crc16(b"123456789") == 0x29B1  # the standard check value of CRC-16/CCITT-FALSE


@pytest.mark.parametrize("fmt", ["binary", "csv"])
def test_frames_round_trip_in_any_chunking_and_damage_is_counted(fmt, rng):
    counts = rng.integers(0, 256, (30, 3, 5)).astype(np.uint8)
    encode = encode_binary if fmt == "binary" else encode_csv
    frames = [encode(65530 + k, c) for k, c in enumerate(counts)]  # the counter wraps on the way
    frames[7] = frames[7][:-5] + bytes([frames[7][-5] ^ 1]) + frames[7][-4:]  # a flipped bit: the checksum fails
    stream = b"\x00\xa5junk" + b"".join(frames[:12]) + b"\xa5\x5a\x03" + b"".join(frames[12:])
    for _ in range(4):
        parser = FrameParser(3, 5, fmt)
        cuts = np.sort(rng.choice(np.arange(1, len(stream)), 40, replace=False))
        got = [f for piece in np.split(np.frombuffer(stream, np.uint8), cuts) for f in parser.feed(piece.tobytes())]
        keep = [k for k in range(30) if k != 7]
        assert [f.counter for f in got] == [(65530 + k) % 65536 for k in keep]
        np.testing.assert_array_equal(np.array([f.counts for f in got]), counts[keep])
        assert parser.corrupt >= 1 and parser.garbage > 0
    with pytest.raises(ValidationError, match="1..64 rows"):
        FrameParser(0, 4)


@pytest.mark.parametrize("fmt", ["binary", "csv"])
def test_the_emulator_read_through_pyserial_counts_lost_and_corrupt_frames(fmt):
    clock = FastClock(5.0)
    faults = TactileFaults(drop_every=7, corrupt_every=11)
    source = lambda t: np.full((4, 4), round(t * 100) % 256, dtype=np.uint8)  # noqa: E731 - counts: the frame index
    with TactileArrayEmulator(source, rate=100.0, fmt=fmt, clock=clock, faults=faults) as emu, \
            TactileArrayReader(emu.port, sensel_area=AREA, fmt=fmt, rate=100.0, clock=clock) as reader:
        deadline = time.monotonic() + 20.0
        while reader.stats.frames < 300 and time.monotonic() < deadline:
            time.sleep(0.02)
    frames = reader.drain()
    stats = reader.stats
    assert len(frames) == stats.frames >= 300
    # between the first and the last frame read, every counter is either a frame kept or a frame lost (dropped, or
    # arrived corrupted and counted as such too)
    first, last = frames[0].t, frames[-1].t
    n_span = int(round((last - first) * 100.0)) + 1
    assert stats.frames + stats.lost == n_span
    assert stats.lost == pytest.approx(n_span / 7 + n_span / 11 - n_span / 77, abs=3)  # frame 77 is dropped
    assert stats.corrupt == pytest.approx(n_span / 11 - n_span / 77, abs=3)
    # every frame is at its counter's time: a frame read late keeps its time, and the counts say which it is
    t = np.array([f.t for f in frames])
    steps = np.diff(t) * 100.0
    np.testing.assert_allclose(steps, np.round(steps), atol=1e-6)
    assert np.all(np.round(steps) >= 1)
    index = np.round((t - t[0]) * 100.0).astype(int) + int(frames[0].counts[0, 0])
    np.testing.assert_array_equal([int(f.counts[0, 0]) for f in frames], index % 256)


def test_a_silent_array_is_reported_not_filled_in():
    with TactileArrayEmulator(lambda t: np.zeros((4, 4), np.uint8), rate=200.0,
                              faults=TactileFaults(silent_after=40)) as emu, \
            TactileArrayReader(emu.port, sensel_area=AREA, rate=200.0, timeout=0.2) as reader:
        deadline = time.monotonic() + 10.0
        while not reader.stats.silent and time.monotonic() < deadline:
            time.sleep(0.02)
    frames = reader.drain()
    # the frames sent before the port was opened are gone; after them, every frame up to the 40th, and none after
    assert reader.stats.silent and reader.stats.lost == 0 and 30 <= len(frames) == reader.stats.frames <= 40
    assert frames[-1].t - frames[0].t == pytest.approx((len(frames) - 1) / 200.0, abs=1e-6)


class _WaitingPort:
    """A pyserial port with ``waiting`` bytes in its buffer that records how many bytes each read asks for (a
    read asking for more than is there waits out the timeout, and everything in it is stamped at its end)."""

    def __init__(self, waiting: int, on_read=lambda: None):
        self.in_waiting = waiting
        self.asked: list[int] = []
        self._on_read = on_read

    def read(self, n: int) -> bytes:
        self.asked.append(n)
        self._on_read()
        return bytes(min(n, max(self.in_waiting, 1)))


def test_both_serial_readers_take_what_has_arrived_instead_of_waiting_out_the_timeout():
    # what is there is read at once; with nothing there, one byte is waited for; a read never asks beyond its limit
    for waiting, limit, asked in ((37, 4096, 37), (0, 4096, 1), (9000, 4096, 4096)):
        port = _WaitingPort(waiting)
        assert len(read_arrived(port, limit)) == asked and port.asked == [asked]
    # the tactile array's reading loop (stopped after one read) and the Liberty's serial transport
    reader = TactileArrayReader("unused", sensel_area=AREA)
    reader._serial = port = _WaitingPort(37, on_read=reader._stop.set)
    reader._run()
    assert port.asked == [37]
    transport = SerialTransport.__new__(SerialTransport)
    transport._serial = port = _WaitingPort(37)
    assert len(transport.read(1 << 14)) == 37 and port.asked == [37]
