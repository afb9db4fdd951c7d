"""The Dynamixel finger as the exploration actuator of ``palpate run`` (entry point ``dynamixel`` in
``palpate.actuators``; the request and the factory signature are in :mod:`palpate.core.session.actuators`).

Before anything is opened, every cell the policy may press is planned as a press (:func:`plan_press`: on the
finger's plane, inside its reach and joint limits along the whole vertical path, not deeper than its
``press.max_depth``), so a grid the finger cannot press is refused before any servo moves.

The taxel frames of each press come from a live tactile array on its own serial port (``taxels``, see
:mod:`palpate.hardware.tactile`), read through pyserial on the driver's clock. With ``emulate = true`` both devices
are emulators on two pseudo-terminals backed by one physics: dynamixel-sdk -> pty -> :class:`ServoBusEmulator` ->
MuJoCo physics of the scenario's object (:func:`palpate.hardware.dynamixel.physics_bus.physics_bus`), and the
array's pty -> :class:`TactileArrayEmulator` -> that physics' pad (:func:`physics_taxels`), all on one stepped
clock. A real bus with no ``taxels`` is refused: a finger without a pad gives no taxel frames.
"""

from __future__ import annotations

import contextlib
import dataclasses
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.perception.force_channel import PERCEPTION as FORCE_PERCEPTION
from palpate.core.perception.pipeline import PipelineConfig
from palpate.core.perception.streams import PressRecording
from palpate.core.session.sources import PressTarget
from palpate.core.world.actuator_kinds import ActuatorKind
from palpate.core.world.table_reader import TableReader, resolve_path
from palpate.hardware.clock import WALL_CLOCK, StepClock
from palpate.hardware.dynamixel.driver import DynamixelFinger
from palpate.hardware.dynamixel.finger import (
    FingerDescription,
    forward_kinematics,
    inverse_kinematics,
    load_finger,
)
from palpate.hardware.dynamixel.physics_bus import physics_bus, physics_taxels
from palpate.hardware.dynamixel.press import PLANE_TOLERANCE, FingerActuator, plan_press
from palpate.hardware.dynamixel.taxel_streams import TaxelPort, open_reader, reader_streams
from palpate.hardware.tactile.emulator import TactileArrayEmulator
from palpate.hardware.tactile.protocol import FORMATS

# At most this many offending cells are named in an error (a whole row off the plane would be a wall of text).
MAX_NAMED = 3
# Between presses the tip travels at the approach height through waypoints this far apart (m): a single joint
# move from cell to cell swings the tip down on the way (planar2, 50 -> 90 mm, 3 mm above a top: 4.4 mm lower
# half-way, into the object), while 2 mm chords sag by ~0.01 mm.
TRAVEL_STEP = 0.002
TRAVEL_TOLERANCE = 0.02  # rad: waypoints need not be reached exactly, only the press start (press.py) does
# A press whose fingertip poses stall longer than the perception's pose-gap limit (the servo loop shares the CPU;
# an emulator on a loaded machine stalls for 0.1 s now and then) loses its taxel frames in the gap, so it is
# pressed again, at most this many times.
REPEATS = 2
# The fingertip poses are the run's pose stream: named as the simulated sources name theirs, so that a recorded
# run (training in simulation, exploration with the finger) holds one pose sensor and replays.
POSE_SENSOR = "pose"
# On the emulated rig's stepped clock, each control cycle also lets this fraction of it pass on the wall, so the
# tactile array's thread keeps up with the servos (their motion does not depend on it).
WALL_RATIO = 0.2


