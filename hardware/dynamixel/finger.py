"""A planar 2-3 link robotic finger: its description file, joint/tick conversion, kinematics and statics.

The finger moves in the vertical x-z plane of the world through its base point. Joint angles are measured
about the world +y axis, so a positive angle curls the finger downwards (towards -z); angle 0 of the first
joint points the first link along +x. The fingertip pitch is the sum of the joint angles (pi/2 = pointing
straight down). A servo reads ``ticks`` (4096 per revolution, 2048 at the centre); the joint angle is
``direction * (ticks - 2048) * 2 pi / ticks_per_rev + offset``.

Description files are TOML under ``models/fingers/``; every key is validated and an error names the file,
the key and what was expected.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.files import read_toml
from palpate.core.perception.streams import PoseSample
from palpate.hardware.dynamixel import control_table as ct


@dataclass(frozen=True)
class Joint:
    """One joint driven by one servo.

    Attributes:
        name: joint name (used as the joint-state name in recordings).
        servo_id: Dynamixel id of its servo.
        link_length: length of the link after this joint, m.
        offset: joint angle at the servo's centre tick, rad.
        direction: +1 or -1, sign between servo rotation and joint angle (mirrored mounts).
        lower, upper: joint limits, rad.
    """

    name: str
    servo_id: int
    link_length: float
    offset: float
    direction: int
    lower: float
    upper: float


@dataclass(frozen=True)
class FingerDescription:
    """A planar finger of 2 or 3 joints.

    Attributes:
        name: finger name.
        joints: joints from base to tip.
        base: world position of the first joint axis, m, shape (3,).
        servo_model: ROBOTIS model name of the servos (all the same).
        ticks_per_rev: encoder ticks per revolution (4096 for X-series).
        current_limit: servo current limit, A (written to the servos' current limit and goal current).
        press_current: a press stops when any joint current magnitude exceeds this, A.
        approach_height: height above the surface from which a press starts, m.
        max_depth: deepest a press may go below the surface when pressing to a force, m.
        tip_pitch: preferred fingertip pitch for 3-link inverse kinematics, rad (pi/2 = pointing down).
        source: file it was loaded from ("" if built in code).
    """

    name: str
    joints: tuple[Joint, ...]
    base: np.ndarray
    servo_model: str = "XM430-W350"
    ticks_per_rev: int = ct.TICKS_PER_REV
    current_limit: float = 1.0
    press_current: float = 0.5
    approach_height: float = 0.01
    max_depth: float = 0.01
    tip_pitch: float = math.pi / 2
    source: str = ""

    @property
    def ids(self) -> list[int]:
        return [j.servo_id for j in self.joints]

    @property
    def names(self) -> list[str]:
        return [j.name for j in self.joints]

    @property
    def lengths(self) -> np.ndarray:
        return np.array([j.link_length for j in self.joints])

    @property
    def lower(self) -> np.ndarray:
        return np.array([j.lower for j in self.joints])

    @property
    def upper(self) -> np.ndarray:
        return np.array([j.upper for j in self.joints])

    @property
    def directions(self) -> np.ndarray:
        return np.array([j.direction for j in self.joints], dtype=float)

    @property
    def offsets(self) -> np.ndarray:
        return np.array([j.offset for j in self.joints])

    @property
    def model(self) -> ct.ServoModel:
        return ct.model_by_name(self.servo_model)


# ---- loading -----------------------------------------------------------------------------------------------

def _num(where: str, key: str, value, *, positive: bool = False, allow_zero: bool = True) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ValidationError(f"{where}: key {key!r} must be a finite number, got {value!r}")
    if positive and (value < 0 or (value == 0 and not allow_zero)):
        raise ValidationError(f"{where}: key {key!r} must be {'>= 0' if allow_zero else '> 0'}, got {value!r}")
    return float(value)


def finger_from_dict(data: dict, source: str = "<dict>") -> FingerDescription:
    """Build and validate a finger description from parsed TOML (see ``models/fingers/*.toml``).

    Lengths in the file are m, angles rad, currents mA. Raises ValidationError naming ``source`` and the key.
    """
    known_top = {"name", "base", "servo", "press", "joints"}
    unknown = set(data) - known_top
    if unknown:
        raise ValidationError(f"{source}: unknown key(s) {sorted(unknown)}; expected {sorted(known_top)}")
    name = data.get("name")
    if not isinstance(name, str) or not name:
        raise ValidationError(f"{source}: key 'name' must be a non-empty string")
    servo = data.get("servo", {})
    if not isinstance(servo, dict):
        raise ValidationError(f"{source}: [servo] must be a table")
    model_name = servo.get("model", "XM430-W350")
    try:
        model = ct.model_by_name(str(model_name))
    except KeyError as exc:
        raise ValidationError(f"{source}: servo.model: {exc.args[0]}") from None
    tpr = servo.get("ticks_per_rev", ct.TICKS_PER_REV)
    if tpr != ct.TICKS_PER_REV:
        raise ValidationError(f"{source}: servo.ticks_per_rev must be {ct.TICKS_PER_REV} for X-series, got {tpr!r}")
    limit_ma = _num(source, "servo.current_limit", servo.get("current_limit", 1000), positive=True, allow_zero=False)
    limit_units = limit_ma * 1e-3 / model.current_unit
    if limit_units > model.current_limit_max:
        raise ValidationError(
            f"{source}: servo.current_limit {limit_ma} mA exceeds what a {model.name} accepts "
            f"({model.current_limit_max * model.current_unit * 1e3:.0f} mA)")
    press = data.get("press", {})
    if not isinstance(press, dict):
        raise ValidationError(f"{source}: [press] must be a table")
    press_ma = _num(source, "press.current_threshold", press.get("current_threshold", 0.5 * limit_ma),
                    positive=True, allow_zero=False)
    if press_ma >= limit_ma:
        raise ValidationError(f"{source}: press.current_threshold ({press_ma} mA) must be below servo.current_limit "
                              f"({limit_ma} mA), or the servo saturates before the press can stop")
    approach = _num(source, "press.approach_height", press.get("approach_height", 0.01), positive=True,
                    allow_zero=False)
    max_depth = _num(source, "press.max_depth", press.get("max_depth", 0.01), positive=True, allow_zero=False)
    tip_pitch = _num(source, "press.tip_pitch", press.get("tip_pitch", math.pi / 2))
    base = data.get("base", [0.0, 0.0, 0.0])
    if not isinstance(base, list) or len(base) != 3:
        raise ValidationError(f"{source}: key 'base' must be [x, y, z] in m, got {base!r}")
    base_arr = np.array([_num(source, f"base[{i}]", v) for i, v in enumerate(base)])
    raw_joints = data.get("joints")
    if not isinstance(raw_joints, list) or not 2 <= len(raw_joints) <= 3:
        raise ValidationError(f"{source}: [[joints]] must list 2 or 3 joints, got "
                              f"{len(raw_joints) if isinstance(raw_joints, list) else raw_joints!r}")
    joints = []
    for i, jd in enumerate(raw_joints):
        w = f"{source}: joints[{i}]"
        if not isinstance(jd, dict):
            raise ValidationError(f"{w} must be a table")
        extra = set(jd) - {"name", "servo_id", "link_length", "offset", "direction", "limits"}
        if extra:
            raise ValidationError(f"{w}: unknown key(s) {sorted(extra)}")
        sid = jd.get("servo_id")
        if isinstance(sid, bool) or not isinstance(sid, int) or not 0 <= sid <= 252:
            raise ValidationError(f"{w}.servo_id must be an integer id in 0..252, got {sid!r}")
        length = _num(w, "link_length", jd.get("link_length"), positive=True, allow_zero=False)
        if length > 1.0:
            raise ValidationError(f"{w}.link_length is in m and must be <= 1 m, got {length} (mm by mistake?)")
        offset = _num(w, "offset", jd.get("offset", 0.0))
        direction = jd.get("direction", 1)
        if direction not in (1, -1) or isinstance(direction, bool):
            raise ValidationError(f"{w}.direction must be 1 or -1, got {direction!r}")
        lim = jd.get("limits")
        if not isinstance(lim, list) or len(lim) != 2:
            raise ValidationError(f"{w}.limits must be [lower, upper] in rad, got {lim!r}")
        lo, hi = _num(w, "limits[0]", lim[0]), _num(w, "limits[1]", lim[1])
        if not lo < hi:
            raise ValidationError(f"{w}.limits must have lower < upper, got {lim!r}")
        jname = jd.get("name", f"joint{i}")
        if not isinstance(jname, str) or not jname:
            raise ValidationError(f"{w}.name must be a non-empty string")
        joint = Joint(jname, sid, length, offset, int(direction), lo, hi)
        ticks = [direction * (q - offset) * tpr / (2 * math.pi) + ct.CENTER_TICK for q in (lo, hi)]
        if min(ticks) < 0 or max(ticks) > tpr - 1:
            raise ValidationError(f"{w}.limits {lim} map to servo ticks {ticks[0]:.0f}..{ticks[1]:.0f}, outside the "
                                  f"servo's 0..{tpr - 1}; change limits or offset")
        joints.append(joint)
    ids = [j.servo_id for j in joints]
    if len(set(ids)) != len(ids):
        raise ValidationError(f"{source}: joints[].servo_id must be unique, got {ids}")
    return FingerDescription(name, tuple(joints), base_arr, model.name, int(tpr), limit_ma * 1e-3, press_ma * 1e-3,
                             approach, max_depth, tip_pitch, source)


def load_finger(path: str | Path) -> FingerDescription:
    """Load and validate a finger description TOML file (see ``models/fingers/``)."""
    path = Path(path)
    return finger_from_dict(read_toml(path, "finger description"), str(path))


# ---- joints and ticks --------------------------------------------------------------------------------------

def ticks_to_joints(finger: FingerDescription, ticks: np.ndarray) -> np.ndarray:
    """Servo positions (ticks) to joint angles (rad)."""
    ticks = np.asarray(ticks, dtype=float)
    return finger.directions * (ticks - ct.CENTER_TICK) * (2 * math.pi / finger.ticks_per_rev) + finger.offsets


def joints_to_ticks(finger: FingerDescription, q: np.ndarray) -> np.ndarray:
    """Joint angles (rad) to the nearest servo positions (int ticks)."""
    q = np.asarray(q, dtype=float)
    return np.rint(finger.directions * (q - finger.offsets) * (finger.ticks_per_rev / (2 * math.pi))
                   + ct.CENTER_TICK).astype(np.int64)


def check_joint_limits(finger: FingerDescription, q: np.ndarray) -> np.ndarray:
    """Return ``q`` as an array if it is finite and inside every joint limit; ValidationError naming the joint."""
    q = np.asarray(q, dtype=float).reshape(-1)
    if q.shape != (len(finger.joints),):
        raise ValidationError(f"finger {finger.name!r} has {len(finger.joints)} joints, got {q.shape[0]} angles")
    for j, v in zip(finger.joints, q, strict=True):
        if not math.isfinite(v):
            raise ValidationError(f"joint {j.name!r} (servo {j.servo_id}): angle is {v}")
        if not j.lower <= v <= j.upper:
            raise ValidationError(f"joint {j.name!r} (servo {j.servo_id}): {v:.4f} rad is outside its limits "
                                  f"[{j.lower}, {j.upper}] rad")
    return q


# ---- kinematics --------------------------------------------------------------------------------------------

def forward_kinematics(finger: FingerDescription, q: np.ndarray) -> tuple[np.ndarray, float]:
    """Fingertip position (m, world, shape (3,)) and pitch (rad) for joint angles ``q`` (rad)."""
    q = np.asarray(q, dtype=float)
    phi = np.cumsum(q)
    d = finger.lengths
    tip = finger.base + np.array([np.sum(d * np.cos(phi)), 0.0, -np.sum(d * np.sin(phi))])
    return tip, float(phi[-1])


def fingertip_pose(finger: FingerDescription, q: np.ndarray, t: float, sensor_id: str = "fingertip") -> PoseSample:
    """The fingertip pose as a PoseSample: position from FK, orientation a rotation of ``pitch`` about +y."""
    tip, pitch = forward_kinematics(finger, q)
    quat = np.array([math.cos(pitch / 2), 0.0, math.sin(pitch / 2), 0.0])
    return PoseSample(t, tip, quat, sensor_id)


def jacobian(finger: FingerDescription, q: np.ndarray) -> np.ndarray:
    """d(x, z)/dq of the fingertip, shape (2, n), m/rad."""
    q = np.asarray(q, dtype=float)
    phi = np.cumsum(q)
    d = finger.lengths
    # joint i moves every link from i on
    dx = -np.cumsum((d * np.sin(phi))[::-1])[::-1]
    dz = -np.cumsum((d * np.cos(phi))[::-1])[::-1]
    return np.vstack([dx, dz])


def _two_link(u: float, w: float, l1: float, l2: float) -> tuple[float, float] | None:
    # (u, w): target relative to the base, w positive downwards; the finger flexes (q2 >= 0).
    c2 = (u * u + w * w - l1 * l1 - l2 * l2) / (2 * l1 * l2)
    if not -1.0 - 1e-12 <= c2 <= 1.0 + 1e-12:
        return None
    q2 = math.acos(min(1.0, max(-1.0, c2)))
    q1 = math.atan2(w, u) - math.atan2(l2 * math.sin(q2), l1 + l2 * math.cos(q2))
    return q1, q2


def inverse_kinematics(finger: FingerDescription, x: float, z: float, pitch: float | None = None) -> np.ndarray:
    """Joint angles (rad) that put the fingertip at world (x, z), m, inside the joint limits.

    Two links: closed form (the flexed solution). Three links: the tip pitch is the free parameter; the
    solution is the one whose pitch is closest to ``pitch`` (default the finger's ``tip_pitch``) among those
    inside the joint limits, each candidate solved in closed form (wrist point, then two links), so the tip
    lands exactly on the target. Raises ValidationError if (x, z) is out of reach within the limits.
    """
    if not (math.isfinite(x) and math.isfinite(z)):
        raise ValidationError(f"IK target must be finite, got x={x}, z={z}")
    u, w = x - finger.base[0], finger.base[2] - z
    lengths = finger.lengths
    where = f"finger {finger.name!r}: fingertip target (x={x:.4f}, z={z:.4f}) m"
    if len(lengths) == 2:
        sol = _two_link(u, w, lengths[0], lengths[1])
        if sol is None:
            raise ValidationError(f"{where} is out of reach (links {lengths.tolist()} m)")
        return check_joint_limits(finger, np.array(sol))
    pitch = finger.tip_pitch if pitch is None else float(pitch)
    return _three_link(finger, u, w, pitch, where)


def _three_link_candidates(finger: FingerDescription, u: float, w: float, phi: np.ndarray) -> np.ndarray:
    """Closed-form solutions (flexed and extended elbow) for tip pitches ``phi``: shape (2, len(phi), 3), NaN
    where the wrist point is out of reach."""
    l1, l2, l3 = finger.lengths
    wu, ww = u - l3 * np.cos(phi), w - l3 * np.sin(phi)
    c2 = (wu * wu + ww * ww - l1 * l1 - l2 * l2) / (2 * l1 * l2)
    reach = np.abs(c2) <= 1.0
    out = np.full((2, phi.size, 3), np.nan)
    for b, sign in enumerate((1.0, -1.0)):
        q2 = sign * np.arccos(np.clip(c2, -1.0, 1.0))
        q1 = np.arctan2(ww, wu) - np.arctan2(l2 * np.sin(q2), l1 + l2 * np.cos(q2))
        q3 = np.mod(phi - q1 - q2 + np.pi, 2 * np.pi) - np.pi
        out[b] = np.where(reach[:, None], np.stack([q1, q2, q3], axis=-1), np.nan)
    return out


def _three_link(finger: FingerDescription, u: float, w: float, pitch: float, where: str) -> np.ndarray:
    lo, hi = finger.lower, finger.upper

    def feasible(q: np.ndarray) -> np.ndarray:
        with np.errstate(invalid="ignore"):
            return np.all((q >= lo) & (q <= hi), axis=-1)

    exact = _three_link_candidates(finger, u, w, np.array([pitch]))[:, 0]
    ok = feasible(exact)
    if ok.any():
        return exact[int(np.argmax(ok))]
    # scan the pitch on a grid, then bisect between the best feasible sample and its infeasible neighbour
    # towards the preferred pitch: the result is the feasible pitch nearest the preferred one (to ~1e-9 rad)
    grid = pitch + np.linspace(-np.pi, np.pi, 721)
    cand = _three_link_candidates(finger, u, w, grid)
    ok = feasible(cand)
    if not ok.any():
        raise ValidationError(f"{where} is out of reach within the joint limits")
    dist = np.where(ok, np.abs(grid - pitch)[None, :], np.inf)
    branch, k = np.unravel_index(int(np.argmin(dist)), dist.shape)
    good, bad = grid[k], grid[k + 1] if grid[k] < pitch else grid[k - 1]
    for _ in range(40):
        mid = 0.5 * (good + bad)
        if feasible(_three_link_candidates(finger, u, w, np.array([mid]))[branch, 0]):
            good = mid
        else:
            bad = mid
    return _three_link_candidates(finger, u, w, np.array([good]))[branch, 0]


# ---- statics -----------------------------------------------------------------------------------------------

def tip_force_from_torques(finger: FingerDescription, q: np.ndarray, joint_torques: np.ndarray) -> np.ndarray:
    """External force on the fingertip, (Fx, Fz) N, balanced by the motors' joint torques (N*m).

    Statics: the motors hold tau = -J^T F, so F = -pinv(J^T) tau (least squares for 3 joints).
    """
    jt = jacobian(finger, q).T
    return -np.linalg.lstsq(jt, np.asarray(joint_torques, dtype=float), rcond=None)[0]


def surface_load_model(finger: FingerDescription, surface_z: float, stiffness: float,
                       exponent: float = 1.5) -> Callable[[np.ndarray], np.ndarray]:
    """A load model for the servo emulator: a flat elastic surface at height ``surface_z`` (m).

    The surface pushes the fingertip up with F = stiffness * d**exponent (N, d = indentation in m; 1.5 is the
    Hertz law). Returns ``load(servo_angles) -> servo shaft torques`` (rad -> N*m) in the finger's joint order.
    """
    if not (stiffness > 0 and math.isfinite(stiffness)):
        raise ValidationError(f"surface stiffness must be > 0 (N/m^{exponent}), got {stiffness}")
    dirs, offs = finger.directions, finger.offsets

    def load(servo_angles: np.ndarray) -> np.ndarray:
        q = dirs * np.asarray(servo_angles, dtype=float) + offs
        tip, _ = forward_kinematics(finger, q)
        depth = max(0.0, surface_z - tip[2])
        force = np.array([0.0, stiffness * depth**exponent])
        joint_torque = jacobian(finger, q).T @ force
        return dirs * joint_torque

    return load
