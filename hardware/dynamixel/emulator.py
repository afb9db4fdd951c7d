"""A bus of emulated X-series servos speaking Protocol 2.0 on a pseudo-terminal.

The emulator opens a pty pair, serves the master side from a thread, and exposes the slave path as
``.port`` so that ``dynamixel_sdk.PortHandler`` opens it like a USB2Dynamixel adapter. Each servo has a
full control-table memory (model number, limits, torque enable, goal/present registers), a simple dynamics
model (position tracking at a rate limit, current from an external load) and optional faults: a servo that
stops answering, corrupted CRCs on status packets, a hardware-error alert.

The load on the joints comes from a pluggable ``load_model(angles) -> torques`` (servo shaft angles in rad,
0 at the centre tick, to the external torque on each shaft in N*m), so a test can put a virtual surface under
the fingertip and a fuller setup can back it with the MuJoCo finger (``palpate.sim.finger_physics.physics_bus``
gives both the load model and an ``observer`` that turns what the servos did into taxel frames).

Run ``python -m palpate.hardware.dynamixel.emulator --ids 1,2`` to serve a bus from its own process.
"""

from __future__ import annotations

import argparse
import collections
import math
import sys
import threading
from collections.abc import Callable, Iterable

import numpy as np

from palpate.core.errors import ValidationError
from palpate.hardware.clock import Clock, as_clock
from palpate.hardware.dynamixel import control_table as ct
from palpate.hardware.dynamixel.protocol import (
    BROADCAST_ID,
    ERR_ACCESS,
    ERR_DATA_LENGTH,
    ERR_DATA_LIMIT,
    ERR_INSTRUCTION,
    ERR_RESULT_FAIL,
    ERRBIT_ALERT,
    INST_PING,
    INST_READ,
    INST_REBOOT,
    INST_SYNC_READ,
    INST_SYNC_WRITE,
    INST_WRITE,
    Packet,
    PacketParser,
    encode,
    status_packet,
)
from palpate.hardware.pty_device import PtyDevice

LoadModel = Callable[[np.ndarray], np.ndarray]
Observer = Callable[[float, np.ndarray], None]

# Integration step of the servo dynamics; lazily integrated up to "now" before every answer.
_MAX_SUBSTEP = 0.002
_MAX_SUBSTEPS = 50
# Instructions that observe the servos: the dynamics are brought up to the present before they are answered.
_READS = (INST_PING, INST_READ, INST_SYNC_READ)
# Registers the host may not write (read-only in the X-series table).
_READ_ONLY = [ct.MODEL_NUMBER, ct.FIRMWARE_VERSION, ct.HARDWARE_ERROR_STATUS, ct.MOVING, ct.PRESENT_CURRENT,
              ct.PRESENT_VELOCITY, ct.PRESENT_POSITION, ct.PRESENT_INPUT_VOLTAGE, ct.PRESENT_TEMPERATURE]


def _baud_code(baud: int) -> int:
    for code, bps in ct.BAUD_CODES.items():
        if bps == baud:
            return code
    rates = sorted(ct.BAUD_CODES.values())
    raise ValidationError(f"emulator baud {baud} is not an X-series rate; expected one of {rates}")


