"""A bounded, streaming reader of MCAP records: every size a file declares is checked before anything is allocated.

Only what a recording reader needs is parsed (header, schemas, channels, messages, chunks, metadata, data end,
footer). Chunks are decompressed (zstd, lz4 or none)
into at most their declared size, their CRC is checked, and the records inside are parsed from one buffer with
``struct.unpack_from`` (a few times faster than the mcap package's record objects).

Limits (:class:`ReadLimits`: the named limits ``mcap_mb`` and ``mcap_messages`` of :mod:`palpate.core.limits`,
raised with ``palpate --limit NAME=N`` or ``PALPATE_LIMITS``, see ``docs/limits.md``):

- ``mcap_mb`` (default 64 MB): the largest record read into memory and the largest decompressed chunk;
- ``mcap_messages`` (default 4,000,000): messages in one file.

A file that breaks a limit fails at once with a :class:`~palpate.core.errors.RecordingError` naming the file, the
byte offset, the size and how to raise the limit. Unused records (message indexes, statistics) are read only if
small; attachments are skipped unread.
"""

from __future__ import annotations

import struct
import zlib
from collections.abc import Iterator
from dataclasses import dataclass

from palpate.core.errors import RecordingError
from palpate.core.limits import ENV as LIMITS_ENV
from palpate.core.limits import LIMITS, limit

MAGIC = b"\x89MCAP0\r\n"
MB = 1_000_000  # the limits' MB
OP_HEADER, OP_FOOTER, OP_SCHEMA, OP_CHANNEL, OP_MESSAGE, OP_CHUNK = 0x01, 0x02, 0x03, 0x04, 0x05, 0x06
OP_METADATA, OP_DATA_END = 0x0C, 0x0F
_READ = {OP_HEADER, OP_FOOTER, OP_SCHEMA, OP_CHANNEL, OP_MESSAGE, OP_CHUNK, OP_METADATA, OP_DATA_END}
_U16, _U32, _U64 = struct.Struct("<H"), struct.Struct("<I"), struct.Struct("<Q")
_RECORD_HEAD = struct.Struct("<BQ")
_SMALL = 1 << 16  # records we do not use are read (for the CRC) only up to this size
_MESSAGE_HEAD = struct.Struct("<HIQQ")  # channel id, sequence, log time, publish time
_CHUNK_HEAD = struct.Struct("<QQQI")  # start time, end time, uncompressed size, uncompressed crc


@dataclass(frozen=True)
class ReadLimits:
    """What one MCAP file may make the reader allocate.

    Attributes:
        max_bytes: largest record read into memory and largest decompressed chunk, bytes.
        max_messages: most messages in one file.
    """

    max_bytes: int = int(LIMITS["mcap_mb"].default * MB)
    max_messages: int = int(LIMITS["mcap_messages"].default)

    @classmethod
    def in_force(cls) -> ReadLimits:
        """The limits ``mcap_mb`` and ``mcap_messages`` as set now (``--limit``, ``PALPATE_LIMITS``, defaults)."""
        return cls(max_bytes=int(limit("mcap_mb") * MB), max_messages=int(limit("mcap_messages")))


def _over(path, what: str, value: float, name: str) -> RecordingError:
    lim = LIMITS[name]
    scale = MB if lim.unit == "MB" else 1
    return RecordingError(f"{path}: {what} is {value / scale:.6g} {lim.unit}, over the limit {name} = "
                          f"{limit(name):g} {lim.unit} (raise it with palpate --limit {name}=N or "
                          f"{LIMITS_ENV}={name}=N; see docs/limits.md)")


@dataclass(frozen=True)
class Schema:
    id: int
    name: str
    encoding: str
    data: bytes


@dataclass(frozen=True)
class Channel:
    id: int
    schema_id: int
    topic: str
    message_encoding: str


@dataclass(frozen=True)
class Metadata:
    name: str
    entries: dict[str, str]


@dataclass(frozen=True)
class Message:
    channel_id: int
    log_time: int
    data: bytes


class Damaged(Exception):
    """The file ends early or holds bytes that are not MCAP; ``truncated`` tells which, ``offset`` where."""

    def __init__(self, what: str, offset: int, truncated: bool):
        super().__init__(what)
        self.offset = offset
        self.truncated = truncated


