"""Drive a Dynamixel finger through the official dynamixel-sdk (Protocol 2.0).

Safety first: every command is checked against the joint limits (and the configured current limit against
the servo model) before a byte is written; torque is switched off on any exception, on Ctrl-C, on SIGTERM and
SIGHUP (while a finger is open they raise :class:`~palpate.hardware.exit_signals.Terminated`, see
:mod:`palpate.hardware.exit_signals`), on exit of the context manager and at interpreter exit. A servo that
stops answering ends what was running with a DeviceError naming its id, after torque has been switched off on the
servos that still answer.
"""

from __future__ import annotations

import atexit
import math
from collections.abc import Callable, Iterable

import numpy as np

from palpate.core.errors import DeviceError, ValidationError
from palpate.hardware import exit_signals
from palpate.hardware.clock import Clock, as_clock
from palpate.hardware.dynamixel import control_table as ct
from palpate.hardware.dynamixel.finger import (
    FingerDescription,
    check_joint_limits,
    fingertip_pose,
    joints_to_ticks,
    ticks_to_joints,
)
from palpate.hardware.dynamixel.joint_state import JointState, LostServo
from palpate.hardware.dynamixel.press import press_and_release

_STATE_START = ct.PRESENT_CURRENT[0]  # one sync read covers current (2), velocity (4), position (4)
_STATE_LENGTH = 10
# 200 Hz, a usual servo control rate over USB (the adapter's latency, not the 1 Mbaud bus, bounds a cycle); the press
# loop moves its goal at most press.MAX_STEP_TIME of motion per cycle, the same 5 ms.
DEFAULT_CYCLE = 0.005
SERIAL_POLL = 0.001  # s
# Confirmed writes of torque off tried per servo (each with its retries) before giving up on it.
TORQUE_OFF_TRIES = 5
BROADCAST_ID = 0xFE
# How long dynamixel-sdk waits for an answer on a virtual clock, ms of wall time. On the wall clock it waits what the
# bus needs (~34 ms at 1 Mbaud); an emulator whose thread a loaded machine leaves unscheduled for longer is not a
# lost servo, and waiting costs the emulated servos no time. A servo silenced on purpose is still declared lost,
# after retries + 1 such waits.
VIRTUAL_ANSWER_TIMEOUT_MS = 1000.0


def _comm_text(packet_handler, result: int) -> str:
    return packet_handler.getTxRxResult(result).replace("[TxRxResult] ", "")