@dataclass(frozen=True)
class DynamixelOptions:
    """``[actuator]`` options of kind ``dynamixel`` (lengths m).

    Attributes:
        port: serial port of the servo bus (None with ``emulate``).
        baud: bus bit rate.
        finger: finger description file (models/fingers/*.toml).
        emulate: press through the servo emulator on a pty, backed by MuJoCo physics of the scene.
        pose_noise: standard deviation of noise added to each fingertip position, m per axis.
        approach_height: height above the surface where each press starts, m (None: the finger file's).
        taxels: the tactile array's serial settings (port, format, rate, baud; None with ``emulate``).
        pad: False for a finger with no tactile pad: each press's c_P is the fingertip force from its joint currents
            and the memory judges it by its kinesthetic model alone (training too: :attr:`perception`).
    """

    port: str | None = None
    baud: int = 1_000_000
    finger: Path | None = None
    emulate: bool = False
    pose_noise: float = 0.0
    approach_height: float | None = None
    taxels: TaxelPort | None = None
    pad: bool = True

    @property
    def perception(self) -> dict | None:
        """How this actuator's presses are perceived, when not as taxels (the run trains its memory alike)."""
        return None if self.pad else dict(FORCE_PERCEPTION)


def parse_options(r: TableReader, base: Path) -> DynamixelOptions:
    """Validate the ``[actuator]`` keys of kind ``dynamixel``; relative paths resolve against ``base``."""
    emulate = r.get("emulate", bool, False)
    port = r.get("port", str, "") or None
    if emulate and port:
        raise r.err("port", "not used with emulate = true (the emulator opens its own pseudo-terminal); "
                    "leave one of them out")
    if not emulate and not port:
        raise r.err("port", "missing: the servo bus's serial port (e.g. /dev/ttyUSB0), or emulate = true")
    finger = r.get("finger", str)
    if not finger:
        raise r.err("finger", "must name a finger description file (models/fingers/*.toml)")
    approach = r.number("approach_mm", None, lo=0.0, lo_open=True)
    taxel_port = r.get("taxels", str, "") or None
    pad = r.get("pad", bool, True)
    if not pad and taxel_port:
        raise r.err("taxels", "not used with pad = false (a finger without a pad measures its force by its currents)")
    if emulate and taxel_port:
        raise r.err("taxels", "not used with emulate = true (the emulated tactile array opens its own pseudo-terminal)")
    fmt = r.get("taxel_format", str, "binary")
    if fmt not in FORMATS:
        raise r.err("taxel_format", f"must be one of {', '.join(FORMATS)}, got {fmt!r}")
    taxels = None
    if pad and (emulate or taxel_port):
        taxels = TaxelPort(taxel_port or "emulator", fmt, r.number("taxel_rate", 50.0, lo=0.0, lo_open=True),
                           r.integer("taxel_baud", 115200, lo=1))
    return DynamixelOptions(port=port, baud=r.integer("baud", DynamixelOptions.baud, lo=1),
                            finger=resolve_path(base, finger), emulate=emulate,
                            pose_noise=r.number("pose_noise_mm", 0.0, lo=0.0) * 1e-3,
                            approach_height=None if approach is None else approach * 1e-3, taxels=taxels, pad=pad)


class FingerSession:
    """A :class:`FingerActuator` together with the bus (and emulator) it owns; ``close()`` releases them.

    Each press first travels to the target at the approach height (:meth:`travel_to`), so the streams of a
    press hold the press alone and the tip never sweeps through the object between cells.
    """

    def __init__(self, actuator: FingerActuator, stack: contextlib.ExitStack):
        self.actuator = actuator
        self._stack = stack

    def press(self, target: PressTarget) -> PressRecording:
        """Travel above ``target``, then one press-and-release there (m, N, m/s); see :meth:`FingerActuator.press`.

        A press whose pose stream has a gap longer than the pipeline's ``max_gap`` is made again (``REPEATS``
        times at most); ``meta["attempts"]`` says how many presses it took, ``meta["pose_gap_s"]`` the longest
        gap left when none was clean.
        """
        max_gap = PipelineConfig().max_gap
        attempts = 0
        while True:
            attempts += 1
            self.travel_to(target.x)
            rec = self.actuator.press(target)
            t = np.array([p.t for p in rec.poses])
            gap = float(np.max(np.diff(t))) if len(t) > 1 else float("inf")
            if gap <= max_gap or attempts > REPEATS:
                break
        rec.poses = [dataclasses.replace(p, sensor_id=POSE_SENSOR) for p in rec.poses]
        rec.meta = {**rec.meta, "attempts": attempts}
        if gap > max_gap:
            rec.meta["pose_gap_s"] = gap if np.isfinite(gap) else None
        return rec

    def travel_to(self, x: float) -> None:
        """Move the tip to ``x`` (m) at the approach height above the surface: straight up first if it is lower,
        then along x through waypoints ``TRAVEL_STEP`` apart. ValidationError (nothing sent) if a waypoint is out
        of reach."""
        driver = self.actuator.driver
        finger = driver.finger
        z = self.actuator.surface_z + finger.approach_height
        with driver.safety():
            tip = forward_kinematics(finger, driver.read_state().position)[0]
            path = [(float(tip[0]), z)] if tip[2] < z - 1e-4 else []
            n = int(np.ceil(abs(x - tip[0]) / TRAVEL_STEP))
            path += [(float(xi), z) for xi in np.linspace(tip[0], x, n + 1)[1:]]
            goals = [inverse_kinematics(finger, xi, zi) for xi, zi in path]  # all planned before anything moves
            if goals and not driver._torque_on:
                driver.enable_torque()
            for q in goals:
                driver.move_to(q, TRAVEL_TOLERANCE)

    def close(self) -> None:
        """Torque off, port closed, emulator stopped (idempotent)."""
        self._stack.close()


