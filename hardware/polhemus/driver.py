"""Polhemus Liberty driver: configure the device, read single or continuous records, yield PoseSamples in SI.

Time base: with the timestamp item (8) in the output list, which is the default, ``PoseSample.t`` is the
device clock (ms since the device's timer was last reset, continued past 2^32 ms by the stream's own steps) in s;
it has 1 ms resolution. Without it, ``t`` is the host's monotonic clock when the bytes were read (``time_base``
says which); records that arrive in one read then share a time, so keep item 8 whenever poses feed the perception
stack. Positions are converted to metres from the configured units; quaternions are (w, x, y, z) as the device sends.

Trust: a streamed record becomes a pose only if it could be true: frame counter and clock continuity, and a
position and orientation a hand can reach from its neighbours (:mod:`palpate.hardware.polhemus.plausibility`);
the others are counted in ``stats.rejected`` by reason.
"""

from __future__ import annotations

import time
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np

from palpate.core.errors import DeviceError, ValidationError
from palpate.core.perception.streams import PoseSample
from palpate.hardware.clock import DeviceTimeMap
from palpate.hardware.polhemus.parser import RecordParser
from palpate.hardware.polhemus.plausibility import Plausibility, RecordGate
from palpate.hardware.polhemus.protocol import (
    CM_PER_INCH,
    DEFAULT_ITEMS,
    ITEM_POSITION,
    ITEM_QUATERNION,
    ITEM_TIMESTAMP,
    ErrorEvent,
    Record,
    format_command,
    output_list_command,
    validate_items,
    validate_station,
)

UNIT_TO_M = {"cm": 0.01, "in": CM_PER_INCH / 100.0}
READ_CHUNK = 1 << 14


def station_sensor_id(station: int) -> str:
    """Sensor id of a Liberty station in PoseSamples and recordings."""
    return f"liberty_station{station}"


@dataclass
class StreamStats:
    """What a stream produced.

    Attributes:
        records: good records per station.
        errors: error events (garbage, partial, implausible, device_error, bad_line), in arrival order.
        rejected: records that parsed but could not be true, by reason (see
            :mod:`palpate.hardware.polhemus.plausibility`).
        stop_reason: why the stream ended: 'duration', 'count', 'stopped', 'silent' (no record within the
            timeout) or 'link lost: ...'.
        started, ended: host monotonic clock, s.
    """

    records: dict[int, int] = field(default_factory=dict)
    errors: list[ErrorEvent] = field(default_factory=list)
    rejected: Counter = field(default_factory=Counter)
    stop_reason: str = ""
    started: float = 0.0
    ended: float = 0.0

    @property
    def total(self) -> int:
        return int(sum(self.records.values()))

    def error_counts(self) -> dict[str, int]:
        out: dict[str, int] = {}
        for e in self.errors:
            out[e.kind] = out.get(e.kind, 0) + 1
        return out