def _string(buf, pos: int, end: int) -> tuple[str, int]:
    if pos + 4 > end:
        raise ValueError("string length runs past the record")
    n = _U32.unpack_from(buf, pos)[0]
    pos += 4
    if pos + n > end:
        raise ValueError(f"string of {n} bytes runs past the record")
    return bytes(buf[pos:pos + n]).decode("utf-8"), pos + n


def _string_map(buf, pos: int, end: int) -> tuple[dict[str, str], int]:
    if pos + 4 > end:
        raise ValueError("map length runs past the record")
    n = _U32.unpack_from(buf, pos)[0]
    pos += 4
    stop = pos + n
    if stop > end:
        raise ValueError(f"map of {n} bytes runs past the record")
    out = {}
    while pos < stop:
        key, pos = _string(buf, pos, stop)
        out[key], pos = _string(buf, pos, stop)
    return out, pos


def _parse(op: int, buf, pos: int, end: int):
    """One record's content buf[pos:end] -> Schema | Channel | Message | Metadata | ('chunk', ...) | None."""
    if op == OP_MESSAGE:
        cid, _, log_time, _ = _MESSAGE_HEAD.unpack_from(buf, pos)
        return Message(cid, log_time, bytes(buf[pos + 22:end]))
    if op == OP_SCHEMA:
        sid = _U16.unpack_from(buf, pos)[0]
        name, p = _string(buf, pos + 2, end)
        encoding, p = _string(buf, p, end)
        n = _U32.unpack_from(buf, p)[0]
        if p + 4 + n > end:
            raise ValueError("schema data runs past the record")
        return Schema(sid, name, encoding, bytes(buf[p + 4:p + 4 + n]))
    if op == OP_CHANNEL:
        cid, sid = struct.unpack_from("<HH", buf, pos)
        topic, p = _string(buf, pos + 4, end)
        encoding, p = _string(buf, p, end)
        _string_map(buf, p, end)
        return Channel(cid, sid, topic, encoding)
    if op == OP_METADATA:
        name, p = _string(buf, pos, end)
        return Metadata(name, _string_map(buf, p, end)[0])
    return None


def _inflate(compression: str, data: bytes, size: int) -> bytes:
    """A chunk's records, decompressed into at most ``size`` bytes; ValueError if they inflate to more, or if the
    compressed bytes are damaged (whatever the decompressor raises)."""
    try:
        return _inflate_checked(compression, data, size)
    except ValueError:
        raise
    except Exception as exc:  # noqa: BLE001 - zstandard.ZstdError, lz4's RuntimeError: damaged compressed bytes
        raise ValueError(f"its {compression} data do not decompress ({type(exc).__name__}: {exc})") from None


def _inflate_checked(compression: str, data: bytes, size: int) -> bytes:
    if compression == "":
        out = data
    elif compression == "zstd":
        import zstandard

        declared = zstandard.frame_content_size(data)
        if declared >= 0 and declared != size:
            raise ValueError(f"its zstd frame declares {declared} bytes, the chunk {size}")
        reader = zstandard.ZstdDecompressor().stream_reader(data, read_across_frames=True)
        parts, got = [], 0
        while got <= size:
            part = reader.read(size + 1 - got)
            if not part:
                break
            parts.append(part)
            got += len(part)
        out = b"".join(parts)
    elif compression == "lz4":
        import lz4.frame

        out = lz4.frame.LZ4FrameDecompressor().decompress(data, max_length=size + 1)
    else:
        raise ValueError(f"unsupported chunk compression {compression!r}")
    if len(out) != size:
        raise ValueError(f"it inflates to {'more than' if len(out) > size else 'only'} "
                         f"{min(len(out), size)} bytes, not its declared {size}")
    return out