def finger_for(request) -> FingerDescription:
    """The request's finger description, with its approach height overridden when the scenario sets one."""
    spec: DynamixelOptions = request.spec.options
    if spec.finger is None:
        raise ValidationError("actuator.finger: missing (a finger description, models/fingers/*.toml)")
    finger = load_finger(spec.finger)
    if spec.approach_height is not None:
        finger = dataclasses.replace(finger, approach_height=float(spec.approach_height))
    return finger


def check_reach(finger: FingerDescription, request) -> None:
    """Plan a press at every cell of ``request.cells``; ValidationError naming the object, the cells and why.

    A planar finger moves in the plane y = base y: every cell centre must lie within PLANE_TOLERANCE of it.
    """
    obj = request.obj
    surface_z = obj.height
    y0 = float(finger.base[1])
    where = f"actuator dynamixel, object {obj.name!r}"
    src = finger.source or finger.name
    targets = np.asarray(request.targets, dtype=float).reshape(-1, 2)
    off = np.nonzero(np.abs(targets[:, 1] - y0) > PLANE_TOLERANCE)[0]
    if len(off):
        named = ", ".join(f"[{request.cells[i][0] + 1}, {request.cells[i][1] + 1}] at y = {targets[i, 1] * 1e3:.1f} mm"
                          for i in off[:MAX_NAMED])
        more = f" and {len(off) - MAX_NAMED} more" if len(off) > MAX_NAMED else ""
        half = request.cell_size * 1e3 / 2
        raise ValidationError(
            f"{where}: {len(off)} of the {len(targets)} cells the exploration may press lie off the plane of finger "
            f"{finger.name!r} ({src}), y = {y0 * 1e3:.1f} mm: cell(s) {named}{more}. A planar finger presses one row: "
            f"give the object grid_cells = [N, 1] and grid_origin_mm = [x0, {y0 * 1e3 - half:.1f}]")
    for (ix, iy), (x, y) in zip(request.cells, targets, strict=True):
        try:
            plan_press(finger, PressTarget(float(x), float(y), depth=request.depth, force=request.max_force,
                                           speed=request.speed), surface_z)
        except ValidationError as exc:
            raise ValidationError(f"{where}: cell [{ix + 1}, {iy + 1}] at x = {x * 1e3:.1f} mm cannot be pressed "
                                  f"{request.depth * 1e3:.1f} mm deep from a top at z = {surface_z * 1e3:.1f} mm: "
                                  f"{exc}") from None


