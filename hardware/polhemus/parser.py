"""Reading the Liberty's output stream: :class:`RecordParser` turns bytes (binary or ASCII, as they arrive) into
records and error events; see :mod:`palpate.hardware.polhemus.protocol` for the formats."""

from __future__ import annotations

import numpy as np

from palpate.core.errors import ValidationError
from palpate.hardware.polhemus.protocol import (
    ASCII_HEADER,
    DEFAULT_ITEMS,
    HEADER_SIZE,
    ITEM_CRLF,
    ITEM_LAYOUT,
    ITEM_SPACE,
    MAGIC,
    MAX_ABS_POSITION,
    MAX_STATIONS,
    NO_ERROR,
    QUAT_NORM_TOLERANCE,
    RECORD_COMMANDS,
    ErrorEvent,
    Record,
    RecordBatch,
    decode_ascii_line,
    interleave_events,
    record_dtype,
    validate_items,
    validate_station,
)


class RecordParser:
    """Streaming parser of Liberty output that resynchronises after corrupt, missing or extra bytes.

    Feed it whatever the transport delivered, in any chunking; it returns the complete records found and the
    problems met, and keeps an incomplete tail for the next call. A record is accepted when it starts with
    'LY', a plausible station (one of ``stations``), a record command ('P'/'C'), the payload size of the
    configured output list; when no other such header starts inside it (which would mean it was cut short);
    and when its values can be a pose (finite, unit quaternion, position in range).

    Args:
        items: the output list the device was configured with.
        stations: station numbers that may appear (default: any of 1..16).
        binary: True for F1 output, False for F0 (ASCII lines).
    """

    def __init__(self, items=DEFAULT_ITEMS, stations=None, binary: bool = True):
        self.items = validate_items(items)
        self.binary = bool(binary)
        stations = range(1, MAX_STATIONS + 1) if stations is None else [validate_station(s) for s in stations]
        self._station_ok = np.zeros(256, dtype=bool)
        self._station_ok[list(stations)] = True
        self._command_ok = np.zeros(256, dtype=bool)
        self._command_ok[list(RECORD_COMMANDS)] = True
        self._dtype = record_dtype(self.items)
        self._size = self._dtype.itemsize
        if not self.binary and self.items[-1] != ITEM_CRLF:
            raise ValidationError(
                f"ASCII output list {self.items} must end with item {ITEM_CRLF} (CR/LF), which ends each record"
            )
        self._ascii_counts = [ITEM_LAYOUT[i][2] for i in self.items if i not in (ITEM_SPACE, ITEM_CRLF)]
        self._pending = b""
        self.bytes_dropped = 0

    @property
    def record_size(self) -> int:
        """Bytes of one whole binary record (header + payload)."""
        return self._size

    def feed(self, data: bytes) -> list[Record | ErrorEvent]:
        """Parse more bytes; return the error events met, then the records found (each group in stream order).

        Binary output goes through :meth:`feed_arrays`; use that directly for speed.
        """
        if not self.binary:
            return self._feed_ascii(data)
        batch = self.feed_arrays(data)
        return interleave_events(batch)

    def flush(self) -> list[ErrorEvent]:
        """End of stream: report the incomplete tail, if any, and forget it."""
        n = len(self._pending)
        self._pending = b""
        if n == 0:
            return []
        self.bytes_dropped += n
        return [ErrorEvent("partial", f"stream ended inside a record: {n} bytes left incomplete", nbytes=n)]

    # -- binary -------------------------------------------------------------------------------------------

    def feed_arrays(self, data: bytes) -> RecordBatch:
        """Binary fast path: parse more bytes into a RecordBatch (vectorised over records).

        The batch holds the accepted records in stream order and, separately, the error events in stream order.
        """
        if not self.binary:
            raise ValidationError("feed_arrays() parses binary (F1) output; this parser is configured for ASCII")
        buf = self._pending + bytes(data)
        arr = np.frombuffer(buf, dtype=np.uint8)
        size = self._size
        starts = self._header_candidates(arr)
        if starts.size == 0:
            # Keep the last bytes: they may be the beginning of a header whose end has not arrived yet.
            keep = min(len(buf), HEADER_SIZE - 1)
            dropped = len(buf) - keep
            events = []
            if dropped:
                events.append(ErrorEvent("garbage", f"skipped {dropped} bytes with no record header", dropped))
                self.bytes_dropped += dropped
            self._pending = buf[len(buf) - keep :]
            return self._batch(np.zeros(0, dtype=self._dtype), events)
        nxt = np.append(starts[1:], np.iinfo(np.int64).max)
        complete = starts + size <= len(buf)
        cut_short = nxt < starts + size
        whole = complete & ~cut_short
        # Only the last header can be incomplete without a later header inside it: it waits for more bytes.
        if not complete[-1] and not cut_short[-1]:
            end = int(starts[-1])
        else:
            end = max(int(starts[-1]) + size, len(buf) - (HEADER_SIZE - 1))
        take = starts[whole]
        if take.size and int(take[-1]) - int(take[0]) == (take.size - 1) * size:
            # Back-to-back records (the normal stream): view the bytes in place, no gather.
            rec = np.frombuffer(buf, dtype=self._dtype, count=take.size, offset=int(take[0]))
            plausible = self._plausible(rec)
        elif take.size:
            rec = arr[take[:, None] + np.arange(size)].reshape(-1).view(self._dtype)
            plausible = self._plausible(rec)
        else:
            rec = np.zeros(0, dtype=self._dtype)
            plausible = np.zeros(0, dtype=bool)
        if take.size and not plausible[-1] and int(take[-1]) + size + HEADER_SIZE - 1 > len(buf):
            # A bad last record may be one cut short by a header whose end has not arrived yet: decide when it has.
            end = int(take[-1])
            rec, plausible = rec[:-1], plausible[:-1]
        events = self._gap_events(arr, starts, whole, cut_short, plausible, end)
        self._pending = buf[end:]
        good = rec[plausible]
        flagged = ~np.isin(good["error"], NO_ERROR)
        batch = self._batch(good[~flagged], events)
        if flagged.any():
            for r in self._batch(good[flagged], []).records():
                batch.events.append(
                    ErrorEvent("device_error", f"station {r.station} reported error code {r.error}", 0, r)
                )
        return batch

    def _header_candidates(self, arr: np.ndarray) -> np.ndarray:
        n = arr.shape[0] - HEADER_SIZE + 1
        if n <= 0:
            return np.zeros(0, dtype=np.int64)
        pos = np.flatnonzero((arr[:n] == MAGIC[0]) & (arr[1 : n + 1] == MAGIC[1])).astype(np.int64)
        if pos.size == 0:
            return pos
        ok = self._station_ok[arr[pos + 2]] & self._command_ok[arr[pos + 3]]
        size = arr[pos + 6].astype(np.int32) | (arr[pos + 7].astype(np.int32) << 8)
        ok &= size == self._size - HEADER_SIZE
        return pos[ok]

    def _plausible(self, rec: np.ndarray) -> np.ndarray:
        ok = np.ones(rec.shape[0], dtype=bool)
        names = rec.dtype.names
        # Damaged bytes decode to NaN, signalling NaN or huge floats: expected here, and rejected below.
        with np.errstate(invalid="ignore", over="ignore"):
            if "position" in names:
                p = rec["position"].astype(np.float64)
                ok &= np.all(np.isfinite(p), axis=1) & np.all(np.abs(p) < MAX_ABS_POSITION, axis=1)
            if "quaternion" in names:
                q = rec["quaternion"].astype(np.float64)
                norm = np.sqrt(np.sum(q * q, axis=1))
                ok &= np.isfinite(norm) & (np.abs(norm - 1.0) < QUAT_NORM_TOLERANCE)
        if "crlf" in names:
            ok &= (rec["crlf"][:, 0] == 13) & (rec["crlf"][:, 1] == 10)
        if "space" in names:
            ok &= rec["space"] == 0x20
        return ok

    def _gap_events(self, arr, starts, whole, cut_short, plausible, end) -> list[ErrorEvent]:
        """Events for the bytes in [0, end) that are not inside an accepted record."""
        size = self._size
        m = int(np.searchsorted(starts, end))  # headers that start before the kept tail
        # The common case, checked vectorised: back-to-back good records from byte 0 up to the tail.
        if (m == 0 and end == 0) or (
            m > 0
            and starts[0] == 0
            and whole[:m].all()
            and plausible.all()
            and np.all(np.diff(starts[:m]) == size)
            and int(starts[m - 1]) + size == end
        ):
            return []
        events: list[ErrorEvent] = []
        covered = 0
        wi = 0
        for k in range(m):
            s = int(starts[k])
            if s < covered:
                continue  # a header-looking byte run inside an accepted record
            if s > covered:
                events.append(ErrorEvent("garbage", f"skipped {s - covered} bytes before a record header", s - covered))
            if cut_short[k]:
                nb = int(starts[k + 1]) - s
                events.append(ErrorEvent(
                    "partial", f"record of station {int(arr[s + 2])} cut short after {nb} of {size} bytes", nb))
                covered = s + nb
                continue
            if not plausible[wi]:
                events.append(ErrorEvent(
                    "implausible",
                    f"dropped a record of station {int(arr[s + 2])} whose values are not a pose "
                    "(non-finite, non-unit quaternion or out of range)", size))
            wi += 1
            covered = s + size
        if end > covered:
            events.append(ErrorEvent("garbage", f"skipped {end - covered} bytes after the last record", end - covered))
        self.bytes_dropped += sum(e.nbytes for e in events)
        return events

    def _batch(self, rec: np.ndarray, events) -> RecordBatch:
        names = rec.dtype.names
        return RecordBatch(
            station=rec["station"].copy(),
            command=rec["command"].copy(),
            error=rec["error"].copy(),
            position=rec["position"].copy() if "position" in names else None,
            quaternion=rec["quaternion"].copy() if "quaternion" in names else None,
            timestamp_ms=rec["timestamp"].copy() if "timestamp" in names else None,
            frame=rec["frame"].copy() if "frame" in names else None,
            events=list(events),
        )

    # -- ASCII --------------------------------------------------------------------------------------------

    def _feed_ascii(self, data: bytes) -> list[Record | ErrorEvent]:
        buf = self._pending + bytes(data)
        out: list[Record | ErrorEvent] = []
        *lines, rest = buf.split(b"\r\n")
        # A line that never ends is not a record: bound what is kept so garbage cannot grow without limit.
        limit = 64 + 24 * sum(self._ascii_counts)
        if len(rest) > limit:
            out.append(ErrorEvent("garbage", f"skipped {len(rest)} bytes with no CR/LF", len(rest)))
            self.bytes_dropped += len(rest)
            rest = b""
        self._pending = rest
        for line in lines:
            item = decode_ascii_line(line, self.items, self._station_ok)
            if isinstance(item, ErrorEvent):
                skipped, item = self._resync_line(line, item)
                if skipped:
                    out.append(skipped)
                    self.bytes_dropped += skipped.nbytes
            if isinstance(item, ErrorEvent):
                self.bytes_dropped += item.nbytes
            elif item.error not in NO_ERROR:
                item = ErrorEvent("device_error", f"station {item.station} reported error code {item.error}", 0, item)
            out.append(item)
        return out

    def _resync_line(self, line: bytes, failure: ErrorEvent) -> tuple[ErrorEvent | None, Record | ErrorEvent]:
        """A bad line may be garbage (or a record cut short) followed by a good record: find that record."""
        for m in ASCII_HEADER.finditer(line, 1):
            rec = decode_ascii_line(line[m.start() :], self.items, self._station_ok)
            if isinstance(rec, Record):
                n = m.start()
                return ErrorEvent("garbage", f"skipped {n} bytes before an ASCII record", n), rec
        return None, failure
