"""Whether a Liberty record can be true: a record that parses is not yet a pose to trust.

A binary record has no checksum, so a corrupted byte inside one (or random bytes that happen to start with a
plausible header) still decodes to numbers. Each record is therefore checked against the station's own recent
records before it becomes a pose:

- **sequence**: the frame counter (item 9) moves forward by 1..``max_skip`` frames, and the device clock (item 8)
  by as many frame periods (within ``time_slack``), both modulo 2^32, so a genuine wrap of the 32-bit clock is
  simply a small step forward and a garbled top byte is a jump no device makes;
- **clock phase**: the Liberty stamps each frame with its own clock in whole ms, and its frames are exactly one
  period apart on that clock, so the stamps of a station's recent frames, less their frame count times the period,
  lie within one tick of each other. A stamp moved by a tick or two (a damaged low byte) fits a single step within
  ``time_slack`` but breaks that phase; with ``frame_locked_clock`` off (a tracker that stamps by host time) only
  the steps are checked;
- **quaternion norm**: the device sends unit quaternions, rounded by the record's format (float32 in binary, the
  decimals written in ASCII), so a norm off 1 by more than ``quaternion_norm`` plus that rounding is a damaged
  record (a byte of a component near 0 turns the sensor by a degree or two and nothing else tells);
- **motion**: a record is held until the next good one arrives, then its position must lie on the path between
  its neighbours: the interpolation error of a hand's path with acceleration at most ``max_accel`` is at most
  ``max_accel / 2 * (t - t0) * (t1 - t)``, plus the tracker's noise; its orientation likewise with
  ``max_angular_accel``; its speed from the last good pose is at most ``max_speed``. When it does not fit, either
  it or its successor is off the path: the record after the successor decides (it is kept when it fits between
  its predecessor and that record and the successor does not fit between them). Dropping a good record for a bad
  successor would widen the gap round the bad one, and the bound grows with the gap: so the two records a record
  is checked between lie at most ``vouch_span`` frames apart (``damaged_span`` on a line that has just damaged two
  records); beyond that the record is dropped and the station locks in again.

A stream starts (and restarts after ``relock_after`` s of host time without a good record, unless that record
continues the station's frame counter and clock: a host that stalled reads the buffered frames late) by three
consecutive records that agree with each other; until then nothing is trusted, and a record that disagrees with
those held replaces them. Locking in again within a running stream keeps only the middle of the three (the one
checked between the others). Rejected records are counted by reason; nothing is repaired or invented. The cost is one
record of delay per station (4 ms at 240 Hz), two when a record does not fit.

The bound is physical, so a damaged position that stays within it next to a long gap (records lost on either side)
still passes; docs/real_rig.md says how often on a very noisy line.
"""

from __future__ import annotations

import math
from collections import Counter, deque
from dataclasses import dataclass, field

import numpy as np

#: At lock-in the three records must be at most this many frames apart (a clean stream has them consecutive).
LOCK_SKIP = 3
#: Reasons a record is rejected (StreamStats.rejected keys).
REASONS = ("frame counter", "timestamp", "position jump", "orientation jump", "speed", "no lock", "quaternion norm",
           "gap")
#: How many of a station's latest good records the clock phase is checked against: enough to hold every phase of
#: the ms rounding at 240 Hz (it repeats every 6 frames) twice.
PHASE_FRAMES = 12


@dataclass(frozen=True)
class Plausibility:
    """What a hand holding a Liberty sensor can do, and what the tracker's noise is.

    Attributes:
        max_speed: m/s (a fast hand: a few m/s).
        max_accel: m/s^2 (quick hand movements stay under ~50).
        max_angular_accel: rad/s^2.
        position_noise: standard deviation of the tracker's position noise, m.
        orientation_noise: of its orientation, rad.
        sigmas: how many noise standard deviations a record may stray.
        max_skip: most frames between two records of a station that are still one stream.
        time_slack: how far the clock step may differ from the frame step times the period, s (1 ms ticks).
        relock_after: a station without a good record for this long starts again from three agreeing records, s.
        frame_locked_clock: the device stamps frames by a clock its frame rate is locked to (the Liberty's), so
            the clock phase is checked (module docstring).
        clock_tick: the timestamp's resolution, s.
        quaternion_norm: how far the device's own quaternion norm may be from 1 before its output format rounds
            it; the gate adds the record's rounding (``feed``'s ``quaternion_rounding``: ~6e-8 in binary float32,
            1e-4 with four decimals in ASCII, 1e-6 with six), as rounding each component by at most h moves the
            norm by at most 2 h. A damaged byte in a component near 0, which turns the sensor by a degree or two,
            moves the norm by ~1e-4 (a component of 0.01 adds 5e-5): caught in binary and six-decimal ASCII, not
            always with four decimals. Raise it for a tracker whose quaternions are less exactly unit.
        vouch_span: the two records a record is checked between may lie at most this many frames apart (3: one
            lost record beside it). Across a longer gap the bound a hand's acceleration allows grows past the few
            mm a damaged byte moves a float32 position (steps of 1.25 mm at 20-30 cm), so such a record is dropped
            and the station locks in again; 0 checks no span (records without a frame counter are never held to
            it).
        damaged_span: the span allowed instead on a damaged line: one where two records of the station were
            rejected for their values within ``damage_memory`` s. At 240 Hz a span of 3 lets a record stray
            2.3 mm (acceleration term 0.9 mm plus the noise term 1.4 mm), one of 2 (its own neighbours) 1.8 mm:
            under the 2 mm that misleads. A single damaged record on a clean line still costs only itself.
    """

    max_speed: float = 5.0
    max_accel: float = 50.0
    max_angular_accel: float = 500.0
    position_noise: float = 2e-4
    orientation_noise: float = math.radians(0.05)
    sigmas: float = 5.0
    max_skip: int = 1000
    time_slack: float = 0.0015
    relock_after: float = 0.5
    frame_locked_clock: bool = True
    clock_tick: float = 0.001
    quaternion_norm: float = 1e-6
    vouch_span: int = 3
    damaged_span: int = 2
    damage_memory: float = 0.25


