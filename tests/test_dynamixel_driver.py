"""The finger driver through dynamixel-sdk against the Protocol 2.0 servo emulator on a pty.

The emulator and the driver share a StepClock: the servos move one control cycle per state read, so every
outcome is set by the packets exchanged, not by how busy the machine is."""

from __future__ import annotations

import numpy as np
import pytest

from palpate.core.errors import DeviceError, ValidationError
from palpate.core.session.sources import PressTarget
from palpate.hardware.clock import StepClock
from palpate.hardware.dynamixel import control_table as ct
from palpate.hardware.dynamixel.driver import DynamixelFinger, LostServo
from palpate.hardware.dynamixel.emulator import ServoBusEmulator
from palpate.hardware.dynamixel.finger import (
    forward_kinematics,
    inverse_kinematics,
    joints_to_ticks,
    load_finger,
    surface_load_model,
)
from palpate.hardware.dynamixel.protocol import INST_SYNC_WRITE, INST_WRITE
from palpate.hardware.dynamixel.scan import scan

BAUD = 1_000_000
SURFACE_Z = 0.03
STIFFNESS = 2.0 / 0.003**1.5  # N/m^1.5: 2 N at 3 mm


@pytest.fixture(params=["planar2", "planar3"])
def finger(request, repo_dir):
    return load_finger(repo_dir / "models" / "fingers" / f"{request.param}.toml")


@pytest.fixture
def planar2(repo_dir):
    return load_finger(repo_dir / "models" / "fingers" / "planar2.toml")


def _bus(finger, x=0.07, load=True):
    q0 = inverse_kinematics(finger, x, SURFACE_Z + finger.approach_height)
    model = surface_load_model(finger, SURFACE_Z, STIFFNESS) if load else None
    return ServoBusEmulator(finger.ids, finger.model.number, BAUD, model, joints_to_ticks(finger, q0),
                            clock=StepClock())


def test_scan_finds_the_configured_ids():
    with ServoBusEmulator([1, 4, 9], baud=BAUD) as emu:
        found = scan(emu.port, BAUD, range(0, 11))
    assert [s["id"] for s in found] == [1, 4, 9]
    assert {s["model"] for s in found} == {"XM430-W350"}
    assert {s["model_number"] for s in found} == {1020}


def test_open_configures_limits_with_torque_off(planar2):
    with _bus(planar2) as emu, DynamixelFinger(emu.port, BAUD, planar2, clock=emu.clock):
        for k, sid in enumerate(planar2.ids):
            assert emu.register(sid, ct.OPERATING_MODE) == ct.MODE_CURRENT_POSITION
            assert emu.register(sid, ct.TORQUE_ENABLE) == 0
            assert emu.register(sid, ct.CURRENT_LIMIT) == round(planar2.current_limit / 2.69e-3)
            ticks = joints_to_ticks(planar2, [planar2.lower, planar2.upper][0])[k], joints_to_ticks(
                planar2, planar2.upper)[k]
            assert emu.register(sid, ct.MIN_POSITION_LIMIT) == min(ticks)
            assert emu.register(sid, ct.MAX_POSITION_LIMIT) == max(ticks)


def test_sync_read_returns_the_emulated_positions(finger):
    with _bus(finger, load=False) as emu, DynamixelFinger(emu.port, BAUD, finger, clock=emu.clock) as drv:
        ticks = np.array([2100, 2300, 2500][: len(finger.ids)])
        for sid, tk in zip(finger.ids, ticks, strict=True):
            emu.set_register(sid, ct.PRESENT_POSITION, int(tk))
        state = drv.read_state()
        np.testing.assert_allclose(state.position, finger.directions * (ticks - 2048) * 2 * np.pi / 4096
                                   + finger.offsets)
        np.testing.assert_array_equal(state.current, 0.0)


def test_sync_write_moves_the_emulated_servos(finger):
    with _bus(finger, load=False) as emu, DynamixelFinger(emu.port, BAUD, finger, clock=emu.clock) as drv:
        drv.enable_torque()
        q = inverse_kinematics(finger, 0.06, 0.05)
        state = drv.move_to(q, tolerance=2e-3, timeout=5.0)
        np.testing.assert_allclose(emu.positions(), joints_to_ticks(finger, q), atol=1.5)
        tip, _ = forward_kinematics(finger, state.position)
        np.testing.assert_allclose(tip[[0, 2]], [0.06, 0.05], atol=3e-4)
    # leaving the context switched torque off
    assert all(emu.memory[:, ct.TORQUE_ENABLE[0]] == 0)


