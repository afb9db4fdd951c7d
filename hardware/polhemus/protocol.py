"""Polhemus Liberty wire protocol: command strings, record encoding and a resynchronising stream parser.

Pure functions and plain data, no I/O, so the driver and the emulator share one definition of the bytes.

Binary record (``F1``), Liberty manual Table 2-2: an 8-byte header

    'L' 'Y' | station (uint8, 1-based) | initiating command (ASCII, 'P' or 'C') | error (uint8) | reserved
    | payload size (int16 little-endian, bytes after the header)

then the output-list items in order, little-endian: position x,y,z (item 2, 3 x float32, in the current
units), quaternion w,x,y,z (item 7, 4 x float32), timestamp (item 8, uint32, ms), frame count (item 9, uint32),
space (item 0, one byte) and CR LF (item 1, two bytes).

ASCII record (``F0``): a header of the station as two digits, the initiating command and the error indicator
(a space when there is no error), then the items as space-separated decimal fields, then CR LF.

An error byte of 0 or an ASCII space both mean "no error": the manual uses a space in ASCII output and real
units have been seen to send either in binary, so both are accepted.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

from palpate.core.errors import ValidationError

MAGIC = b"LY"
HEADER_SIZE = 8
MAX_STATIONS = 16
RECORD_COMMANDS = (ord("P"), ord("C"))
NO_ERROR = (0, 0x20)
CM_PER_INCH = 2.54

# Output-list item numbers of the Liberty (the 'O' command) that palpate understands, with their binary layout.
ITEM_SPACE = 0
ITEM_CRLF = 1
ITEM_POSITION = 2
ITEM_QUATERNION = 7
ITEM_TIMESTAMP = 8
ITEM_FRAMECOUNT = 9
ITEM_LAYOUT: dict[int, tuple[str, str, int]] = {
    # item: (field name, numpy dtype of one value, number of values)
    ITEM_SPACE: ("space", "u1", 1),
    ITEM_CRLF: ("crlf", "u1", 2),
    ITEM_POSITION: ("position", "<f4", 3),
    ITEM_QUATERNION: ("quaternion", "<f4", 4),
    ITEM_TIMESTAMP: ("timestamp", "<u4", 1),
    ITEM_FRAMECOUNT: ("frame", "<u4", 1),
}
DEFAULT_ITEMS = (ITEM_POSITION, ITEM_QUATERNION, ITEM_TIMESTAMP, ITEM_FRAMECOUNT, ITEM_CRLF)
# A quaternion from the device is unit to float32 precision; anything far off means the bytes are not a record.
QUAT_NORM_TOLERANCE = 0.05
# A field as the device writes it in ASCII: digits, at most one point, no exponent.
_FIXED_POINT = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)")
# Positions beyond this (in device units) are outside any Liberty's range: the bytes are not a record.
MAX_ABS_POSITION = 1.0e4


@dataclass(frozen=True)
class Record:
    """One decoded Liberty record, in device units.

    Attributes:
        station: station number, 1-based.
        command: initiating command, 'P' (single) or 'C' (continuous).
        error: device error code (0 when none).
        position: (x, y, z) in the configured units (cm or inch), or None if not in the output list.
        quaternion: (w, x, y, z), or None if not in the output list.
        timestamp_ms: device clock, ms, or None.
        frame: device frame count, or None.
        quaternion_rounding: how far the record's format can have moved the quaternion from the device's value
            (Euclidean, dimensionless): half a float32 unit in the last place per component in binary, half the
            last decimal written per component in ASCII (:func:`quaternion_rounding`); 0 when not known.
    """

    station: int
    command: str
    error: int
    position: np.ndarray | None
    quaternion: np.ndarray | None
    timestamp_ms: int | None
    frame: int | None
    quaternion_rounding: float = 0.0


@dataclass(frozen=True)
class ErrorEvent:
    """Something went wrong in the byte stream; later records are still parsed.

    Attributes:
        kind: 'garbage' (bytes skipped while resynchronising), 'partial' (a record cut short by the next header),
            'implausible' (a well-framed record whose values cannot be a pose), 'device_error' (nonzero error
            byte; the record is attached) or 'bad_line' (an ASCII line that does not parse).
        message: what happened, with byte counts or the offending text.
        nbytes: how many bytes were dropped (0 for device_error).
        record: for 'device_error', the record the device flagged.
    """

    kind: str
    message: str
    nbytes: int = 0
    record: Record | None = None


@dataclass
class RecordBatch:
    """Many records as arrays (the fast path); row i of every array is record i.

    Arrays whose item is not in the output list are None.
    """

    station: np.ndarray
    command: np.ndarray
    error: np.ndarray
    position: np.ndarray | None
    quaternion: np.ndarray | None
    timestamp_ms: np.ndarray | None
    frame: np.ndarray | None
    events: list[ErrorEvent] = field(default_factory=list)

    def __len__(self) -> int:
        return int(self.station.shape[0])

    def records(self) -> list[Record]:
        """The batch as Record objects."""
        n = len(self)
        rounding = np.zeros(n) if self.quaternion is None else quaternion_rounding(self.quaternion)
        out = []
        for i in range(n):
            out.append(
                Record(
                    station=int(self.station[i]),
                    command=chr(int(self.command[i])),
                    error=int(self.error[i]),
                    position=None if self.position is None else self.position[i].astype(float),
                    quaternion=None if self.quaternion is None else self.quaternion[i].astype(float),
                    timestamp_ms=None if self.timestamp_ms is None else int(self.timestamp_ms[i]),
                    frame=None if self.frame is None else int(self.frame[i]),
                    quaternion_rounding=float(rounding[i]),
                )
            )
        return out


# ---------------------------------------------------------------------------------------------- commands


def validate_items(items) -> tuple[int, ...]:
    """Check an output list: known item numbers, no repeats. Returns it as a tuple of ints."""
    items = tuple(int(i) for i in items)
    if not items:
        raise ValidationError("Liberty output list is empty; expected item numbers such as 2,7,8,9,1")
    for i in items:
        if i not in ITEM_LAYOUT:
            known = ", ".join(f"{k} ({v[0]})" for k, v in ITEM_LAYOUT.items())
            raise ValidationError(f"Liberty output list item {i} is not supported; supported items: {known}")
    if len(set(items)) != len(items):
        raise ValidationError(f"Liberty output list {items} repeats an item")
    return items


def validate_station(station: int) -> int:
    """Check a 1-based station number (1..16)."""
    if not isinstance(station, (int, np.integer)) or not 1 <= int(station) <= MAX_STATIONS:
        raise ValidationError(f"Liberty station must be an integer 1..{MAX_STATIONS}, got {station!r}")
    return int(station)


def format_command(letter: str, *args) -> bytes:
    """Format a Liberty command: letter, comma-separated arguments, CR (e.g. ``O*,2,7,8,9,1\\r``).

    ``P`` and ``C`` with no argument are single-byte commands that act at once and are sent without CR.
    """
    if len(letter) != 1 or not letter.isalpha():
        raise ValidationError(f"Liberty command letter must be one letter, got {letter!r}")
    if letter in "PC" and not args:
        return letter.encode("ascii")
    text = letter + ",".join(str(a) for a in args)
    return (text + "\r").encode("ascii")


def output_list_command(items, station: int | str = "*") -> bytes:
    """The ``O`` command setting the output list of one station (or ``*`` for all)."""
    items = validate_items(items)
    if station != "*":
        station = validate_station(station)
    return ("O" + ",".join([str(station), *map(str, items)]) + "\r").encode("ascii")


def parse_command_line(line: bytes) -> tuple[str, list[str]]:
    """Split one command (without its CR) into its letter and its comma-separated arguments.

    ``F1`` -> ('F', ['1']); ``O*,2,7`` -> ('O', ['*', '2', '7']). Raises ValidationError on an empty or
    non-ASCII command.
    """
    try:
        text = line.decode("ascii").strip()
    except UnicodeDecodeError as exc:
        raise ValidationError(f"Liberty command {line!r} is not ASCII") from exc
    if not text or not text[0].isalpha():
        raise ValidationError(f"Liberty command {line!r} does not start with a command letter")
    letter, rest = text[0].upper(), text[1:]
    return letter, ([] if rest == "" else rest.split(","))


# ---------------------------------------------------------------------------------------------- binary


def record_dtype(items) -> np.dtype:
    """Numpy structured dtype of one whole binary record (header + payload) for this output list."""
    items = validate_items(items)
    fields = [
        ("magic", "S2"),
        ("station", "u1"),
        ("command", "u1"),
        ("error", "u1"),
        ("reserved", "u1"),
        ("size", "<i2"),
    ]
    for i in items:
        name, dt, n = ITEM_LAYOUT[i]
        fields.append((name, dt, (n,)) if n > 1 else (name, dt))
    return np.dtype(fields)


def payload_size(items) -> int:
    """Bytes after the header in a binary record with this output list."""
    return record_dtype(items).itemsize - HEADER_SIZE


def encode_binary(
    items,
    station: np.ndarray | int,
    command: str,
    position: np.ndarray | None = None,
    quaternion: np.ndarray | None = None,
    timestamp_ms: np.ndarray | int | None = None,
    frame: np.ndarray | int | None = None,
    error: np.ndarray | int = 0,
) -> bytes:
    """Encode one or many binary records (vectorised: arrays with a leading record axis).

    Position is in device units (cm or inch). Items of the output list that are not given are sent as zeros.
    """
    items = validate_items(items)
    dt = record_dtype(items)
    station = np.atleast_1d(np.asarray(station))
    n = station.shape[0]
    rec = np.zeros(n, dtype=dt)
    rec["magic"] = MAGIC
    rec["station"] = station
    rec["command"] = ord(command)
    rec["error"] = error
    rec["size"] = dt.itemsize - HEADER_SIZE
    values = {"position": position, "quaternion": quaternion, "timestamp": timestamp_ms, "frame": frame}
    for i in items:
        name = ITEM_LAYOUT[i][0]
        if name == "space":
            rec[name] = 0x20
        elif name == "crlf":
            rec[name] = (13, 10)
        elif values.get(name) is not None:
            v = np.asarray(values[name])
            rec[name] = v.reshape(rec[name].shape) if v.size == rec[name].size else v
    return rec.tobytes()


ASCII_HEADER = re.compile(rb"\d\d[PC]")


def interleave_events(batch: RecordBatch) -> list[Record | ErrorEvent]:
    return [*batch.events, *batch.records()]


def encode_ascii(
    items,
    station: int,
    command: str,
    position=None,
    quaternion=None,
    timestamp_ms: int | None = None,
    frame: int | None = None,
    error: int = 0,
    quaternion_decimals: int = 6,
) -> bytes:
    """Encode one ASCII (F0) record: header, space-separated fields in output-list order, CR LF last (positions
    with 4 decimals, quaternion components with ``quaternion_decimals``)."""
    items = validate_items(items)
    err = " " if error in NO_ERROR else chr(error)
    parts: list[str] = []
    for i in items:
        if i == ITEM_POSITION:
            parts.extend(f"{v:.4f}" for v in np.asarray(position if position is not None else np.zeros(3)))
        elif i == ITEM_QUATERNION:
            q = quaternion if quaternion is not None else (1.0, 0.0, 0.0, 0.0)
            parts.extend(f"{v:.{quaternion_decimals}f}" for v in np.asarray(q))
        elif i == ITEM_TIMESTAMP:
            parts.append(str(int(timestamp_ms or 0)))
        elif i == ITEM_FRAMECOUNT:
            parts.append(str(int(frame or 0)))
    text = f"{station:02d}{command}{err} " + " ".join(parts)
    if ITEM_SPACE in items:
        text += " "
    if ITEM_CRLF in items:
        text += "\r\n"
    return text.encode("ascii")


def decode_ascii_line(line: bytes, items, station_ok: np.ndarray | None = None) -> Record | ErrorEvent:
    """Decode one ASCII record (without its CR LF); an ErrorEvent names what is wrong with a bad line."""
    nbytes = len(line) + 2

    def bad(why: str) -> ErrorEvent:
        shown = line[:40]
        return ErrorEvent("bad_line", f"ASCII record {shown!r}: {why}", nbytes)

    if len(line) < 4:
        return bad("shorter than the 4-character header")
    try:
        text = line.decode("ascii")
    except UnicodeDecodeError:
        return bad("contains non-ASCII bytes")
    head, body = text[:4], text[4:]
    if not re.fullmatch(r"[ 0-9][0-9]", head[:2]):
        return bad("does not start with a two-digit station number")
    station = int(head[:2])
    if station_ok is not None and not (0 <= station < len(station_ok) and station_ok[station]):
        return bad(f"station {station} is not one of the configured stations")
    command = head[2]
    if ord(command) not in RECORD_COMMANDS:
        return bad(f"initiating command {command!r} is not P or C")
    error = 0 if head[3] == " " else ord(head[3])
    fields = body.split()
    values: dict[str, object] = {}
    k = 0
    for i in items:
        if i in (ITEM_SPACE, ITEM_CRLF):
            continue
        name, _, n = ITEM_LAYOUT[i]
        chunk = fields[k : k + n]
        k += n
        if len(chunk) != n:
            return bad(f"expected {n} value(s) for item {i} ({name})")
        try:
            if name in ("timestamp", "frame"):
                values[name] = int(chunk[0])
            else:
                values[name] = np.array([float(c) for c in chunk])
            if name == "quaternion":
                values["rounding"] = float(np.sqrt(np.sum(np.square([_half_last_decimal(c) for c in chunk]))))
        except ValueError:
            return bad(f"item {i} ({name}) is not numeric: {' '.join(chunk)!r}")
    if k != len(fields):
        return bad(f"{len(fields)} fields where the output list gives {k}")
    pos, quat = values.get("position"), values.get("quaternion")
    if pos is not None and not (np.all(np.isfinite(pos)) and np.all(np.abs(pos) < MAX_ABS_POSITION)):
        return bad("position is not finite or out of range")
    if quat is not None and not abs(float(np.linalg.norm(quat)) - 1.0) < QUAT_NORM_TOLERANCE:
        return bad("quaternion is not a unit quaternion")
    return Record(station, command, error, pos, quat, values.get("timestamp"), values.get("frame"),
                  float(values.get("rounding", 0.0)))


def quaternion_rounding(quaternions: np.ndarray) -> np.ndarray:
    """How far float32 storage can have moved each quaternion (rows of an (n, 4) float32 array): the Euclidean norm
    of half a unit in the last place of each component (about 6e-8 for a unit quaternion)."""
    q = np.abs(np.asarray(quaternions, dtype=np.float32))
    return np.sqrt(np.sum(np.square(0.5 * np.spacing(q).astype(float)), axis=-1))


def _half_last_decimal(text: str) -> float:
    """Half the unit of the last decimal written in a fixed-point field ('0.0123' -> 5e-5): how far rounding to it
    can have moved the value. ValueError for anything the device does not write (an exponent, inf, nan: a
    damaged byte, whose exponent would otherwise claim a coarse resolution)."""
    if not _FIXED_POINT.fullmatch(text):
        raise ValueError(f"{text!r} is not a fixed-point decimal")
    _, _, decimals = text.partition(".")
    return 0.5 * 10.0 ** -len(decimals)