@dataclass
class _Pose:
    t: float  # s, unwrapped device time
    ms: int | None
    frame: int | None
    position: np.ndarray
    quaternion: np.ndarray
    record: object
    host: float  # host time it arrived, s


@dataclass
class _Station:
    accepted: list = field(default_factory=list)  # the last accepted poses (at most 2)
    pending: list = field(default_factory=list)  # sequence-checked, not yet motion-checked
    period: float | None = None  # s per frame, from the first and the latest accepted record
    period_error: float = 0.0  # its bound, s per frame: the two ends' rounding differs by less than a tick
    first: _Pose | None = None  # the first accepted record since lock-in
    recent: deque = field(default_factory=lambda: deque(maxlen=PHASE_FRAMES))  # (frame, t) of the latest good ones
    damage: deque = field(default_factory=lambda: deque(maxlen=2))  # device times of the latest value rejections


class RecordGate:
    """Per-station plausibility checks (see the module docstring); ``feed`` returns the records now accepted.

    Args:
        limits: the bounds.
    """

    def __init__(self, limits: Plausibility | None = None):
        self.limits = limits or Plausibility()
        self.rejected: Counter[str] = Counter()
        self._stations: dict[int, _Station] = {}

    def feed(self, station: int, position: np.ndarray, quaternion: np.ndarray, timestamp_ms: int | None,
             frame: int | None, t_host: float, record=None, quaternion_rounding: float = 0.0
             ) -> list[tuple[float, object]]:
        """Check one record (position m, quaternion w,x,y,z, ``quaternion_rounding``: how far its format can have
        moved the quaternion, :attr:`~palpate.hardware.polhemus.protocol.Record.quaternion_rounding`); returns
        ``(t, record)`` of every record accepted by it, in order (none, or the one held before it, or two at
        lock-in). ``t`` is the unwrapped device time in s (the host time ``t_host`` when the record has no
        timestamp)."""
        st = self._stations.setdefault(station, _Station())
        quat = np.asarray(quaternion, dtype=float)
        if not abs(float(np.linalg.norm(quat)) - 1.0) <= self.limits.quaternion_norm + quaternion_rounding:
            self.rejected["quaternion norm"] += 1
            if st.accepted:
                st.damage.append(st.accepted[-1].t)
            return []
        pose = _Pose(0.0, timestamp_ms, frame, np.asarray(position, dtype=float), quat / np.linalg.norm(quat), record,
                     t_host)
        if st.accepted and t_host - st.accepted[-1].host > self.limits.relock_after \
                and not self._resumes(st, timestamp_ms, frame, t_host):
            # no good record for a while (a silent or restarted device): start again from agreeing records
            self.rejected["no lock"] += len(st.pending)
            st = self._stations[station] = _Station()
        if st.accepted:
            # the sequence is checked against the last record known good, never against one still held
            pose.t, why = self._sequence(st, st.accepted[-1], timestamp_ms, frame, t_host)
            if why is not None:
                self.rejected[why] += 1
                st.damage.append(st.accepted[-1].t)
                return []
            st.pending.append(pose)
            return self._decide(st)
        ref = st.pending[-1] if st.pending else None
        pose.t, why = self._sequence(st, ref, timestamp_ms, frame, t_host)
        if why is not None:
            # nothing is confirmed yet: the records held so far were the odd ones out as much as this one
            self.rejected["no lock"] += len(st.pending)
            st.pending.clear()
            pose.t = timestamp_ms / 1000.0 if timestamp_ms is not None else t_host
        st.pending.append(pose)
        return self._lock_in(st)

    def flush(self) -> list[tuple[float, object]]:
        """End of stream: a record still held has no successor to be checked against; it is accepted when it
        continues the last two good poses (extrapolated, with the acceleration bound), else rejected (counted)."""
        out = []
        for st in self._stations.values():
            for c in st.pending:
                if len(st.accepted) == 2 and self._continues(*st.accepted, c) is None:
                    st.accepted = [st.accepted[1], c]
                    out.append((c.t, c.record))
                else:
                    self.rejected["no lock"] += 1
            st.pending.clear()
        return sorted(out, key=lambda x: x[0])

    # ---- sequence ------------------------------------------------------------------------------------------
    def _resumes(self, st: _Station, ms, frame, t_host) -> bool:
        """Whether a record that arrives long after the last good one (host time) still continues its device
        sequence: the host stalled and read the buffered frames late (a loaded machine), the device did not stop.
        Without a frame counter or a stamp nothing tells the two apart, so the stream restarts."""
        if frame is None and ms is None:
            return False
        return self._sequence(st, st.accepted[-1], ms, frame, t_host)[1] is None

    def _sequence(self, st: _Station, ref: _Pose | None, ms, frame, t_host) -> tuple[float, str | None]:
        lim = self.limits
        if ref is None:
            return (ms / 1000.0 if ms is not None else t_host), None
        df = None
        if frame is not None and ref.frame is not None:
            df = (frame - ref.frame) % (1 << 32)
            if not 1 <= df <= lim.max_skip:
                return 0.0, "frame counter"
        if ms is None or ref.ms is None:
            return t_host, None
        dt = ((ms - ref.ms) % (1 << 32)) / 1000.0
        if not 0 < dt <= lim.relock_after:
            return 0.0, "timestamp"
        if df is not None and st.period is not None and \
                abs(dt - df * st.period) > lim.time_slack + df * st.period_error:
            return 0.0, "timestamp"
        if df is not None and lim.frame_locked_clock and not self._in_phase(st, frame, ref.t + dt):
            return 0.0, "timestamp"
        return ref.t + dt, None

    def _in_phase(self, st: _Station, frame: int, t: float) -> bool:
        """Whether a record's stamp keeps the station's recent stamps within one tick of one clock phase."""
        if st.period is None or st.first is None or not st.recent:
            return True
        frames = np.array([f for f, _ in st.recent] + [frame], dtype=np.int64)
        times = np.array([s for _, s in st.recent] + [t])
        counted = (frames - st.first.frame) % (1 << 32)
        phase = times - counted * st.period
        # Rounded to whole ticks, one clock's stamps spread over less than a tick (nearly one when the rate is
        # nearly a whole number of ticks per frame); a stamp moved by a tick spreads them over a tick plus its
        # distance from the earliest phase, so it is caught unless it is that earliest (or latest) one. The
        # period's own error tilts the phases over the frames spanned.
        tilt = (counted.max() - counted.min()) * st.period_error
        return float(phase.max() - phase.min()) <= self.limits.clock_tick + tilt

    def _learn_period(self, st: _Station, a: _Pose, b: _Pose) -> None:
        """The frame period over the longest baseline known: first accepted record to ``b``."""
        if a.frame is None or b.frame is None or a.ms is None or b.ms is None:
            return
        if st.first is None:
            st.first = a
            st.recent.append((a.frame, a.t))
        st.recent.append((b.frame, b.t))
        df = (b.frame - st.first.frame) % (1 << 32)
        if df:
            st.period = (b.t - st.first.t) / df
            st.period_error = self.limits.clock_tick / df


    # ---- motion --------------------------------------------------------------------------------------------
    def _span(self, st: _Station, t: float) -> int:
        """Most frames between the two records that check one at device time ``t`` (s): ``vouch_span``, or
        ``damaged_span`` on a line that has just damaged two records."""
        lim = self.limits
        recent = sum(1 for x in st.damage if 0.0 <= t - x <= lim.damage_memory)
        return lim.damaged_span if recent >= 2 else lim.vouch_span

    def _fits_between(self, a: _Pose, c: _Pose, b: _Pose, span: int = 0) -> str | None:
        """Why ``c`` cannot lie between ``a`` and ``b`` (None when it can; ``span``: most frames from a to b, 0 for
        any)."""
        lim = self.limits
        if _frames_apart(a, b) > span > 0:
            return "gap"
        span = b.t - a.t
        if span <= 0 or not a.t < c.t < b.t:
            # host stamps (no timestamp item): records read together share a time; only their order is known
            return None if c.ms is None else "timestamp"
        w = (c.t - a.t) / span
        bend = 0.5 * (c.t - a.t) * (b.t - c.t)
        if np.linalg.norm(b.position - a.position) > lim.max_speed * span + lim.sigmas * lim.position_noise * 2:
            return "speed"
        off = np.linalg.norm(c.position - (a.position + w * (b.position - a.position)))
        if off > lim.max_accel * bend + lim.sigmas * lim.position_noise * math.sqrt(2):
            return "position jump"
        q_mid = _slerp(a.quaternion, b.quaternion, w)
        angle = 2.0 * math.acos(min(1.0, abs(float(np.dot(q_mid, c.quaternion)))))
        if angle > lim.max_angular_accel * bend + lim.sigmas * lim.orientation_noise * math.sqrt(2):
            return "orientation jump"
        return None

    def _continues(self, a: _Pose, b: _Pose, c: _Pose) -> str | None:
        """Why ``c`` cannot follow ``a`` and ``b`` (extrapolated; None when it can)."""
        lim = self.limits
        if b.t <= a.t or c.t <= b.t:
            return None if c.ms is None else "timestamp"
        w = (c.t - a.t) / (b.t - a.t)
        bend = 0.5 * (c.t - a.t) * (c.t - b.t)
        off = np.linalg.norm(c.position - (a.position + w * (b.position - a.position)))
        if off > lim.max_accel * bend + lim.sigmas * lim.position_noise * (1 + abs(w)):
            return "position jump"
        return None

    def _lock_in(self, st: _Station) -> list[tuple[float, object]]:
        while len(st.pending) >= 3:
            a, c, b = st.pending[-3:]
            if self._fits_between(a, c, b, self._span(st, c.t)) is None and \
                    _same_rhythm(a, c, b, self.limits.time_slack):
                # only c was checked between two others: a damaged a shows at c by half its damage at most. At the
                # stream's start a is kept (a configured device's first records); locking in again after a gap
                # in a running stream (a damaged line) it is dropped
                restart = st.first is not None
                st.accepted = [c] if restart else [a, c]
                st.pending = [b]
                self._learn_period(st, a, c)
                self._learn_period(st, c, b)
                if restart:
                    self.rejected["no lock"] += 1
                    return [(c.t, c.record)]
                return [(a.t, a.record), (c.t, c.record)]
            self.rejected["no lock"] += 1
            st.pending.pop(0)
        return []

    def _decide(self, st: _Station) -> list[tuple[float, object]]:
        out = []
        while len(st.pending) >= 2:
            a = st.accepted[-1]
            c, b = st.pending[0], st.pending[1]
            span = self._span(st, c.t)
            why = self._fits_between(a, c, b, span)
            if why is not None:
                # c or b is off the path: wait for the record after b to tell which. Dropping a good c for a bad
                # b would widen the gap round b, and with it the bound a bad record is checked against.
                if len(st.pending) < 3:
                    break
                d = st.pending[2]
                if self._fits_between(a, c, d, span) is None and self._fits_between(c, b, d, span) is not None:
                    why = None
            if why == "gap":
                # the last good record is too far back to vouch for c: lock in again from the records held
                st.accepted = []
                return out + self._lock_in(st)
            if why is None:
                self._learn_period(st, a, c)
                st.accepted = [a, c]
                out.append((c.t, c.record))
            else:
                # c, or its successor, is not on a hand's path: drop c; a bad successor fails in its turn
                self.rejected[why] += 1
                st.damage.append(c.t)
            st.pending.pop(0)
        return out