class DynamixelFinger:
    """A finger of X-series servos on one bus.

    Args:
        port: serial device (e.g. /dev/ttyUSB0, or an emulator's pty).
        baud: bus bit rate (one the SDK supports, e.g. 57600, 1000000).
        finger: its description (ids, limits, current limit).
        retries: times a corrupt or missing status is retried before giving up.
        clock: time source (see :mod:`palpate.hardware.clock`; default the wall clock). Give the emulator and the
            driver one :class:`~palpate.hardware.clock.StepClock` and the emulated finger moves exactly one
            ``cycle`` per state read, however loaded the machine is.
        cycle: shortest control cycle, s: :meth:`read_state` sleeps out the rest of the cycle on ``clock`` (a real
            bus usually takes about this long anyway; on a stepped clock this is what moves time on).
        answer_timeout: how long to wait for a servo's answer, s (None: dynamixel-sdk's, ~34 ms at 1 Mbaud with a
            16 ms USB latency timer). Longer for a slow adapter, or a bus served by another process on a loaded
            machine; a silent servo then takes (retries + 1) x this to be declared lost.

    Use as a context manager: ``with DynamixelFinger(port, 1_000_000, finger) as f: f.press(...)``.
    """

    def __init__(self, port: str, baud: int, finger: FingerDescription, *, retries: int = 3,
                 clock: Clock | Callable[[], float] | None = None, cycle: float = DEFAULT_CYCLE,
                 answer_timeout: float | None = None):
        if not (math.isfinite(cycle) and 0 < cycle <= 0.1):
            raise ValidationError(f"control cycle must be in (0, 0.1] s, got {cycle!r}")
        if answer_timeout is not None and not (math.isfinite(answer_timeout) and 0 < answer_timeout <= 10):
            raise ValidationError(f"answer timeout must be in (0, 10] s, got {answer_timeout!r}")
        self.answer_timeout = answer_timeout
        self.port_name = str(port)
        self.baud = int(baud)
        self.finger = finger
        self.clock = as_clock(clock)
        self.retries = int(retries)
        self.cycle = float(cycle)
        self._next_cycle: float | None = None
        self.model = finger.model
        self._port = None
        self._ph = None
        self._sync_read = None
        self._sync_write = None
        self._sdk = None
        self._torque_on = False
        self._signals_held = False
        self.lost: set[int] = set()
        # Answers retried because they were corrupt (bad CRC) or late (an emulator on a loaded machine, noise).
        self.corrupt_retries = 0
        self.timeout_retries = 0

    # ---- lifetime ------------------------------------------------------------------------------------------
    def open(self) -> DynamixelFinger:
        """Open the port, find every servo, check its model, configure limits with torque off."""
        import dynamixel_sdk as sdk  # optional dependency: only needed when a finger is driven

        self._sdk = sdk
        limit_units = self.finger.current_limit / self.model.current_unit
        if not 0 < limit_units <= self.model.current_limit_max:
            raise ValidationError(f"finger {self.finger.name!r}: current limit {self.finger.current_limit} A is "
                                  f"outside what a {self.model.name} accepts")
        if self._port is not None:
            return self
        port = sdk.PortHandler(self.port_name)
        try:
            opened = port.openPort()
        except Exception as exc:  # pyserial raises SerialException (an OSError subclass on some versions)
            raise DeviceError(f"cannot open Dynamixel port {self.port_name!r}: {exc}") from None
        if not opened:
            raise DeviceError(f"cannot open Dynamixel port {self.port_name!r}")
        if not port.setBaudRate(self.baud):
            port.closePort()
            raise DeviceError(f"baud {self.baud} is not supported by dynamixel-sdk on {self.port_name!r}")
        self._port, self._ph = port, sdk.PacketHandler(2.0)
        # dynamixel-sdk polls its port with reads that return at once, a busy loop holding the interpreter: an
        # emulator thread in this process then waits for a turn (seen: a second on a loaded machine), and a real bus
        # burns a core. Reads that wait up to 1 ms for the bytes asked for release it meanwhile.
        port.ser.timeout = SERIAL_POLL
        if self.clock.virtual or self.answer_timeout is not None:
            wait_ms = VIRTUAL_ANSWER_TIMEOUT_MS if self.answer_timeout is None else 1000.0 * self.answer_timeout
            port.setPacketTimeout = lambda _length: port.setPacketTimeoutMillis(wait_ms)
        try:
            self._find_servos()
            self._configure()
        except BaseException:
            self._close_port()
            raise
        self._sync_read = sdk.GroupSyncRead(port, self._ph, _STATE_START, _STATE_LENGTH)
        self._sync_write = sdk.GroupSyncWrite(port, self._ph, ct.GOAL_POSITION[0], ct.GOAL_POSITION[1])
        for sid in self.finger.ids:
            self._sync_read.addParam(sid)
        atexit.register(self.close)
        self._signals_held = exit_signals.hold()
        return self

    def _find_servos(self) -> None:
        missing, garbled, wrong = [], [], []
        for sid in self.finger.ids:
            number, corrupt = self._ping(sid)
            if number is None:
                (garbled if corrupt else missing).append(sid)
            elif number != self.model.number:
                wrong.append(f"id {sid} is a {ct.model_name(number)}")
        if garbled:
            # something answered, so port and baud rate are right: the packets are damaged on the way
            raise DeviceError(f"servo id(s) {garbled} on {self.port_name!r} answered only with corrupt packets (bad "
                              f"CRC) in {self.retries + 1} tries each; check the cable, its connectors and "
                              "termination, the supply voltage, and for another device talking on the bus")
        if len(missing) == len(self.finger.ids):
            raise DeviceError(f"no servo answered on {self.port_name!r} at {self.baud} baud (ids {self.finger.ids}); "
                              "check the port, the baud rate and the servo power")
        if missing:
            raise LostServo(f"servo id(s) {missing} did not answer on {self.port_name!r}", missing[0])
        if wrong:
            raise DeviceError(f"finger {self.finger.name!r} expects {self.model.name} servos but {', '.join(wrong)}")

    def _ping(self, sid: int) -> tuple[int | None, bool]:
        """(model number or None, whether any answer came back corrupt)."""
        corrupt = False
        for _ in range(self.retries + 1):
            number, result, _ = self._ph.ping(self._port, sid)
            if result == self._sdk.COMM_SUCCESS:
                return int(number), corrupt
            corrupt |= result == self._sdk.COMM_RX_CORRUPT
            if not self._retryable(result):
                break
        return None, corrupt

    def _configure(self) -> None:
        # every value is checked above or at load time; EEPROM writes need torque off
        limit_units = int(round(self.finger.current_limit / self.model.current_unit))
        lo_t = joints_to_ticks(self.finger, self.finger.lower)
        hi_t = joints_to_ticks(self.finger, self.finger.upper)
        for k, sid in enumerate(self.finger.ids):
            self._write(sid, ct.TORQUE_ENABLE, 0)
            self._write(sid, ct.OPERATING_MODE, ct.MODE_CURRENT_POSITION)
            self._write(sid, ct.CURRENT_LIMIT, limit_units)
            self._write(sid, ct.MIN_POSITION_LIMIT, int(min(lo_t[k], hi_t[k])))
            self._write(sid, ct.MAX_POSITION_LIMIT, int(max(lo_t[k], hi_t[k])))
            self._write(sid, ct.GOAL_CURRENT, limit_units)

    def close(self) -> None:
        """Switch torque off (best effort) and close the port. Safe to call twice."""
        atexit.unregister(self.close)
        if self._port is None:
            return
        try:
            self.disable_torque()
        finally:
            self._close_port()
            if self._signals_held:
                self._signals_held = False
                exit_signals.release()

    def _close_port(self) -> None:
        try:
            self._port.closePort()
        except Exception:
            pass
        self._port = None

    def __enter__(self) -> DynamixelFinger:
        return self.open()

    def __exit__(self, *exc) -> None:
        self.close()

    # ---- register access -----------------------------------------------------------------------------------
    def _require_open(self) -> None:
        if self._port is None:
            raise DeviceError(f"Dynamixel finger on {self.port_name!r} is not open; call open() or use 'with'")

    def _retryable(self, result: int) -> bool:
        # a corrupt or missing answer is tried again (and counted); a servo is declared lost only when every
        # attempt times out, so one late packet does not stop a press
        if result == self._sdk.COMM_RX_CORRUPT:
            self.corrupt_retries += 1
            return True
        if result == self._sdk.COMM_RX_TIMEOUT:
            self.timeout_retries += 1
            return True
        return False

    def _write(self, sid: int, reg: tuple[int, int], value: int) -> None:
        """Write one register and check the status; DeviceError naming the servo otherwise."""
        addr, size = reg
        fn = {1: self._ph.write1ByteTxRx, 2: self._ph.write2ByteTxRx, 4: self._ph.write4ByteTxRx}[size]
        value = int(value) & ((1 << (8 * size)) - 1)
        for _ in range(self.retries + 1):
            result, error = fn(self._port, sid, addr, value)
            if not self._retryable(result):
                break
        if result == self._sdk.COMM_RX_TIMEOUT:
            self.lost.add(sid)
            raise LostServo(f"servo {sid} did not answer a write to address {addr} on {self.port_name!r}", sid)
        if result != self._sdk.COMM_SUCCESS:
            raise DeviceError(f"servo {sid}: write to address {addr} failed: {_comm_text(self._ph, result)}")
        if error:
            raise DeviceError(f"servo {sid}: write of {value} to address {addr} refused: "
                              f"{self._ph.getRxPacketError(error).replace('[RxPacketError] ', '')}")

    def read_register(self, sid: int, reg: tuple[int, int]) -> int:
        """Read one register of one servo (unsigned)."""
        self._require_open()
        addr, size = reg
        for _ in range(self.retries + 1):
            data, result, error = self._ph.readTxRx(self._port, sid, addr, size)
            if not self._retryable(result):
                break
        if result != self._sdk.COMM_SUCCESS:
            raise DeviceError(f"servo {sid}: read of address {addr} failed: {_comm_text(self._ph, result)}")
        return int.from_bytes(bytes(data[:size]), "little")

    # ---- torque --------------------------------------------------------------------------------------------
    def enable_torque(self) -> None:
        """Hold the current positions, then switch torque on (all servos or none)."""
        self._require_open()
        with self.safety():
            state = self.read_state()
            self._send_goal(joints_to_ticks(self.finger, state.position))
            for sid in self.finger.ids:
                self._write(sid, ct.TORQUE_ENABLE, 1)
            self._torque_on = True

    def disable_torque(self) -> list[int]:
        """Switch torque off on every servo that answers; returns the ids that confirmed. Never raises."""
        if self._port is None:
            return []
        done = []
        self._port.is_using = False  # an exception may have left a transfer half done
        try:
            # first to every servo at once (a broadcast needs no answer: it works even when answers are lost) ...
            self._ph.write1ByteTxOnly(self._port, BROADCAST_ID, ct.TORQUE_ENABLE[0], 0)
            self._port.is_using = False
        except Exception:
            pass
        # ... then servo by servo, until each confirms or TORQUE_OFF_TRIES are spent
        for sid in self.finger.ids:
            if sid in self.lost:
                continue
            for _ in range(TORQUE_OFF_TRIES):
                try:
                    self._write(sid, ct.TORQUE_ENABLE, 0)
                    done.append(sid)
                    break
                except Exception:
                    self._port.is_using = False
        self._torque_on = False
        return done

    class _Safety:
        def __init__(self, owner: DynamixelFinger):
            self.owner = owner

        def __enter__(self):
            return self.owner

        def __exit__(self, exc_type, exc, tb):
            if exc_type is None:
                return False
            off = self.owner.disable_torque()
            if getattr(exc, "_torque_handled", False):  # an inner safety context already reported it
                return False
            try:
                exc._torque_handled = True
            except AttributeError:
                pass
            if isinstance(exc, LostServo):
                others = ", ".join(map(str, off)) or "none"
                err = LostServo(f"{exc}; stopped and switched torque off on servo(s) {others}", exc.servo_id)
                err._torque_handled = True
                raise err from None
            return False

    def safety(self) -> DynamixelFinger._Safety:
        """Context in which any exception (Ctrl-C included) switches torque off before propagating."""
        return DynamixelFinger._Safety(self)

    # ---- streaming -----------------------------------------------------------------------------------------
    def read_state(self) -> JointState:
        """One sync read of present current, velocity and position of every joint.

        Corrupt or late answers are retried; a servo that never answers raises LostServo naming it; a hardware
        alert raises DeviceError with the servo's hardware error status.
        """
        self._require_open()
        self._pace()
        sdk, ph, port = self._sdk, self._ph, self._port
        ids = self.finger.ids
        raw = np.zeros((len(ids), _STATE_LENGTH), dtype=np.uint8)
        failure = None
        t = self.clock()
        for _ in range(self.retries + 1):
            result = self._sync_read.txPacket()
            if result != sdk.COMM_SUCCESS:
                raise DeviceError(f"sync read on {self.port_name!r} could not be sent: {_comm_text(ph, result)}")
            failure = None
            alerts = []
            for k, sid in enumerate(ids):
                # per-id receive (what GroupSyncRead.rxPacket does) so the lost id and error bytes are known
                data, result, error = ph.readRx(port, sid, _STATE_LENGTH)
                if result != sdk.COMM_SUCCESS:
                    port.is_using = False
                    failure = (sid, result)
                    self._retryable(result)
                    break
                if error & 0x80:
                    alerts.append(sid)
                raw[k] = data[:_STATE_LENGTH]
            if failure is None:
                break
        if failure is not None:
            sid, result = failure
            if result == sdk.COMM_RX_TIMEOUT:
                self.lost.add(sid)
                raise LostServo(f"servo {sid} ({self._joint_name(sid)}) stopped answering on {self.port_name!r} "
                                f"({self.retries + 1} sync reads without its status)", sid)
            raise DeviceError(f"sync read on {self.port_name!r}: servo {sid} gave {self.retries + 1} bad answers in "
                              f"a row ({_comm_text(ph, result)}); check the cable and the baud rate")
        if alerts:
            status = {s: self.read_register(s, ct.HARDWARE_ERROR_STATUS) for s in alerts}
            detail = ", ".join(f"servo {s}: hardware error status 0x{v:02x}" for s, v in status.items())
            raise DeviceError(f"hardware alert ({detail}); the servo switched its torque off, reboot it to clear")
        current = raw[:, 0:2].copy().view("<i2").reshape(-1).astype(float) * self.model.current_unit
        velocity = raw[:, 2:6].copy().view("<i4").reshape(-1).astype(float) * ct.VELOCITY_UNIT
        ticks = raw[:, 6:10].copy().view("<i4").reshape(-1).astype(float)
        d = self.finger.directions
        return JointState(t, ticks_to_joints(self.finger, ticks), d * velocity, d * current)

    def _pace(self) -> None:
        """Sleep out the rest of the control cycle, so states are read at most once per ``cycle`` s."""
        now = self.clock()
        if self._next_cycle is not None and now < self._next_cycle:
            self.clock.sleep(self._next_cycle - now)
            now = self.clock()
        self._next_cycle = now + self.cycle

    def _joint_name(self, sid: int) -> str:
        return next(j.name for j in self.finger.joints if j.servo_id == sid)

    def _send_goal(self, ticks: Iterable[int]) -> None:
        sw = self._sync_write
        sw.clearParam()
        for sid, tk in zip(self.finger.ids, ticks, strict=True):
            sw.addParam(sid, list(int(tk).to_bytes(4, "little", signed=True)))
        result = sw.txPacket()
        if result != self._sdk.COMM_SUCCESS:
            raise DeviceError(f"goal position sync write on {self.port_name!r} failed: {_comm_text(self._ph, result)}")

    def command_joints(self, q: np.ndarray) -> None:
        """Send goal joint angles (rad). Limits are checked first: out-of-range input writes nothing."""
        self._require_open()
        q = check_joint_limits(self.finger, q)
        if not self._torque_on:
            raise DeviceError(f"torque is off on {self.port_name!r}; call enable_torque() before commanding")
        with self.safety():
            self._send_goal(joints_to_ticks(self.finger, q))

    def joint_torques(self, state: JointState) -> np.ndarray:
        """Motor torques on the joints, N*m, from the present currents (torque constant of the model)."""
        return state.current * self.model.torque_constant

    def move_to(self, q: np.ndarray, tolerance: float = 0.01, timeout: float = 5.0,
                on_state: Callable[[JointState], None] | None = None) -> JointState:
        """Command ``q`` (rad) and stream states until every joint is within ``tolerance`` rad or ``timeout`` s."""
        self.command_joints(q)
        q = np.asarray(q, dtype=float)
        t0 = self.clock()
        with self.safety():
            while True:
                state = self.read_state()
                if on_state is not None:
                    on_state(state)
                if np.max(np.abs(state.position - q)) <= tolerance:
                    return state
                if state.t - t0 > timeout:
                    worst = int(np.argmax(np.abs(state.position - q)))
                    raise DeviceError(f"joint {self.finger.joints[worst].name!r} (servo {self.finger.ids[worst]}) did "
                                      f"not reach {q[worst]:.3f} rad within {timeout} s (at "
                                      f"{state.position[worst]:.3f} rad); blocked or current limit too low?")

    def pose(self, state: JointState):
        """Fingertip PoseSample for a joint state."""
        return fingertip_pose(self.finger, state.position, state.t)

    def press(self, target, surface_z: float, **kwargs):
        """Press and release at ``target`` (a PressTarget) on a surface at ``surface_z`` m; see press.py."""

        return press_and_release(self, target, surface_z, **kwargs)
