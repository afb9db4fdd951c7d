"""DYNAMIXEL Protocol 2.0 packet codec for the emulator side of the wire.

The driver talks through the official ``dynamixel-sdk``; this codec exists so that the servo emulator can
understand what that library sends and answer in kind. A packet on the wire is::

    FF FF FD 00 | ID | LEN_L LEN_H | INST | PARAMS... | CRC_L CRC_H

LEN counts INST + PARAMS + CRC after byte stuffing; the CRC-16 (polynomial 0x8005, no reflection, initial 0)
covers everything from the first header byte to the last parameter, stuffed. Byte stuffing inserts an extra
0xFD after any FF FF FD inside INST + PARAMS so that the header never appears in a packet body.
A status packet has INST = 0x55 and an error byte as its first parameter.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

HEADER = b"\xff\xff\xfd\x00"
BROADCAST_ID = 0xFE
MAX_ID = 0xFC

INST_PING = 0x01
INST_READ = 0x02
INST_WRITE = 0x03
INST_REBOOT = 0x08
INST_STATUS = 0x55
INST_SYNC_READ = 0x82
INST_SYNC_WRITE = 0x83

# Error byte of a status packet: low 7 bits are an error number, bit 7 is the hardware alert.
ERR_RESULT_FAIL = 1
ERR_INSTRUCTION = 2
ERR_CRC = 3
ERR_DATA_RANGE = 4
ERR_DATA_LENGTH = 5
ERR_DATA_LIMIT = 6
ERR_ACCESS = 7
ERRBIT_ALERT = 0x80

# Longest body the emulator accepts; the SDK's own buffers are 1 KiB, so anything longer is garbage.
MAX_LENGTH = 1024


def _crc_table() -> np.ndarray:
    # Table of the MSB-first CRC-16 with polynomial 0x8005 (the "DYNAMIXEL CRC table" of the Protocol 2.0 spec).
    table = np.zeros(256, dtype=np.uint16)
    for i in range(256):
        crc = i << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x8005) if crc & 0x8000 else (crc << 1)
        table[i] = crc & 0xFFFF
    return table


CRC_TABLE: tuple[int, ...] = tuple(int(v) for v in _crc_table())


def crc16(data: bytes | bytearray, crc: int = 0) -> int:
    """CRC-16 of ``data`` as Protocol 2.0 computes it (poly 0x8005, init 0, MSB first)."""
    table = CRC_TABLE
    for byte in data:
        crc = ((crc << 8) ^ table[((crc >> 8) ^ byte) & 0xFF]) & 0xFFFF
    return crc


def stuff(body: bytes, prefix: bytes = b"") -> bytes:
    """Byte-stuff a packet body (instruction + parameters).

    ``prefix`` is what precedes the body on the wire (id and length bytes): a header-like run that starts
    there and ends inside the body is stuffed too, as the reference implementation does.
    """
    out = bytearray()
    window = bytes(prefix[-2:]).rjust(2, b"\x00")
    p2, p1 = window[0], window[1]
    for b in body:
        out.append(b)
        if b == 0xFD and p1 == 0xFF and p2 == 0xFF:
            out.append(0xFD)
        p2, p1 = p1, b
    return bytes(out)


def unstuff(body: bytes) -> bytes:
    """Undo :func:`stuff`: drop the extra 0xFD after each FF FF FD in a received body."""
    out = bytearray()
    i = 0
    n = len(body)
    while i < n:
        b = body[i]
        out.append(b)
        if b == 0xFD and i + 1 < n and body[i + 1] == 0xFD and len(out) >= 3 and out[-2] == 0xFF and out[-3] == 0xFF:
            i += 1  # skip the stuffed copy
        i += 1
    return bytes(out)


@dataclass(frozen=True)
class Packet:
    """One decoded Protocol 2.0 packet (unstuffed).

    Attributes:
        id: servo id (0..252) or 254 for broadcast.
        instruction: instruction byte (0x55 for status packets).
        params: parameter bytes; for a status packet the first byte is the error byte.
    """

    id: int
    instruction: int
    params: bytes = b""

    @property
    def error(self) -> int:
        """Error byte of a status packet (0 when this is not a status packet or it has no parameters)."""
        return self.params[0] if self.instruction == INST_STATUS and self.params else 0

    @property
    def data(self) -> bytes:
        """Data bytes of a status packet (after the error byte)."""
        return self.params[1:] if self.instruction == INST_STATUS else self.params


def encode(packet: Packet) -> bytes:
    """Encode a packet for the wire: header, id, stuffed length, stuffed body, CRC."""
    if not 0 <= packet.id <= 0xFE:
        raise ValueError(f"packet id must be 0..254, got {packet.id}")
    body = bytes([packet.instruction]) + bytes(packet.params)
    length_guess = len(body) + 2
    prefix = bytes([packet.id, length_guess & 0xFF, length_guess >> 8])
    stuffed = stuff(body, prefix)
    length = len(stuffed) + 2
    if length > 0xFFFF:
        raise ValueError(f"packet too long: {length} bytes")
    head = HEADER + bytes([packet.id, length & 0xFF, length >> 8])
    frame = head + stuffed
    crc = crc16(frame)
    return frame + bytes([crc & 0xFF, crc >> 8])


def status_packet(servo_id: int, error: int = 0, data: bytes = b"") -> Packet:
    """A status packet from ``servo_id`` carrying ``error`` and ``data``."""
    return Packet(servo_id, INST_STATUS, bytes([error & 0xFF]) + bytes(data))


class PacketParser:
    """Streaming decoder: feed it bytes as they arrive, get whole packets back.

    Garbage between packets is skipped; a packet whose CRC does not match is dropped (counted in
    ``crc_errors``) and the search for the next header resumes one byte after the bad header, so that a
    good packet hidden inside a corrupt one is still found.
    """

    def __init__(self, max_length: int = MAX_LENGTH):
        self._buf = bytearray()
        self.max_length = max_length
        self.crc_errors = 0
        self.skipped_bytes = 0

    def feed(self, data: bytes) -> list[Packet]:
        """Append received bytes and return every complete, valid packet now available, in order."""
        self._buf += data
        out: list[Packet] = []
        buf = self._buf
        while True:
            start = buf.find(HEADER)
            if start < 0:
                # keep a possible partial header at the end
                keep = 0
                for k in (3, 2, 1):
                    if buf.endswith(HEADER[:k]):
                        keep = k
                        break
                self.skipped_bytes += len(buf) - keep
                del buf[: len(buf) - keep]
                break
            if start:
                self.skipped_bytes += start
                del buf[:start]
            if len(buf) < 7:
                break
            length = buf[5] | (buf[6] << 8)
            if length < 3 or length > self.max_length:
                self.skipped_bytes += 1
                del buf[:1]
                continue
            total = 7 + length
            if len(buf) < total:
                break
            frame = bytes(buf[:total])
            crc = frame[-2] | (frame[-1] << 8)
            if crc16(frame[:-2]) != crc:
                self.crc_errors += 1
                del buf[:1]
                continue
            del buf[:total]
            body = unstuff(frame[7:-2])
            out.append(Packet(frame[4], body[0], body[1:]))
        return out

    def pending(self) -> int:
        """Bytes held while waiting for the rest of a packet."""
        return len(self._buf)