def _slerp(q0: np.ndarray, q1: np.ndarray, s: float) -> np.ndarray:
    dot = float(np.dot(q0, q1))
    if dot < 0:
        q1, dot = -q1, -dot
    if dot > 0.9999995:
        q = q0 + s * (q1 - q0)
        return q / np.linalg.norm(q)
    theta = math.acos(min(1.0, dot))
    return (math.sin((1 - s) * theta) * q0 + math.sin(s * theta) * q1) / math.sin(theta)


def _frames_apart(a: _Pose, b: _Pose) -> int:
    """Frames from ``a`` to ``b`` (0 when either has no frame counter)."""
    if a.frame is None or b.frame is None:
        return 0
    return (b.frame - a.frame) % (1 << 32)


def _same_rhythm(a: _Pose, c: _Pose, b: _Pose, slack: float) -> bool:
    """At lock-in, before any period is known: the three records are close frames (at most ``LOCK_SKIP`` apart)
    whose clock steps fit one frame period."""
    if a.frame is None or c.frame is None or b.frame is None or a.ms is None:
        return True
    d1, d2 = (c.frame - a.frame) % (1 << 32), (b.frame - c.frame) % (1 << 32)
    if not (1 <= d1 <= LOCK_SKIP and 1 <= d2 <= LOCK_SKIP):
        return False
    p1, p2 = (c.t - a.t) / d1, (b.t - c.t) / d2
    return abs(p1 - p2) <= slack
