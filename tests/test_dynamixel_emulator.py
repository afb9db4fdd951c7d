"""The servo emulator's instruction handling and dynamics, driven by a hand-stepped clock (no pty, no timing)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from palpate.core.errors import ValidationError
from palpate.hardware.dynamixel import control_table as ct
from palpate.hardware.dynamixel.emulator import ServoBusEmulator
from palpate.hardware.dynamixel.protocol import (
    ERR_ACCESS,
    ERR_DATA_LIMIT,
    INST_READ,
    INST_SYNC_READ,
    INST_SYNC_WRITE,
    INST_WRITE,
    Packet,
    PacketParser,
)


class Clock:
    def __init__(self):
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


def _write(emu, sid, reg, value):
    addr, size = reg
    replies = PacketParser().feed(emu.handle(Packet(sid, INST_WRITE, bytes([addr, 0]) + value.to_bytes(size, "little",
                                                                                                      signed=True))))
    return replies[0].error


def test_position_tracking_is_rate_limited_at_the_no_load_speed():
    clock = Clock()
    emu = ServoBusEmulator([1], clock=clock)
    assert _write(emu, 1, ct.TORQUE_ENABLE, 1) == 0
    assert _write(emu, 1, ct.GOAL_POSITION, 3000) == 0
    clock.t = 0.1
    expected = 2048 + emu.model.no_load_speed * 0.1 * 4096 / (2 * math.pi)
    assert emu.positions()[0] == pytest.approx(expected, rel=1e-9)
    assert emu.register(1, ct.PRESENT_VELOCITY, signed=True) == round(emu.model.no_load_speed / ct.VELOCITY_UNIT)
    clock.t = 1.0
    assert emu.positions()[0] == 3000


def test_servo_stalls_where_the_load_needs_more_than_the_goal_current():
    clock = Clock()
    spring = 2.0  # N*m/rad pushing the shaft back to 0
    emu = ServoBusEmulator([1], load_model=lambda a: -spring * a, clock=clock)
    _write(emu, 1, ct.OPERATING_MODE, ct.MODE_CURRENT_POSITION)
    _write(emu, 1, ct.GOAL_CURRENT, 200)  # 200 * 2.69 mA = 0.538 A
    _write(emu, 1, ct.TORQUE_ENABLE, 1)
    _write(emu, 1, ct.GOAL_POSITION, 4000)
    clock.t = 2.0
    stall_angle = emu.model.torque_constant * 200 * emu.model.current_unit / spring
    angle = (emu.positions()[0] - 2048) * 2 * math.pi / 4096
    # stopped at the stall angle to within one encoder tick, never beyond it
    assert stall_angle - 2 * math.pi / 4096 <= angle <= stall_angle + math.pi / 4096
    assert emu.register(1, ct.PRESENT_CURRENT, signed=True) == 200  # saturated at the goal current


def test_present_current_balances_the_load():
    clock = Clock()
    emu = ServoBusEmulator([1, 2], load_model=lambda a: np.array([-0.1, 0.05]), clock=clock)
    for sid in (1, 2):
        _write(emu, sid, ct.TORQUE_ENABLE, 1)
    clock.t = 0.01
    kt, unit = emu.model.torque_constant, emu.model.current_unit
    assert emu.register(1, ct.PRESENT_CURRENT, signed=True) == round(0.1 / kt / unit)
    assert emu.register(2, ct.PRESENT_CURRENT, signed=True) == round(-0.05 / kt / unit)


def test_torque_gates_motion_and_eeprom_and_limits_gate_goals():
    clock = Clock()
    emu = ServoBusEmulator([1], clock=clock)
    _write(emu, 1, ct.GOAL_POSITION, 2500)
    clock.t = 1.0
    assert emu.positions()[0] == 2048  # torque off: the goal is stored but nothing moves
    _write(emu, 1, ct.MAX_POSITION_LIMIT, 3000)
    _write(emu, 1, ct.TORQUE_ENABLE, 1)
    assert _write(emu, 1, ct.OPERATING_MODE, 3) == ERR_ACCESS
    assert _write(emu, 1, ct.GOAL_POSITION, 3500) == ERR_DATA_LIMIT
    assert emu.register(1, ct.GOAL_POSITION) == 2500
    assert _write(emu, 1, ct.PRESENT_POSITION, 10) == ERR_ACCESS


def test_sync_write_and_sync_read_address_each_listed_servo():
    emu = ServoBusEmulator([1, 2, 3], clock=Clock())
    body = bytes([116, 0, 4, 0])
    for sid, val in ((3, 2100), (1, 2200)):
        body += bytes([sid]) + val.to_bytes(4, "little")
    assert emu.handle(Packet(0xFE, INST_SYNC_WRITE, body)) == b""  # no status for a broadcast
    assert emu.register(1, ct.GOAL_POSITION) == 2200 and emu.register(3, ct.GOAL_POSITION) == 2100
    assert emu.register(2, ct.GOAL_POSITION) == 2048
    emu.silence(2)
    replies = PacketParser().feed(emu.handle(Packet(0xFE, INST_SYNC_READ, bytes([116, 0, 4, 0, 3, 2, 1]))))
    assert [(r.id, int.from_bytes(r.data, "little")) for r in replies] == [(3, 2100), (1, 2200)]
    assert emu.handle(Packet(2, INST_READ, bytes([116, 0, 4, 0]))) == b""


def test_a_load_model_returning_nan_is_an_error():
    clock = Clock()
    emu = ServoBusEmulator([1], load_model=lambda a: np.array([np.nan]), clock=clock)
    clock.t = 0.01
    with pytest.raises(ValidationError, match="finite torques"):
        emu.positions()