class ServoBusEmulator(PtyDevice):
    """Emulated Protocol 2.0 servos behind a pty; use as a context manager or call start()/stop().

    Args:
        ids: servo ids on the bus (0..252, unique).
        model_number: model each servo reports (1020 = XM430-W350).
        baud: bit rate the servos listen at; a host whose port is set to another standard rate gets no answer,
            as on a real bus.
        load_model: external torque on each servo shaft (N*m) as a function of the shaft angles (rad, 0 at
            the centre tick), both in ``ids`` order. None means no load.
        initial_ticks: present positions at start (ticks, default the centre 2048).
        clock: time source (:mod:`palpate.hardware.clock`; the wall clock by default). The servo dynamics are
            integrated up to ``clock()`` whenever a servo is read (ping, read, sync read, or :meth:`register` /
            :meth:`positions`). On the wall clock a write is applied at the time it arrives; on a virtual clock
            (:class:`~palpate.hardware.clock.StepClock`) it takes effect from the last read, so the emulated motion
            depends only on the host's packets and the clock's values, never on when this thread got to run.
        observer: called as ``observer(t, angles)`` after every integration substep with the time (s, on
            ``clock``) and the shaft angles reached (rad, 0 at the centre tick, ``ids`` order), so a physics
            backend can record what the servos actually did (the load model also sees trial positions).
    """

    def __init__(
        self,
        ids: Iterable[int] = (1, 2),
        model_number: int = 1020,
        baud: int = 1_000_000,
        load_model: LoadModel | None = None,
        initial_ticks: Iterable[float] | None = None,
        clock: Clock | Callable[[], float] | None = None,
        observer: Observer | None = None,
    ):
        self.ids = [int(i) for i in ids]
        if not self.ids or len(set(self.ids)) != len(self.ids) or not all(0 <= i <= 252 for i in self.ids):
            raise ValidationError(f"emulator ids must be unique integers in 0..252, got {self.ids}")
        if model_number not in ct.MODELS:
            raise ValidationError(f"emulator model number {model_number} unknown; known: {sorted(ct.MODELS)}")
        self.model = ct.MODELS[model_number]
        PtyDevice.__init__(self, int(baud), f"dxl-emulator ids {self.ids}", clock=as_clock(clock))
        self.load_model = load_model
        self.observer = observer
        self._index = {sid: k for k, sid in enumerate(self.ids)}
        n = len(self.ids)
        self.memory = np.zeros((n, ct.TABLE_SIZE), dtype=np.uint8)
        ticks = np.full(n, float(ct.CENTER_TICK)) if initial_ticks is None else np.asarray(
            list(initial_ticks), dtype=float)
        if ticks.shape != (n,) or not np.all(np.isfinite(ticks)):
            raise ValidationError(f"initial_ticks must be {n} finite tick values, got {initial_ticks!r}")
        self._pos = ticks.copy()
        for k, sid in enumerate(self.ids):
            self._init_table(k, sid)
        self._last = self.clock()
        self._lock = threading.RLock()
        self._parser = PacketParser()
        # Observability for tests: instruction counts and a bounded log of applied writes (id, address, bytes).
        self.instruction_counts: collections.Counter[int] = collections.Counter()
        self.writes: collections.deque[tuple[int, int, bytes]] = collections.deque(maxlen=100_000)
        # Called as on_write(servo id, address, bytes) after every applied write (e.g. to log torque changes).
        self.on_write: Callable[[int, int, bytes], None] | None = None
        # Fault injection
        self.silent: set[int] = set()
        self._corrupt_next = 0

    # ---- control table -------------------------------------------------------------------------------------
    def _init_table(self, k: int, sid: int) -> None:
        self._set(k, ct.MODEL_NUMBER, self.model.number)
        self._set(k, ct.FIRMWARE_VERSION, 48)
        self._set(k, ct.ID, sid)
        self._set(k, ct.BAUD_RATE, _baud_code(self.baud))
        self._set(k, ct.RETURN_DELAY_TIME, 0)
        self._set(k, ct.OPERATING_MODE, ct.MODE_POSITION)
        self._set(k, ct.CURRENT_LIMIT, self.model.current_limit_max)
        self._set(k, ct.VELOCITY_LIMIT, int(self.model.no_load_speed / ct.VELOCITY_UNIT))
        self._set(k, ct.MAX_POSITION_LIMIT, ct.TICKS_PER_REV - 1)
        self._set(k, ct.MIN_POSITION_LIMIT, 0)
        self._set(k, ct.STATUS_RETURN_LEVEL, 2)
        self._set(k, ct.GOAL_CURRENT, self.model.current_limit_max)
        self._set(k, ct.GOAL_POSITION, int(round(self._pos[k])))
        self._set(k, ct.PRESENT_POSITION, int(round(self._pos[k])))
        self._set(k, ct.PRESENT_INPUT_VOLTAGE, 120)
        self._set(k, ct.PRESENT_TEMPERATURE, 30)

    def _get(self, k: int, reg: tuple[int, int], signed: bool = False) -> int:
        addr, size = reg
        return int.from_bytes(self.memory[k, addr: addr + size].tobytes(), "little", signed=signed)

    def _set(self, k: int, reg: tuple[int, int], value: int) -> None:
        addr, size = reg
        value = int(value)
        self.memory[k, addr: addr + size] = np.frombuffer(
            value.to_bytes(size, "little", signed=value < 0), dtype=np.uint8)

    def register(self, servo_id: int, reg: tuple[int, int], signed: bool = False) -> int:
        """Value of a control-table register of one servo (for inspection; not over the wire)."""
        with self._lock:
            self._advance(self.clock())
            return self._get(self._index[servo_id], reg, signed)

    def set_register(self, servo_id: int, reg: tuple[int, int], value: int) -> None:
        """Set a register directly, bypassing the wire (to prepare a scenario in a test)."""
        with self._lock:
            k = self._index[servo_id]
            self._set(k, reg, value)
            if reg == ct.PRESENT_POSITION:
                self._pos[k] = float(value)

    @property
    def integrated_until(self) -> float:
        """The clock time up to which the servo dynamics have been integrated, s."""
        return self._last

    def last_positions(self) -> np.ndarray:
        """Positions at :attr:`integrated_until`, ticks (nothing is integrated: the motion stays the host's)."""
        with self._lock:
            return self._pos.copy()

    def positions(self) -> np.ndarray:
        """Present positions of every servo, ticks (float, in ``ids`` order)."""
        with self._lock:
            self._advance(self.clock())
            return self._pos.copy()

    # ---- faults --------------------------------------------------------------------------------------------
    def silence(self, servo_id: int, silent: bool = True) -> None:
        """Make a servo stop answering (a cut cable, a brown-out) or answer again."""
        if servo_id not in self._index:
            raise ValidationError(f"no servo {servo_id} on this emulated bus (ids {self.ids})")
        with self._lock:
            (self.silent.add if silent else self.silent.discard)(servo_id)

    def corrupt_next_status(self, count: int = 1) -> None:
        """Flip a CRC bit in the next ``count`` status packets sent."""
        with self._lock:
            self._corrupt_next += int(count)

    def set_hardware_error(self, servo_id: int, bits: int = 0x20) -> None:
        """Raise a hardware error (default 0x20, overload): torque drops and every status carries the alert bit."""
        with self._lock:
            k = self._index[servo_id]
            self._set(k, ct.HARDWARE_ERROR_STATUS, bits)
            self._set(k, ct.TORQUE_ENABLE, 0)

    # ---- dynamics ------------------------------------------------------------------------------------------
    def _column(self, reg: tuple[int, int], signed: bool = False) -> np.ndarray:
        addr, size = reg
        raw = np.ascontiguousarray(self.memory[:, addr: addr + size])
        dtype = {1: "u1", 2: "<i2" if signed else "<u2", 4: "<i4" if signed else "<u4"}[size]
        return raw.view(dtype).reshape(-1).astype(float)

    def _advance(self, now: float) -> None:
        total = now - self._last
        if total <= 0:
            return
        t_start = self._last
        self._last = now
        torque = self._column(ct.TORQUE_ENABLE) == 1
        mode = self._column(ct.OPERATING_MODE)
        enabled = torque & np.isin(mode, (ct.MODE_POSITION, ct.MODE_EXTENDED_POSITION, ct.MODE_CURRENT_POSITION))
        goal = self._column(ct.GOAL_POSITION, signed=True)
        profile = self._column(ct.PROFILE_VELOCITY)
        vmax = np.where(profile > 0, profile * ct.VELOCITY_UNIT, self.model.no_load_speed)
        vmax_ticks = vmax * ct.TICKS_PER_REV / (2 * math.pi)
        unit = self.model.current_unit
        limit = self._column(ct.CURRENT_LIMIT) * unit
        limit = np.where(mode == ct.MODE_CURRENT_POSITION, np.minimum(limit, self._column(ct.GOAL_CURRENT) * unit),
                         limit)
        kt = self.model.torque_constant
        # servos at rest under a position-only load need one evaluation, not one per substep
        moving = np.any(enabled & (np.abs(goal - self._pos) > 1e-9))
        n_sub = min(max(1, math.ceil(total / _MAX_SUBSTEP)), _MAX_SUBSTEPS) if moving else 1
        dt = total / n_sub
        pos = self._pos
        current = np.zeros_like(pos)
        start = pos.copy()
        for i_sub in range(n_sub):
            step = np.clip(goal - pos, -vmax_ticks * dt, vmax_ticks * dt) * enabled
            needed = self._holding_current(pos + step, kt)
            stalled = enabled & (np.abs(needed) > limit)
            if np.any(stalled):
                # a stalled servo still moves as far into the step as its current allows: bisect the fraction
                lo_f, hi_f = np.zeros_like(pos), np.ones_like(pos)
                for _ in range(12):
                    mid = 0.5 * (lo_f + hi_f)
                    frac = np.where(stalled, mid, 1.0)
                    ok = np.abs(self._holding_current(pos + frac * step, kt)) <= limit
                    lo_f, hi_f = np.where(ok, mid, lo_f), np.where(ok, hi_f, mid)
                step = np.where(stalled, lo_f, 1.0) * step
                needed = self._holding_current(pos + step, kt)
            pos = pos + step
            current = np.where(enabled, np.where(stalled, np.sign(needed) * limit, needed), 0.0)
            if self.observer is not None:
                self.observer(t_start + (i_sub + 1) * dt, (pos - ct.CENTER_TICK) * (2 * math.pi / ct.TICKS_PER_REV))
        self._pos = pos
        velocity = (pos - start) / total / ct.TICKS_PER_REV * 2 * math.pi / ct.VELOCITY_UNIT
        for k in range(len(pos)):
            self._set(k, ct.PRESENT_POSITION, int(round(pos[k])))
            self._set(k, ct.PRESENT_VELOCITY, int(round(velocity[k])))
            self._set(k, ct.PRESENT_CURRENT, int(np.clip(round(current[k] / unit), -32768, 32767)))
            self._set(k, ct.MOVING, int(abs(goal[k] - pos[k]) > 1 and enabled[k]))

    def _holding_current(self, ticks: np.ndarray, kt: float) -> np.ndarray:
        # the motor holds the external load: current opposing the torque, A
        if self.load_model is None:
            return np.zeros_like(ticks)
        angles = (ticks - ct.CENTER_TICK) * (2 * math.pi / ct.TICKS_PER_REV)
        load = np.asarray(self.load_model(angles), dtype=float).reshape(-1)
        if load.shape != ticks.shape or not np.all(np.isfinite(load)):
            raise ValidationError(f"emulator load_model must return {len(ticks)} finite torques (N*m), got {load!r}")
        return -load / kt

    # ---- instructions --------------------------------------------------------------------------------------
    def _status(self, k: int, error: int = 0, data: bytes = b"") -> bytes:
        if self._get(k, ct.HARDWARE_ERROR_STATUS):
            error |= ERRBIT_ALERT
        raw = bytearray(encode(status_packet(self.ids[k], error, data)))
        if self._corrupt_next > 0:
            self._corrupt_next -= 1
            raw[-1] ^= 0x5A
        return bytes(raw)

    def _write(self, k: int, addr: int, data: bytes) -> int:
        """Apply a write to servo k; return the error number (0 if applied)."""
        end = addr + len(data)
        if not data or end > ct.TABLE_SIZE:
            return ERR_DATA_LENGTH
        for raddr, rsize in _READ_ONLY:
            if addr < raddr + rsize and raddr < end:
                return ERR_ACCESS
        torque_on = self._get(k, ct.TORQUE_ENABLE) == 1
        if addr < ct.EEPROM_END and torque_on:
            return ERR_ACCESS
        trial = self.memory[k].copy()
        trial[addr:end] = np.frombuffer(bytes(data), dtype=np.uint8)
        g_addr, g_size = ct.GOAL_POSITION
        if addr < g_addr + g_size and g_addr < end:
            goal = int.from_bytes(trial[g_addr: g_addr + g_size].tobytes(), "little", signed=True)
            lo = self._get(k, ct.MIN_POSITION_LIMIT, signed=True)
            hi = self._get(k, ct.MAX_POSITION_LIMIT, signed=True)
            if not lo <= goal <= hi:
                return ERR_DATA_LIMIT
        t_addr = ct.TORQUE_ENABLE[0]
        if addr <= t_addr < end and trial[t_addr] == 1 and self._get(k, ct.HARDWARE_ERROR_STATUS):
            return ERR_RESULT_FAIL
        self.memory[k] = trial
        self.writes.append((self.ids[k], addr, bytes(data)))
        if self.on_write is not None:
            self.on_write(self.ids[k], addr, bytes(data))
        return 0

    def handle(self, packet: Packet) -> bytes:
        """Answer one instruction packet; returns the bytes the bus sends back (possibly none)."""
        with self._lock:
            pid, inst, p = packet.id, packet.instruction, packet.params
            if inst in _READS or not self.clock.virtual:
                self._advance(self.clock())
            self.instruction_counts[packet.instruction] += 1
            alive = [k for k, sid in enumerate(self.ids) if sid not in self.silent]
            if pid == BROADCAST_ID:
                targets = alive
            elif pid in self._index and pid not in self.silent:
                targets = [self._index[pid]]
            else:
                targets = []
            out = bytearray()
            if inst == INST_PING:
                for k in targets:
                    out += self._status(k, 0, bytes(self.memory[k, 0:2]) + bytes(self.memory[k, 6:7]))
            elif inst == INST_READ:
                if pid == BROADCAST_ID:
                    return b""
                for k in targets:
                    if len(p) != 4:
                        out += self._status(k, ERR_DATA_LENGTH)
                        continue
                    addr, length = p[0] | p[1] << 8, p[2] | p[3] << 8
                    if addr + length > ct.TABLE_SIZE or length == 0:
                        out += self._status(k, ERR_DATA_LENGTH)
                    else:
                        out += self._status(k, 0, self.memory[k, addr: addr + length].tobytes())
            elif inst == INST_WRITE:
                for k in targets:
                    err = ERR_DATA_LENGTH if len(p) < 3 else self._write(k, p[0] | p[1] << 8, p[2:])
                    if pid != BROADCAST_ID:
                        out += self._status(k, err)
            elif inst == INST_SYNC_READ:
                if len(p) < 5:
                    return b""
                addr, length = p[0] | p[1] << 8, p[2] | p[3] << 8
                for sid in p[4:]:
                    k = self._index.get(sid)
                    if k is None or sid in self.silent:
                        continue
                    if addr + length > ct.TABLE_SIZE or length == 0:
                        out += self._status(k, ERR_DATA_LENGTH)
                    else:
                        out += self._status(k, 0, self.memory[k, addr: addr + length].tobytes())
            elif inst == INST_SYNC_WRITE:
                if len(p) < 4:
                    return b""
                addr, length = p[0] | p[1] << 8, p[2] | p[3] << 8
                block = 1 + length
                body = p[4:]
                for j in range(0, len(body) - block + 1, block):
                    k = self._index.get(body[j])
                    if k is not None and body[j] not in self.silent:
                        self._write(k, addr, body[j + 1: j + block])
            elif inst == INST_REBOOT:
                for k in targets:
                    self._set(k, ct.HARDWARE_ERROR_STATUS, 0)
                    self._set(k, ct.TORQUE_ENABLE, 0)
                    if pid != BROADCAST_ID:
                        out += self._status(k, 0)
            else:
                if pid != BROADCAST_ID:
                    for k in targets:
                        out += self._status(k, ERR_INSTRUCTION)
            return bytes(out)

    # ---- bytes from the pty ----------------------------------------------------------------------------
    def on_start(self) -> None:
        """The servo dynamics integrate from the moment the bus is served."""
        self._last = self.clock()

    def respond(self, data: bytes) -> bytes:
        """Answer the bytes the host wrote: the status packets of every complete instruction packet in them."""
        out = bytearray()
        for packet in self._parser.feed(data):
            out += self.handle(packet)
        return bytes(out)