def test_press_to_depth_and_to_force_follow_the_surface_law(finger):
    with _bus(finger) as emu, DynamixelFinger(emu.port, BAUD, finger, clock=emu.clock) as drv:
        deep = drv.press(PressTarget(0.07, 0.0, depth=0.003, speed=0.05), SURFACE_Z)
        assert deep.stopped_by == "depth"
        assert deep.depth == pytest.approx(0.003, abs=2e-4)
        # force from the joint currents against the emulated surface law; currents are quantised (2.69 mA)
        assert deep.force == pytest.approx(STIFFNESS * deep.depth**1.5, abs=0.25)
        soft = drv.press(PressTarget(0.07, 0.0, depth=None, force=1.0, speed=0.05), SURFACE_Z)
        assert soft.stopped_by == "force"
        assert soft.force >= 1.0
        assert STIFFNESS * soft.depth**1.5 == pytest.approx(soft.force, abs=0.25)
        assert soft.depth < deep.depth
        # the press ends back at the approach height
        end = forward_kinematics(finger, soft.joints[-1].position)[0]
        assert end[2] == pytest.approx(SURFACE_Z + finger.approach_height, abs=5e-4)
        # the reported depth is what the poses show (the servos may settle a tick or so past it on release)
        poses_z = np.array([p.position[2] for p in soft.recording.poses])
        assert poses_z.min() == pytest.approx(SURFACE_Z - soft.depth, abs=2e-4)


def test_a_press_on_the_stepped_clock_is_the_same_every_time(planar2):
    runs = []
    for _ in range(2):
        with _bus(planar2) as emu, DynamixelFinger(emu.port, BAUD, planar2, clock=emu.clock) as drv:
            press = drv.press(PressTarget(0.07, 0.0, depth=0.003, speed=0.05), SURFACE_Z)
        runs.append(np.array([np.concatenate([[s.t], s.position, s.current]) for s in press.joints]))
    # bit for bit: the servos moved one control cycle per state read, whatever the scheduler did meanwhile
    assert runs[0].shape == runs[1].shape and len(runs[0]) > 20
    np.testing.assert_array_equal(runs[0], runs[1])


def test_limits_are_refused_before_any_write(planar2):
    with _bus(planar2) as emu, DynamixelFinger(emu.port, BAUD, planar2, clock=emu.clock) as drv:
        drv.enable_torque()
        writes, syncs = len(emu.writes), emu.instruction_counts[INST_SYNC_WRITE]
        q = 0.5 * (planar2.lower + planar2.upper)
        q[1] = planar2.upper[1] + 0.05
        with pytest.raises(ValidationError, match="pip"):
            drv.command_joints(q)
        with pytest.raises(ValidationError, match="out of reach"):
            drv.press(PressTarget(0.5, 0.0, depth=0.003), SURFACE_Z)
        with pytest.raises(ValidationError, match="max_depth"):
            drv.press(PressTarget(0.07, 0.0, depth=0.05), SURFACE_Z)
        with pytest.raises(ValidationError, match="plane"):
            drv.press(PressTarget(0.07, 0.02, depth=0.003), SURFACE_Z)
        assert len(emu.writes) == writes
        assert emu.instruction_counts[INST_SYNC_WRITE] == syncs


def test_servo_lost_mid_press_stops_cleanly(finger):
    lost = finger.ids[-1]
    seen = []

    def cut_cable(state, pose):
        seen.append(state)
        if len(seen) == 40:
            emu.silence(lost)

    with _bus(finger) as emu, DynamixelFinger(emu.port, BAUD, finger, clock=emu.clock) as drv:
        with pytest.raises(LostServo, match=f"servo {lost} .*stopped answering") as info:
            drv.press(PressTarget(0.07, 0.0, depth=0.003, speed=0.01), SURFACE_Z, on_state=cut_cable)
        assert info.value.servo_id == lost
        assert isinstance(info.value, DeviceError)
        # the others were switched off and told so; the lost one keeps whatever it had
        for sid in finger.ids[:-1]:
            assert emu.register(sid, ct.TORQUE_ENABLE) == 0
        assert len(seen) == 40  # every state received before the loss reached the callback


def test_ctrl_c_switches_torque_off(planar2):
    def interrupt(state, pose):
        raise KeyboardInterrupt

    with _bus(planar2) as emu, DynamixelFinger(emu.port, BAUD, planar2, clock=emu.clock) as drv:
        with pytest.raises(KeyboardInterrupt):
            drv.press(PressTarget(0.07, 0.0, depth=0.003), SURFACE_Z, on_state=interrupt)
        assert all(emu.register(sid, ct.TORQUE_ENABLE) == 0 for sid in planar2.ids)
        assert emu.writes[-1][1:] == (ct.TORQUE_ENABLE[0], b"\x00")


