"""Bounded MCAP reads: declared and inflated chunk sizes, record sizes and message counts are checked before
anything is allocated; each limit fails with a clear error naming the file and the variable that raises it."""

from __future__ import annotations

import os
import struct
import subprocess
import sys
import zlib
from pathlib import Path

import numpy as np
import pytest

from palpate.core.errors import RecordingError, ValidationError
from palpate.core.io.mcap_reader import read_recording
from palpate.core.io.mcap_records import MAGIC, ReadLimits
from palpate.core.io.mcap_writer import RecordingWriter
from palpate.core.perception.streams import TaxelFrame


def _record(op: int, body: bytes) -> bytes:
    return struct.pack("<BQ", op, len(body)) + body


def _string(s: str) -> bytes:
    b = s.encode()
    return struct.pack("<I", len(b)) + b


def _map(entries: dict[str, str]) -> bytes:
    body = b"".join(_string(k) + _string(v) for k, v in entries.items())
    return struct.pack("<I", len(body)) + body


def _zstd_rle(total: int, byte: int = 0) -> bytes:
    """A zstd frame of ``total`` bytes ``byte`` made of RLE blocks (4 bytes per 128 KiB): 2 GiB in 64 KiB."""
    out = bytearray(struct.pack("<I", 0xFD2FB528)) + bytes([0x00, 7 << 3])  # no content size; 128 KiB window
    left = total
    while left > 0:
        n = min(1 << 17, left)
        left -= n
        out += ((left == 0) | (1 << 1) | (n << 3)).to_bytes(3, "little") + bytes([byte])
    return bytes(out)


def _mcap(path, chunk_records: bytes, declared: int, compression: str = "zstd", crc: int = 0) -> None:
    """A palpate recording (format 2 metadata) holding one chunk, assembled byte by byte."""
    chunk = struct.pack("<QQQI", 0, 0, declared, crc) + _string(compression)
    chunk += struct.pack("<Q", len(chunk_records)) + chunk_records
    data = MAGIC + _record(0x01, _string("") + _string("test")) + _record(
        0x0C, _string("palpate") + _map({"format_version": "2"})) + _record(0x06, chunk)
    data += _record(0x0F, struct.pack("<I", 0)) + _record(0x02, struct.pack("<QQI", 0, 0, 0)) + MAGIC
    path.write_bytes(data)


def test_a_chunk_declaring_gigabytes_fails_before_decompressing(tmp_path):
    path = tmp_path / "bomb.mcap"
    _mcap(path, _zstd_rle(2 << 30), declared=2 << 30)
    assert path.stat().st_size < 70_000
    with pytest.raises(RecordingError, match=r"bomb.mcap: the chunk at byte \d+, decompressed, is 2147.48 MB, over "
                                             r"the limit mcap_mb = 64 MB \(raise it with palpate --limit mcap_mb=N "
                                             r"or PALPATE_LIMITS=mcap_mb=N; see docs/limits.md\)"):
        read_recording(path)


BOMB_READER = """
import resource, sys
resource.setrlimit(resource.RLIMIT_AS, (1 << 30, 1 << 30))  # 1 GiB of address space: a 2 GiB inflation fails
from palpate.core.errors import RecordingError, ValidationError
from palpate.core.io.mcap_reader import read_recording
try:
    read_recording(sys.argv[1])
except RecordingError as exc:
    print(exc)
"""