class LibertyDriver:
    """Drive a Liberty over any byte transport (serial, pty, USB).

    Args:
        transport: an open transport (see :mod:`palpate.hardware.polhemus.transport`).
        stations: stations to read, 1-based; records of other stations are ignored.
        units: 'cm' (U1) or 'in' (U0) on the wire; PoseSamples are always in metres.
        binary: F1 binary output (True) or F0 ASCII (False).
        items: output list; must contain position (2) and quaternion (7).
        timeout: how long to wait for an answer, s; also how long a silent stream is tolerated.
        plausibility: the bounds a streamed record must meet to become a pose (see
            :mod:`palpate.hardware.polhemus.plausibility`); records are delayed by one per station for it (two
            while one does not fit).
    """

    def __init__(self, transport, stations=(1,), units: str = "cm", binary: bool = True, items=DEFAULT_ITEMS,
                 timeout: float = 0.5, plausibility: Plausibility | None = None):
        if units not in UNIT_TO_M:
            raise ValidationError(f"Liberty units must be 'cm' or 'in', got {units!r}")
        self.stations = tuple(sorted({validate_station(s) for s in stations}))
        if not self.stations:
            raise ValidationError("LibertyDriver needs at least one station")
        self.items = validate_items(items)
        for needed in (ITEM_POSITION, ITEM_QUATERNION):
            if needed not in self.items:
                raise ValidationError(f"Liberty output list {self.items} must contain item {needed} to make poses")
        if not timeout > 0:
            raise ValidationError(f"Liberty answer timeout must be > 0 s, got {timeout}")
        self.transport = transport
        self.units = units
        self.binary = bool(binary)
        self.timeout = float(timeout)
        self.time_base = "device" if ITEM_TIMESTAMP in self.items else "host"
        self._scale = UNIT_TO_M[units]
        self._parser = self._new_parser()
        self.plausibility = plausibility or Plausibility()
        # Set to a DeviceTimeMap to have streamed poses on the host clock (device time + least arrival delay).
        self.host_time_map: DeviceTimeMap | None = None
        self._last_host_t: dict[int, float] = {}
        self._gate = RecordGate(self.plausibility)
        self.stats = StreamStats(rejected=self._gate.rejected)
        self.streaming = False

    def _new_parser(self) -> RecordParser:
        # Accept any station while parsing so a sensor that was not asked for is not mistaken for garbage.
        return RecordParser(self.items, stations=None, binary=self.binary)

    # -- setup --------------------------------------------------------------------------------------------

    def configure(self) -> None:
        """Stop any stream left running, set format, units and output list, and check the device answers.

        Raises DeviceError naming the link when nothing valid comes back (wrong baud, device off, wrong port).
        """
        # P ends a stream left running; when idle the device answers it with one record, drained here too.
        self.transport.write(format_command("P"))
        self._drain(limit=max(0.2, self.timeout))
        self.transport.write(format_command("F", 1 if self.binary else 0))
        self.transport.write(format_command("U", 1 if self.units == "cm" else 0))
        self.transport.write(output_list_command(self.items))
        self._parser = self._new_parser()
        self.single()

    def _drain(self, quiet: float = 0.1, limit: float = 1.0) -> bytes:
        """Read until the line has been quiet for ``quiet`` s (at most ``limit`` s); return what was read."""
        got = bytearray()
        deadline = time.monotonic() + limit
        last = time.monotonic()
        while time.monotonic() < deadline and time.monotonic() - last < quiet:
            chunk = self.transport.read(READ_CHUNK)
            if chunk:
                got += chunk
                last = time.monotonic()
        return bytes(got)

    # -- reading ------------------------------------------------------------------------------------------

    def single(self) -> list[PoseSample]:
        """Ask for one record per station (``P``) and return one PoseSample per requested station.

        Raises DeviceError if nothing valid arrives within the timeout (with a hint at the baud rate), or if a
        station answers only with a device error.
        """
        if self.streaming:
            raise DeviceError("single() while continuous output is on; call stop() first")
        self.transport.write(format_command("P"))
        got: dict[int, PoseSample] = {}
        flagged: dict[int, ErrorEvent] = {}
        nbytes = 0
        deadline = time.monotonic() + self.timeout
        while time.monotonic() < deadline and len(got) < len(self.stations):
            chunk = self.transport.read(READ_CHUNK)
            nbytes += len(chunk)
            t_host = time.monotonic()
            for item in self._parse(chunk):
                if isinstance(item, ErrorEvent):
                    self.stats.errors.append(item)
                    if item.record is not None and item.record.station in self.stations:
                        flagged[item.record.station] = item
                elif item.station in self.stations:
                    got[item.station] = self._pose(item, item.timestamp_ms / 1000.0 if item.timestamp_ms is not None
                                                   else t_host)
        missing = [s for s in self.stations if s not in got]
        if not missing:
            return [got[s] for s in self.stations]
        where = getattr(self.transport, "description", "the link")
        if nbytes == 0:
            raise DeviceError(
                f"no answer from the Liberty on {where} within {self.timeout:g} s; check that it is powered, "
                "that this is its port, and that the baud rate matches the device's"
            )
        if not got and not flagged:
            raise DeviceError(
                f"the Liberty on {where} sent {nbytes} bytes but no valid record within {self.timeout:g} s: "
                "no answer at this baud rate; check the baud rate set on the device"
            )
        if flagged and all(s in flagged for s in missing):
            codes = ", ".join(f"station {s}: error code {flagged[s].record.error}" for s in missing)
            raise DeviceError(f"the Liberty on {where} reported an error ({codes})")
        raise DeviceError(
            f"station(s) {missing} of the Liberty on {where} did not answer within {self.timeout:g} s; "
            "is a sensor plugged into each?"
        )

    def start_continuous(self) -> None:
        """Start continuous output (``C``)."""
        self._parser = self._new_parser()
        self._gate = RecordGate(self.plausibility)
        self.stats = StreamStats(records={s: 0 for s in self.stations}, started=time.monotonic(),
                                 rejected=self._gate.rejected)
        self.transport.write(format_command("C"))
        self.streaming = True

    def stream(self, seconds: float | None = None, max_records: int | None = None) -> Iterator[PoseSample]:
        """Yield PoseSamples from continuous output until ``seconds`` of host time, ``max_records`` records, or
        the device goes silent for ``timeout`` s, whichever comes first. Starts continuous output if needed.

        Never raises for a silent device or a lost link: it ends cleanly, keeps every record received, and
        says why in ``stats.stop_reason``. Error events are collected in ``stats.errors``.
        """
        if seconds is not None and not seconds > 0:
            raise ValidationError(f"stream duration must be > 0 s, got {seconds}")
        if not self.streaming:
            self.start_continuous()
        start = time.monotonic()
        last_good = start
        count = 0
        while True:
            now = time.monotonic()
            if seconds is not None and now - start >= seconds:
                self.stats.stop_reason = "duration"
                break
            if now - last_good > self.timeout:
                self.stats.stop_reason = "silent"
                break
            try:
                chunk = self.transport.read(READ_CHUNK)
            except DeviceError as exc:
                self.stats.stop_reason = f"link lost: {exc}"
                break
            t_host = time.monotonic()
            for item in self._parse(chunk):
                if isinstance(item, ErrorEvent):
                    self.stats.errors.append(item)
                    continue
                if item.station not in self.stations:
                    continue
                last_good = t_host
                for pose in self._accept(item, t_host):
                    count += 1
                    yield pose
                    if max_records is not None and count >= max_records:
                        self.stats.stop_reason = "count"
                        self.stats.ended = time.monotonic()
                        return
        if self.stats.stop_reason != "duration":
            # The device is gone: an incomplete tail will never complete, and the records held for checking have
            # no successor. After a duration the stream is still running and stop() parses the rest of it.
            self.stats.errors.extend(self._parser.flush())
            yield from self._flush_gate()
        self.stats.ended = time.monotonic()

    def stop(self) -> list[PoseSample]:
        """Stop continuous output (``P``) and return the records that were already on their way."""
        if not self.streaming:
            return []
        self.streaming = False
        try:
            self.transport.write(format_command("P"))
            tail = self._drain(quiet=min(0.1, self.timeout), limit=max(0.2, self.timeout))
        except DeviceError as exc:
            self.stats.stop_reason = self.stats.stop_reason or f"link lost: {exc}"
            return []
        t_host = time.monotonic()
        out = []
        for item in [*self._parse(tail), *self._parser.flush()]:
            if isinstance(item, ErrorEvent):
                self.stats.errors.append(item)
            elif item.station in self.stations:
                out += self._accept(item, t_host)
        out += self._flush_gate()
        if not self.stats.stop_reason:
            self.stats.stop_reason = "stopped"
        self.stats.ended = time.monotonic()
        return out

    # -- conversion ---------------------------------------------------------------------------------------

    def _parse(self, chunk: bytes) -> list[Record | ErrorEvent]:
        return self._parser.feed(chunk) if chunk else []

    def _accept(self, rec: Record, t_host: float) -> list[PoseSample]:
        """The poses the plausibility gate accepts on seeing ``rec`` (counted in ``stats.records``)."""
        accepted = self._gate.feed(rec.station, np.asarray(rec.position, dtype=float) * self._scale, rec.quaternion,
                                   rec.timestamp_ms, rec.frame, t_host, (rec, t_host), rec.quaternion_rounding)
        return [self._counted(self._pose(r, t, host)) for t, (r, host) in accepted]

    def _flush_gate(self) -> list[PoseSample]:
        return [self._counted(self._pose(r, t, host)) for t, (r, host) in self._gate.flush()]

    def _counted(self, pose: PoseSample) -> PoseSample:
        station = int(pose.sensor_id.removeprefix("liberty_station"))
        self.stats.records[station] = self.stats.records.get(station, 0) + 1
        return pose

    def _pose(self, rec: Record, t: float, host: float | None = None) -> PoseSample:
        """A record as a PoseSample at time ``t`` (s; the device clock unwrapped by the gate, or the host's); with a
        ``host_time_map``, device times arriving at host time ``host`` are put on the host clock."""
        if self.host_time_map is not None and host is not None and rec.timestamp_ms is not None:
            self.host_time_map.observe(t, host)
            t = self.host_time_map.host_time(t)
            last = self._last_host_t.get(rec.station)
            if last is not None and t <= last:  # the offset fell (a less delayed record): keep times increasing
                t = last + 1e-6
            self._last_host_t[rec.station] = t
        return PoseSample(
            t=t,
            position=np.asarray(rec.position, dtype=float) * self._scale,
            quaternion=np.asarray(rec.quaternion, dtype=float),
            sensor_id=station_sensor_id(rec.station),
        )