def dynamixel_actuator(request, *, check_only: bool = False):
    """Factory of kind ``dynamixel`` (see :mod:`palpate.core.session.actuators` for the signature).

    Checks the finger file and the reach of every cell; with ``check_only`` stops there. Otherwise opens the bus
    and the tactile array (``emulate``: their emulators over ``request.scene``) and returns a :class:`FingerSession`
    whose presses carry the array's taxel frames, the fingertip poses (plus ``pose_noise``) and, emulated, the
    physics' ground truth.
    """
    spec: DynamixelOptions = request.spec.options
    finger = finger_for(request)
    check_reach(finger, request)
    if not spec.emulate:
        if spec.taxels is None and spec.pad:
            raise ValidationError(f"actuator.taxels: missing: the finger on {spec.port!r} needs the tactile array's "
                                  "serial port (taxels = \"/dev/ttyACM0\", or --taxels PORT) for its presses to be "
                                  "perceived, or pad = false for a finger without one (c_P from its joint currents)")
        if check_only:
            return None
        return _real_finger(spec, finger, request)
    if request.obj.shape not in ("box", "cylinder"):
        raise ValidationError(f"actuator dynamixel, object {request.obj.name!r}: the emulated finger presses boxes "
                              f"and cylinders (a flat top), not a {request.obj.shape}")
    if check_only:
        return None

    surface_z = request.obj.height
    # power on above the first cell the exploration may press: the first move is then short
    start = inverse_kinematics(finger, float(request.targets[0, 0]), surface_z + finger.approach_height)
    # on an error the with-block closes what was opened; on success pop_all hands it to the session
    with contextlib.ExitStack() as stack:
        # the emulated finger runs on a stepped clock: one control cycle per state read, as fast as the machine
        # allows, and the same exploration every time
        clock = StepClock(wall_ratio=WALL_RATIO)
        emulator, physics = physics_bus(finger, request.scene, start, baud=spec.baud, clock=clock)
        stack.enter_context(emulator)
        if spec.pad:
            source, ready = physics_taxels(physics, emulator, seed=request.seed)
            taxels = spec.taxels or TaxelPort("emulator")
            array = stack.enter_context(TactileArrayEmulator(
                source, rows=request.scene.fingertip.rows, cols=request.scene.fingertip.cols,
                rate=request.scene.taxels.rate, fmt=taxels.fmt, baud=taxels.baud, clock=clock, epoch=0.0, ready=ready))
            reader = stack.enter_context(open_reader(replace(taxels, port=array.port, rate=request.scene.taxels.rate),
                                                     request.scene, clock))
            streams = reader_streams(reader, physics.truth)
        else:
            streams = _truth_only(physics)
        return _finger_session(stack, emulator.port, clock, streams, spec, finger, request)


def _real_finger(spec: DynamixelOptions, finger: FingerDescription, request) -> FingerSession:
    """The finger on ``spec.port`` with the tactile array on ``spec.taxels``, both on the wall clock."""
    with contextlib.ExitStack() as stack:
        streams = None
        if spec.pad:
            streams = reader_streams(stack.enter_context(open_reader(spec.taxels, request.scene, WALL_CLOCK)))
        return _finger_session(stack, spec.port, WALL_CLOCK, streams, spec, finger, request)


def _finger_session(stack: contextlib.ExitStack, port: str, clock, streams, spec: DynamixelOptions,
                    finger: FingerDescription, request) -> FingerSession:
    """Open the finger's driver on ``port`` into ``stack`` and hand everything the stack holds to the session."""
    driver = stack.enter_context(DynamixelFinger(port, spec.baud, finger, clock=clock))
    actuator = FingerActuator(driver, request.obj.height, streams=streams, pose_noise=spec.pose_noise,
                              seed=request.seed, force_from_currents=not spec.pad)
    return FingerSession(actuator, stack.pop_all())


def _truth_only(physics):
    """``streams`` giving the physics' ground truth and no taxel frames (a finger without a pad)."""
    return lambda t0, t1: ([], physics.truth(t0, t1))


#: The entry point ``dynamixel`` of ``palpate.actuators``.
DYNAMIXEL = ActuatorKind(keys=("port", "baud", "finger", "emulate", "pose_noise_mm", "approach_mm", "taxels",
                               "taxel_format", "taxel_rate", "taxel_baud", "pad"),
                         parse=parse_options, make=dynamixel_actuator, extra="hardware")