def test_a_chunk_that_inflates_past_its_declared_size_fails_within_bounded_memory(tmp_path):
    path = tmp_path / "liar.mcap"
    _mcap(path, _zstd_rle(2 << 30), declared=4096)
    # In a child limited to 1 GiB of address space: reading the whole 2 GiB would die with MemoryError.
    done = subprocess.run([sys.executable, "-c", BOMB_READER, str(path)], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr
    assert "liar.mcap: recording is corrupt at byte" in done.stdout
    assert "inflates to more than 4096 bytes, not its declared 4096" in done.stdout


def _tiny_messages(n: int) -> bytes:
    schema = _record(0x03, struct.pack("<H", 1) + _string("palpate.JointState") + _string("jsonschema")
                     + struct.pack("<I", 2) + b"{}")
    channel = _record(0x04, struct.pack("<HH", 1, 1) + _string("/other") + _string("json") + _map({}))
    msg = _record(0x05, struct.pack("<HIQQ", 1, 0, 0, 0) + b"{}")
    return schema + channel + msg * n


def test_message_count_limit_and_raising_it(tmp_path, monkeypatch):
    path = tmp_path / "many.mcap"
    records = _tiny_messages(5000)
    _mcap(path, records, declared=len(records), compression="", crc=zlib.crc32(records))
    monkeypatch.setenv("PALPATE_LIMITS", "mcap_messages=1000")
    with pytest.raises(RecordingError, match=r"many.mcap: the number of messages \(by the chunk at byte \d+\) is 1001 "
                                             r"messages, over the limit mcap_messages = 1000 messages"):
        read_recording(path)
    monkeypatch.setenv("PALPATE_LIMITS", "mcap_messages=5000")
    rec = read_recording(path)  # the other tool's topic is skipped, the file is otherwise fine
    assert rec.frames == [] and rec.metadata == {}


def test_record_size_limit_and_raising_it(tmp_path, monkeypatch):
    path = tmp_path / "big.mcap"
    with RecordingWriter(path, {"note": "x" * 3_000_000}) as w:
        w.write_taxel(TaxelFrame(0.0, np.ones((4, 4), np.uint8), 1e-5))
    monkeypatch.setenv("PALPATE_LIMITS", "mcap_mb=1")
    with pytest.raises(RecordingError, match=r"big.mcap: the record at byte \d+ is 3.0\d* MB, over the limit "
                                             r"mcap_mb = 1 MB \(raise it with palpate --limit mcap_mb=N"):
        read_recording(path)
    monkeypatch.setenv("PALPATE_LIMITS", "mcap_mb=8")
    assert len(read_recording(path).frames) == 1
    monkeypatch.setenv("PALPATE_LIMITS", "mcap_mb=lots")
    with pytest.raises(ValidationError, match="PALPATE_LIMITS: limit mcap_mb needs a number"):
        read_recording(path)


def test_limits_default_and_raised_on_the_command_line(tmp_path, monkeypatch, capsys):
    monkeypatch.delenv("PALPATE_LIMITS", raising=False)
    assert ReadLimits.in_force() == ReadLimits() == ReadLimits(64_000_000, 4_000_000)
    monkeypatch.setenv("PALPATE_LIMITS", "mcap_messages=12")
    assert ReadLimits.in_force().max_messages == 12
    monkeypatch.delenv("PALPATE_LIMITS")
    path = tmp_path / "bomb.mcap"
    _mcap(path, _zstd_rle(70_000_000, 0xFF), declared=70_000_000)
    memory = Path(__file__).parent / "data" / "recording_v1" / "memory.json"
    args = ["replay", str(path), "--memory", str(memory), "--out", str(tmp_path / "o")]
    from palpate.core.cli import main

    assert main(args) == 2
    assert "over the limit mcap_mb = 64 MB" in capsys.readouterr().err
    # raised for one command, the 70 MB chunk is inflated and read (its bytes are no MCAP records)
    assert main(["--limit", "mcap_mb=100", *args]) == 2
    err = capsys.readouterr().err
    assert "mcap_mb" not in err and "bomb.mcap: recording is corrupt at byte" in err, err


@pytest.mark.skipif(not os.path.exists("/dev/zero"), reason="needs /dev/zero")
def test_a_device_is_not_read_as_a_recording(tmp_path):
    link = tmp_path / "zero.mcap"
    link.symlink_to("/dev/zero")
    with pytest.raises(RecordingError, match="zero.mcap: not a regular file"):
        read_recording(link)


def test_a_chunk_of_another_compression_is_a_clear_error(tmp_path):
    path = tmp_path / "odd.mcap"
    _mcap(path, b"abc", declared=3, compression="brotli")
    with pytest.raises(RecordingError, match="unsupported chunk compression 'brotli'"):
        read_recording(path)