def main(argv: list[str] | None = None) -> int:
    """Serve an emulated bus from this process until interrupted; prints the port path on stdout."""
    parser = argparse.ArgumentParser(description="Protocol 2.0 servo bus emulator on a pty")
    parser.add_argument("--ids", default="1,2", help="comma-separated servo ids")
    parser.add_argument("--baud", type=int, default=1_000_000)
    parser.add_argument("--model", type=int, default=1020, help="model number (1020 = XM430-W350)")
    parser.add_argument("--log-torque", action="store_true",
                        help="print 'torque ID VALUE' on stdout whenever a servo's torque enable is written")
    args = parser.parse_args(argv)
    try:
        ids = [int(s) for s in args.ids.split(",") if s.strip()]
    except ValueError:
        print(f"--ids must be comma-separated integers, got {args.ids!r}", file=sys.stderr)
        return 2
    emu = ServoBusEmulator(ids, model_number=args.model, baud=args.baud)
    if args.log_torque:
        t_addr = ct.TORQUE_ENABLE[0]

        def log(sid: int, addr: int, data: bytes) -> None:
            if addr <= t_addr < addr + len(data):
                print(f"torque {sid} {data[t_addr - addr]}", flush=True)

        emu.on_write = log
    emu.serve_until_interrupted()
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
