"""The tactile array's wire format: a binary frame, or a CSV line (see ``docs/tactile_array.md``).

Binary frame, little-endian::

    offset  size      field
    0       2         sync 0xA5 0x5A
    2       1         rows R (1..64)
    3       1         cols C (1..64)
    4       2         frame counter, uint16, +1 per frame (wraps at 65536)
    6       R*C       counts, uint8, row-major
    6+R*C   2         CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF) of bytes 2 .. 5+R*C

CSV line (ASCII)::

    T,<counter>,<R>,<C>,<c_00>,<c_01>,...,<c_(R-1)(C-1)>*<XX>\\r\\n

where ``XX`` is the XOR of every byte between ``T`` and ``*`` (``T`` included), in two hex digits, as NMEA
sentences do. A frame whose size does not match the configured pad, or whose checksum fails, is corrupt: it is
counted and dropped, and the parser looks for the next sync (or line).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from palpate.core.errors import ValidationError

SYNC = b"\xa5\x5a"
HEADER = 6
MAX_SIDE = 64
COUNTER_MOD = 1 << 16
FORMATS = ("binary", "csv")


def _crc_table() -> tuple[int, ...]:
    table = []
    for i in range(256):
        crc = i << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) if crc & 0x8000 else (crc << 1)
        table.append(crc & 0xFFFF)
    return tuple(table)


_CRC_TABLE = _crc_table()


def crc16(data: bytes, crc: int = 0xFFFF) -> int:
    """CRC-16/CCITT-FALSE of ``data`` (the binary frame's checksum)."""
    table = _CRC_TABLE
    for byte in data:
        crc = ((crc << 8) ^ table[((crc >> 8) ^ byte) & 0xFF]) & 0xFFFF
    return crc


def check_shape(rows: int, cols: int) -> tuple[int, int]:
    """(rows, cols) if a pad of that size fits the format; ValidationError otherwise."""
    if not (isinstance(rows, int | np.integer) and isinstance(cols, int | np.integer)
            and 1 <= rows <= MAX_SIDE and 1 <= cols <= MAX_SIDE):
        raise ValidationError(f"a tactile array frame holds 1..{MAX_SIDE} rows and columns, got {rows} x {cols}")
    return int(rows), int(cols)


def encode_binary(counter: int, counts: np.ndarray) -> bytes:
    """One binary frame."""
    counts = np.asarray(counts, dtype=np.uint8)
    rows, cols = check_shape(*counts.shape)
    body = bytes([rows, cols]) + int(counter % COUNTER_MOD).to_bytes(2, "little") + counts.tobytes()
    return SYNC + body + crc16(body).to_bytes(2, "little")


def encode_csv(counter: int, counts: np.ndarray) -> bytes:
    """One CSV line."""
    counts = np.asarray(counts, dtype=np.uint8)
    rows, cols = check_shape(*counts.shape)
    text = f"T,{counter % COUNTER_MOD},{rows},{cols}," + ",".join(map(str, counts.reshape(-1).tolist()))
    check = 0
    for b in text.encode("ascii"):
        check ^= b
    return f"{text}*{check:02X}\r\n".encode("ascii")


@dataclass(frozen=True)
class Frame:
    """A frame as received: its counter (mod 2^16) and counts (rows, cols) uint8."""

    counter: int
    counts: np.ndarray


class FrameParser:
    """Frames from bytes in any chunking; counts what it drops.

    Args:
        rows, cols: the pad's size (a frame of another size is corrupt).
        fmt: "binary" or "csv".

    ``corrupt`` counts frames dropped for a bad checksum or size; ``garbage`` bytes skipped between frames.
    """

    def __init__(self, rows: int, cols: int, fmt: str = "binary"):
        self.rows, self.cols = check_shape(rows, cols)
        if fmt not in FORMATS:
            raise ValidationError(f"tactile array format must be one of {FORMATS}, got {fmt!r}")
        self.fmt = fmt
        self.size = HEADER + self.rows * self.cols + 2
        self._buf = b""
        self.corrupt = 0
        self.garbage = 0
        # a CSV line is at most this long; longer runs without a line end are garbage
        self._max_line = 32 + 4 * self.rows * self.cols

    def feed(self, data: bytes) -> list[Frame]:
        """Parse more bytes; the frames completed by them, in order."""
        self._buf += bytes(data)
        return self._binary() if self.fmt == "binary" else self._csv()

    def _binary(self) -> list[Frame]:
        out = []
        buf = self._buf
        pos = 0
        while True:
            k = buf.find(SYNC, pos)
            if k < 0:
                keep = 1 if buf.endswith(SYNC[:1]) else 0
                self.garbage += len(buf) - pos - keep
                pos = len(buf) - keep
                break
            self.garbage += k - pos
            if len(buf) - k < HEADER:
                pos = k
                break
            if buf[k + 2] != self.rows or buf[k + 3] != self.cols:
                self.corrupt += 1
                pos = k + 1
                continue
            if len(buf) - k < self.size:
                pos = k
                break
            frame = buf[k:k + self.size]
            if crc16(frame[2:-2]) != int.from_bytes(frame[-2:], "little"):
                self.corrupt += 1
                pos = k + 1
                continue
            counts = np.frombuffer(frame[HEADER:-2], dtype=np.uint8).reshape(self.rows, self.cols).copy()
            out.append(Frame(int.from_bytes(frame[4:6], "little"), counts))
            pos = k + self.size
        self._buf = buf[pos:]
        return out

    def _csv(self) -> list[Frame]:
        *lines, rest = self._buf.split(b"\n")
        if len(rest) > self._max_line:
            self.garbage += len(rest)
            rest = b""
        self._buf = rest
        out = []
        for raw in lines:
            frame = self._csv_line(raw.strip())
            if frame is not None:
                out.append(frame)
        return out

    def _csv_line(self, line: bytes) -> Frame | None:
        start = line.find(b"T,")
        if start < 0:
            self.garbage += len(line)
            return None
        self.garbage += start
        line = line[start:]
        star = line.rfind(b"*")
        try:
            body, check = line[:star], int(line[star + 1:], 16) if star > 0 else -1
            xor = 0
            for b in body:
                xor ^= b
            fields = body.decode("ascii").split(",")
            counter, rows, cols = int(fields[1]), int(fields[2]), int(fields[3])
            values = [int(v) for v in fields[4:]]
        except (ValueError, IndexError, UnicodeDecodeError):
            self.corrupt += 1
            return None
        if (check != xor or (rows, cols) != (self.rows, self.cols) or len(values) != rows * cols
                or not all(0 <= v <= 255 for v in values) or not 0 <= counter < COUNTER_MOD):
            self.corrupt += 1
            return None
        return Frame(counter, np.array(values, dtype=np.uint8).reshape(rows, cols))
