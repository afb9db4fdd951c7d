"""How many wrong poses a faulty line lets through: the emulator sends records with injected faults over a pty,
the real driver reads them through pyserial, and every pose it accepts is compared with what the emulator meant to
send. Used by the tests and by ``benchmarks/liberty_faults.py``.

A pose counts as **wrong** when no record with its station and timestamp was sent, or when it lies more than
``WRONG_POSITION`` from that record's position or ``WRONG_ANGLE`` from its orientation: beyond the Liberty's own
accuracy (0.76 mm and 0.15 degrees RMS), so a wrong pose is one that could mislead, not one within the noise.

A trial is reproducible: the emulator's stream starts at a fixed device time (``STREAM_TIME``) and draws its noise
and faults per record from the seed, and only the records stamped within a fixed window of device time are counted,
read until a pose beyond the window shows every record in it has been decided. One seed gives one outcome whatever
the host's timing: the trial's driver tolerates a host that stalls for up to ``STALL_TOLERANCE`` (a loaded machine
reading late) before it calls the line silent or lets its gate relock, so neither a silence timeout nor a relock
decided by host time can end or change a trial (``relock_after`` and the silence timeout are host-time rules of a
live rig, tested on their own).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from palpate.hardware.clock import FastClock
from palpate.hardware.polhemus.driver import LibertyDriver
from palpate.hardware.polhemus.emulator import Faults, LibertyEmulator, press_motion
from palpate.hardware.polhemus.plausibility import Plausibility
from palpate.hardware.polhemus.transport import SerialTransport

WRONG_POSITION = 0.002  # m
WRONG_ANGLE = math.radians(1.0)
#: Device time of the first streamed frame, s (whole ms).
STREAM_TIME = 1.0
#: A pose this far beyond the window, s, means every record in it has been accepted or rejected (the gate holds a
#: record at most a few frames).
DECIDED_AFTER = 0.1
#: Longest host stall, s, after which a trial's stream still goes on as if the host had kept up.
STALL_TOLERANCE = 30.0


@dataclass(frozen=True)
class FaultTrial:
    """The outcome of one trial.

    Attributes:
        sent: records the emulator sent while streaming.
        damaged: of those, records a fault touched (bytes, garbage, false header before it, cut, error code).
        accepted: poses the driver accepted.
        wrong: accepted poses that are wrong (see the module docstring).
        lost_good: undamaged records the driver did not accept.
        max_position_error: largest distance of an accepted pose from its record, m (wrong ones without a record
            left out).
        max_angle_error: largest angle, rad.
        rejected: the driver's rejections by reason; events: its parser's error events by kind. Both also count
            the tail read after the window, which depends on when the host stopped reading.
    """

    sent: int
    damaged: int
    accepted: int
    wrong: int
    lost_good: int
    max_position_error: float
    max_angle_error: float
    rejected: dict
    events: dict

    @property
    def rejection_rate(self) -> float:
        """Fraction of the records sent that did not become poses."""
        return 1.0 - self.accepted / max(self.sent, 1)


def run_trial(faults: Faults, *, binary: bool = True, seconds: float = 1.0, speedup: float = 10.0, rate: float = 240.0,
              noise: float = 1e-4, seed: int = 0) -> FaultTrial:
    """Count the records of ``seconds`` of host time at ``speedup`` (``seconds * speedup`` s of device time) from an
    emulator with ``faults``, its sensor pressing 1 cm deep once a second, tilting by up to 0.5 rad, 30 cm from the
    source (the module docstring says what is counted)."""
    motion = press_motion(depth=0.01, period=1.0, origin=(0.25, -0.1, 0.3), tilt=0.5)
    end = STREAM_TIME + seconds * speedup
    end_ms = round(end * 1000)
    with LibertyEmulator(rate=rate, stations=(1,), noise=noise, seed=seed, motion=motion, clock=FastClock(speedup),
                         stream_time=STREAM_TIME) as emu, SerialTransport(emu.port, 115200, timeout=0.02) as transport:
        driver = LibertyDriver(transport, binary=binary, timeout=STALL_TOLERANCE,
                               plausibility=Plausibility(relock_after=STALL_TOLERANCE))
        driver.configure()
        emu.faults = faults  # clean while configuring: the trial is about the stream
        first = len(emu.sent)
        poses = []
        # host time is only a backstop (a line so damaged no pose beyond the window gets through)
        for p in driver.stream(seconds=4 * seconds + 2 + STALL_TOLERANCE):
            poses.append(p)
            if p.t >= end + DECIDED_AFTER:
                break
        poses += driver.stop()
        sent = [r for r in emu.sent[first:] if r.timestamp_ms < end_ms]
    poses = [p for p in poses if round(p.t * 1000.0) < end_ms]
    truth = {(r.station, r.timestamp_ms): r for r in sent}
    wrong, used, d_pos, d_ang = 0, set(), [0.0], [0.0]
    for p in poses:
        key = (int(p.sensor_id.removeprefix("liberty_station")), round(p.t * 1000.0) % (1 << 32))
        r = truth.get(key)
        if r is None:
            wrong += 1
            continue
        used.add(key)
        q = r.quaternion / np.linalg.norm(r.quaternion)
        dp = float(np.linalg.norm(p.position - r.position))
        da = 2.0 * math.acos(min(1.0, abs(float(np.dot(q, p.quaternion)))))
        d_pos.append(dp)
        d_ang.append(da)
        wrong += int(dp > WRONG_POSITION or da > WRONG_ANGLE)
    damaged = [r for r in sent if r.faults]
    lost_good = sum(1 for r in sent if not r.faults and (r.station, r.timestamp_ms) not in used)
    return FaultTrial(len(sent), len(damaged), len(poses), wrong, lost_good, max(d_pos), max(d_ang),
                      dict(driver.stats.rejected), driver.stats.error_counts())