def read_records(f, path, size: int, limits: ReadLimits) -> Iterator:
    """Yield Schema, Channel, Message and Metadata records of an open MCAP file in file order, chunks unpacked.

    Raises:
        Damaged: the file is truncated or corrupt (records before the damage have been yielded).
        RecordingError: a declared or decompressed size, or the message count, exceeds ``limits``.
    """
    head = f.read(8)
    if head != MAGIC:
        if len(head) < 8 and MAGIC.startswith(head):
            raise Damaged(f"truncated at byte {size} (shorter than the 8-byte MCAP magic)", 0, True)
        raise Damaged("not an MCAP file (its first bytes are not the MCAP magic)", 0, False)
    offset, crc, messages = 8, zlib.crc32(head), 0
    record_head = _RECORD_HEAD
    while True:
        raw = f.read(9)
        if len(raw) < 9:
            raise Damaged(f"truncated at byte {size} (last complete record ends at byte {offset})", offset, True)
        op, length = record_head.unpack(raw)
        if offset + 9 + length > size:
            raise Damaged(f"truncated at byte {size} (last complete record ends at byte {offset})", offset, True)
        if op not in _READ:
            if length > _SMALL:  # an attachment: skipped unread (and the data section's CRC with it)
                f.seek(length, 1)
                crc = None
            elif crc is not None:  # message indexes after each chunk: read only for the data section's CRC
                crc = zlib.crc32(f.read(length), zlib.crc32(raw, crc))
            else:
                f.seek(length, 1)
            offset += 9 + length
            continue
        if length > limits.max_bytes:
            raise _over(path, f"the record at byte {offset}", length, "mcap_mb")
        body = f.read(length)
        if op == OP_DATA_END and crc is not None:
            expected = _U32.unpack_from(body, 0)[0] if length >= 4 else 0
            if expected and expected != crc:
                raise Damaged(f"corrupt at byte {offset} of {size} (data section CRC {crc:#010x}, the file says "
                              f"{expected:#010x})", offset, False)
        if crc is not None:
            crc = zlib.crc32(body, zlib.crc32(raw, crc))
        try:
            if op == OP_CHUNK:
                records = _chunk_records(body, path, offset, limits, limits.max_messages - messages)
            elif op == OP_FOOTER:
                if f.read(8) != MAGIC:
                    raise Damaged(f"truncated at byte {size} (no closing MCAP magic after the footer)", offset, True)
                return
            else:
                records = [_parse(op, body, 0, length)]
        except (ValueError, struct.error, UnicodeDecodeError) as exc:
            raise Damaged(f"corrupt at byte {offset} of {size} ({exc})", offset, False) from None
        for r in records:
            if type(r) is Message:
                messages += 1
                if messages > limits.max_messages:
                    raise _over(path, "the number of messages", messages, "mcap_messages")
            if r is not None:
                yield r
        offset += 9 + length


def _chunk_records(body: bytes, path, offset: int, limits: ReadLimits, budget: int) -> list:
    """Every record of one chunk, parsed before any is yielded (a damaged chunk gives nothing); at most
    ``budget`` messages."""
    _, _, size, crc = _CHUNK_HEAD.unpack_from(body, 0)
    compression, p = _string(body, 28, len(body))
    n = _U64.unpack_from(body, p)[0]
    p += 8
    if p + n > len(body):
        raise ValueError("chunk records run past the chunk")
    if size > limits.max_bytes:
        raise _over(path, f"the chunk at byte {offset}, decompressed,", size, "mcap_mb")
    data = _inflate(compression, bytes(body[p:p + n]), size)
    if crc and zlib.crc32(data) != crc:
        raise ValueError("chunk CRC mismatch")
    out, pos, end = [], 0, len(data)
    unpack_head, parse, message = _RECORD_HEAD.unpack_from, _parse, OP_MESSAGE
    while pos < end:
        if pos + 9 > end:
            raise ValueError("a record header runs past the chunk")
        op, length = unpack_head(data, pos)
        start, stop = pos + 9, pos + 9 + length
        if stop > end:
            raise ValueError("a record runs past the chunk")
        if op == message:
            cid, _, log_time, _ = _MESSAGE_HEAD.unpack_from(data, start)
            out.append(Message(cid, log_time, data[start + 22:stop]))
            budget -= 1
            if budget < 0:
                raise _over(path, f"the number of messages (by the chunk at byte {offset})",
                            limits.max_messages + 1, "mcap_messages")
        elif op in (OP_SCHEMA, OP_CHANNEL):
            out.append(parse(op, data, start, stop))
        pos = stop
    return out
