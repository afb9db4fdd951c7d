"""Protocol 2.0 codec: CRC and packets against the e-Manual examples and the SDK, stuffing, a parser fed garbage."""

from __future__ import annotations

import numpy as np

from palpate.hardware.dynamixel.protocol import (
    INST_PING,
    INST_STATUS,
    INST_WRITE,
    Packet,
    PacketParser,
    crc16,
    encode,
    status_packet,
    stuff,
    unstuff,
)

# From the ROBOTIS Protocol 2.0 e-Manual: ping to id 1, and the status of an XM430-W210 (model 1030, fw 38).
PING_ID1 = bytes.fromhex("FF FF FD 00 01 03 00 01 19 4E")


def test_crc_and_encoding_match_the_manual_examples():
    assert encode(Packet(1, INST_PING)) == PING_ID1
    assert crc16(PING_ID1[:-2]) == 0x4E19
    # status of a ping: error 0, model 1030 (0x0406), firmware 0x26
    ping_status = encode(status_packet(1, 0, bytes([0x06, 0x04, 0x26])))
    assert ping_status[:-2] == bytes.fromhex("FF FF FD 00 01 07 00 55 00 06 04 26")
    assert ping_status[-2:] == bytes.fromhex("655D")


def test_crc_table_is_the_sdk_table():
    from dynamixel_sdk import PacketHandler

    ph = PacketHandler(2.0)
    data = list(np.random.default_rng(3).integers(0, 256, 300))
    assert crc16(bytes(data)) == ph.updateCRC(0, data, len(data))


def test_encode_matches_what_the_sdk_sends():
    from dynamixel_sdk import PacketHandler

    class Capture:
        is_using = False

        def clearPort(self):
            pass

        def writePort(self, packet):
            self.sent = bytes(packet)
            return len(packet)

    port = Capture()
    PacketHandler(2.0).write4ByteTxOnly(port, 3, 116, 2500)
    assert encode(Packet(3, INST_WRITE, bytes([116, 0]) + (2500).to_bytes(4, "little"))) == port.sent


def test_stuffing_round_trip_and_wire_form():
    body = bytes([INST_STATUS, 0, 0xFF, 0xFF, 0xFD, 0x10, 0xFF, 0xFF, 0xFD])
    stuffed = stuff(body)
    assert stuffed == bytes([INST_STATUS, 0, 0xFF, 0xFF, 0xFD, 0xFD, 0x10, 0xFF, 0xFF, 0xFD, 0xFD])
    assert unstuff(stuffed) == body
    wire = encode(Packet(5, INST_STATUS, body[1:]))
    assert wire[5] | wire[6] << 8 == len(stuffed) + 2  # the length counts the stuffed body
    assert PacketParser().feed(wire) == [Packet(5, INST_STATUS, body[1:])]


def test_parser_finds_packets_in_garbage_split_anywhere(rng):
    packets = [Packet(int(rng.integers(0, 253)), int(rng.choice([1, 2, 3, 0x55, 0x82, 0x83])),
                      bytes(rng.integers(0, 256, int(rng.integers(0, 40))).astype(np.uint8)))
               for _ in range(50)]
    stream = bytearray()
    for p in packets:
        stream += bytes(rng.integers(0, 256, int(rng.integers(0, 12))).astype(np.uint8)).replace(b"\xff", b"\x00")
        stream += encode(p)
    parser = PacketParser()
    out = []
    cuts = np.sort(rng.integers(0, len(stream), 30))
    for a, b in zip(np.r_[0, cuts], np.r_[cuts, len(stream)], strict=True):
        out += parser.feed(bytes(stream[a:b]))
    assert out == packets
    assert parser.crc_errors == 0


def test_parser_drops_a_corrupt_packet_and_keeps_the_next():
    good = encode(Packet(1, INST_PING))
    bad = bytearray(encode(Packet(2, INST_WRITE, bytes([64, 0, 1]))))
    bad[-1] ^= 0xFF
    parser = PacketParser()
    assert parser.feed(bytes(bad) + good) == [Packet(1, INST_PING)]
    assert parser.crc_errors == 1
    # an absurd length field is not waited for forever
    assert parser.feed(b"\xff\xff\xfd\x00\x01\xff\x7f" + good) == [Packet(1, INST_PING)]