def test_corrupt_status_is_retried(planar2):
    with _bus(planar2, load=False) as emu, DynamixelFinger(emu.port, BAUD, planar2, clock=emu.clock) as drv:
        emu.set_register(1, ct.PRESENT_POSITION, 2222)
        emu.corrupt_next_status(1)
        state = drv.read_state()
        assert drv.corrupt_retries == 1
        assert joints_to_ticks(planar2, state.position)[0] == 2222
        emu.corrupt_next_status(100)
        with pytest.raises(DeviceError, match="bad answers in a row"):
            drv.read_state()


def test_hardware_alert_is_reported(planar2):
    with _bus(planar2, load=False) as emu, DynamixelFinger(emu.port, BAUD, planar2, clock=emu.clock) as drv:
        emu.set_hardware_error(2, 0x20)
        with pytest.raises(DeviceError, match="servo 2: hardware error status 0x20"):
            drv.read_state()


def test_stuffed_status_and_unstuffed_sdk_writes_survive_the_wire(planar2):
    with _bus(planar2, load=False) as emu, DynamixelFinger(emu.port, BAUD, planar2, clock=emu.clock) as drv:
        # FF FF FD inside data: the emulator stuffs it, the SDK unstuffs it
        value = 0x01FDFFFF
        emu.set_register(1, ct.PROFILE_VELOCITY, value)
        assert drv.read_register(1, ct.PROFILE_VELOCITY) == value
        # the SDK itself sends FF FF FD unstuffed (its addStuffing rebinds a local list); still understood
        drv._write(2, ct.PROFILE_VELOCITY, value)
        assert emu.register(2, ct.PROFILE_VELOCITY) == value
        assert emu.writes[-1] == (2, ct.PROFILE_VELOCITY[0], value.to_bytes(4, "little"))
        assert emu.instruction_counts[INST_WRITE] > 0


def test_eeprom_write_with_torque_on_is_refused_by_the_servo(planar2):
    with _bus(planar2, load=False) as emu, DynamixelFinger(emu.port, BAUD, planar2, clock=emu.clock) as drv:
        drv.enable_torque()
        with pytest.raises(DeviceError, match="servo 1: write of 3 to address 11 refused"):
            drv._write(1, ct.OPERATING_MODE, 3)
        assert emu.register(1, ct.OPERATING_MODE) == ct.MODE_CURRENT_POSITION


def test_wrong_port_and_wrong_baud_are_clear_errors(planar2, tmp_path):
    missing = str(tmp_path / "ttyUSB9")
    with pytest.raises(DeviceError, match="ttyUSB9"):
        DynamixelFinger(missing, BAUD, planar2).open()
    with pytest.raises(DeviceError, match="ttyUSB9"):
        scan(missing, BAUD, range(3))
    with ServoBusEmulator(planar2.ids, baud=57600) as emu:
        with pytest.raises(DeviceError, match="no servo answered .* 1000000 baud"):
            DynamixelFinger(emu.port, BAUD, planar2).open()


def test_missing_servo_is_named_at_open(planar2):
    with ServoBusEmulator([1], baud=BAUD) as emu:
        with pytest.raises(LostServo, match=r"servo id\(s\) \[2\] did not answer"):
            DynamixelFinger(emu.port, BAUD, planar2).open()


def test_wrong_servo_model_is_refused(planar2):
    with ServoBusEmulator(planar2.ids, model_number=1120, baud=BAUD) as emu:
        with pytest.raises(DeviceError, match="XM540-W270"):
            DynamixelFinger(emu.port, BAUD, planar2).open()


def test_corrupt_answers_at_open_are_named_as_such_not_as_a_wrong_baud_rate(planar2):
    with ServoBusEmulator(planar2.ids, baud=BAUD) as emu:
        emu.corrupt_next_status(20)
        with pytest.raises(DeviceError, match=r"servo id\(s\) \[1, 2\] .* only with corrupt packets") as info:
            DynamixelFinger(emu.port, BAUD, planar2).open()
    assert "baud" not in str(info.value) and "cable" in str(info.value)


def test_a_longer_answer_timeout_still_names_a_missing_servo_and_bad_values_are_refused(planar2):
    with ServoBusEmulator([1], baud=BAUD) as emu:
        finger = DynamixelFinger(emu.port, BAUD, planar2, retries=1, answer_timeout=0.2)
        with pytest.raises(LostServo, match=r"servo id\(s\) \[2\] did not answer"):
            finger.open()
    for bad in (0.0, -1.0, float("nan"), 11.0):
        with pytest.raises(ValidationError, match="answer timeout"):
            DynamixelFinger("/dev/null", BAUD, planar2, answer_timeout=bad)
