"""The Dynamixel finger in MuJoCo: the physics behind the servo emulator, and the taxels it produces.

``FingerPhysics(finger, scene)`` builds (with ``mujoco.MjSpec``) the planar finger of a description file as a
chain of hinge links over the scene's objects, with the simulation's fingertip at the end: a sphere whose pad
centre is the finger's kinematic tip point, carrying the 4x4 sensel pad. Given the servo shaft angles it

- places the chain (MuJoCo kinematics), finds the tip sphere against the object under it and evaluates the
  ``rigid`` fidelity's contact model: the press point's contact law (its column's layers on the table: finite
  thickness and skins, exact sphere, :mod:`palpate.sim.contact`; an inclusion or edge within reach is not
  solved for, the emulator answers in real time) mapped onto the real footprint by clearance (edges, sloped and
  curved tops; see :mod:`palpate.sim.rigid`), and
- returns the external torque on each servo shaft, ``J^T F`` with ``J`` MuJoCo's Jacobian of the contact point:
  that is the emulator's ``load_model``, so the joint currents a driver reads back are the physics' force;
- records, through the emulator's ``observer`` hook, what the servos actually did (tip pose, force, true
  indentation, mean pressure over each sensel of the tilted pad) as a :class:`PhysicsTrace`, which
  :mod:`palpate.sim.sensors` samples into 50 Hz taxel frames on the emulator's clock.

:func:`palpate.hardware.dynamixel.physics_bus.physics_bus` wires it to the servo emulator, so dynamixel-sdk -> pty ->
emulator -> physics -> taxels runs end to end, and :meth:`FingerPhysics.actuator_streams` gives the finger actuator
its taxel frames. The finger is anything shaped like :class:`FingerChain` (a Dynamixel finger description is one):
sim does not import the hardware package.

Validity: quasi-static (the servos hold their position, the contact force is elastic: Kelvin-Voigt damping and
the finger's inertia are ignored), one object under the tip, the force taken along +z (a sloped top's tangential
part is left out), the validity of ``rigid`` (the validity table of ``palpate bench``), frictionless contact. The
pad follows the fingertip's pitch: on a 2-link finger the tip tilts a few degrees during a press, which shifts the
lit sensels along x.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.perception.streams import GroundTruth, TaxelFrame
from palpate.core.world.scene import ObjectSpec, Scene
from palpate.sim.analytic import local_material
from palpate.sim.contact.law import ContactLaw
from palpate.sim.contact.stack import object_law
from palpate.sim.fingertip import cap_height, sensel_quadrature, sensel_sites
from palpate.sim.footprint import Footprint, contact_geometry, equivalent_radius, footprint_rings, law_pressure
from palpate.sim.scene import add_object, surface_heights
from palpate.sim.sensors import ground_truth, sample_taxels
from palpate.sim.stability import MAX_DEPTH_OVER_RADIUS
from palpate.sim.trace import PhysicsTrace


class ChainJoint(Protocol):
    """A hinge of a planar finger: its name, limits (rad) and the length of the link it drives (m)."""

    name: str
    lower: float
    upper: float
    link_length: float


class FingerChain(Protocol):
    """What the physics needs of a planar finger (e.g. ``palpate.hardware.dynamixel.finger.FingerChain``).

    Attributes:
        name: the finger's name; joints: its hinges from the base out; lengths: link lengths, m;
        base: (x, y, z) of the first joint, m; directions, offsets: servo angle -> joint angle
        (``q = direction * servo + offset``), per joint.
    """

    name: str
    joints: Sequence[ChainJoint]
    lengths: np.ndarray
    base: np.ndarray
    directions: np.ndarray
    offsets: np.ndarray


@dataclass(frozen=True)
class FingerContact:
    """Contact of the fingertip for one set of joint angles.

    Attributes:
        tip: kinematic fingertip point (the pad centre, what the finger's forward kinematics gives), m, (3,).
        centre: tip-sphere centre, m, (3,).
        quaternion: fingertip frame orientation (w, x, y, z); identity when the finger points straight down.
        force: external force on the fingertip, N, (3,) (the surface pushes it up: force[2] >= 0).
        indentation: depth of the sphere below the undeformed surface, m (0 out of contact).
        joint_torque: external torque on each joint, N*m, (n,) (J^T F in joint-angle convention).
        sensel_pressure: mean normal pressure over each sensel, Pa, (rows, cols); None when not asked for.
    """

    tip: np.ndarray
    centre: np.ndarray
    quaternion: np.ndarray
    force: np.ndarray
    indentation: float
    joint_torque: np.ndarray
    sensel_pressure: np.ndarray | None = None


@dataclass(frozen=True)
class _Under:
    """What the tip meets above one point: its footprint there, the point's contact law and the object."""

    footprint: Footprint
    law: ContactLaw
    obj: ObjectSpec


@dataclass(frozen=True)
class _Load:
    """The surface's push on the tip sphere: normal force N, indentation m, and what it pressed (None: nothing)."""

    force: float
    depth: float
    under: _Under | None


class FingerPhysics:
    """The MuJoCo finger over a scene's objects, with the local-Hertz contact of the ``rigid`` fidelity.

    Args:
        finger: the finger description (links, offsets, directions, servo ids).
        scene: the objects pressed and the fingertip/taxel/pose models (the tip radius and pad come from
            ``scene.fingertip``).
        rings, sectors: polar cells over the tip footprint for the total force (as in ``rigid``).
        order: Gauss-Legendre order per sensel side for the sensel pressures.
        retable: the footprint's surface sampling is redone when the tip centre moves more than this in
            x or y, m (on a flat top it never changes; it matters near edges).
        max_states: the recorded history is cut to its newer half when it grows past this many states (the
            emulator records one per 2 ms substep while the servos move: 200 000 is several minutes).

    Thread-safe: the emulator's thread calls :meth:`load` and :meth:`observe`, the test or run loop reads the
    trace. The emulator's thread only evaluates the force (tens of microseconds) and stores the angles it was
    shown; sensel pressures are computed when a trace is asked for, vectorised over its states.
    """

    def __init__(self, finger: FingerChain, scene: Scene, *, rings: int = 96, sectors: int = 24,
                 order: int = 6, retable: float = 1e-4, max_states: int = 200_000):
        import mujoco

        if not scene.objects:
            raise ValidationError("FingerPhysics: the scene has no object to press")
        if not (np.isfinite(retable) and retable > 0):
            raise ValidationError(f"FingerPhysics: retable must be > 0 m, got {retable!r}")
        if max_states < 4:
            raise ValidationError(f"FingerPhysics: max_states must be >= 4, got {max_states!r}")
        self.finger = finger
        self.scene = scene
        self.radius = float(scene.fingertip.radius)
        if self.radius >= finger.lengths[-1]:
            raise ValidationError(f"finger {finger.name!r}: the fingertip radius {self.radius} m must be shorter than "
                                  f"the last link ({finger.lengths[-1]} m)")
        self._mj = mujoco
        self.model, self.data = build_finger_model(finger, scene)
        self._tip_body = self.model.body("fingertip").id
        self._jacp = np.zeros((3, self.model.nv))
        self._dirs = finger.directions.copy()
        self._offs = finger.offsets.copy()
        self._cells = footprint_rings(self.radius, rings, sectors)
        self._laws: dict = {}  # contact laws by stack or press point (palpate.sim.contact.stack.point_law)
        for obj in scene.objects:  # solved now, not at the first contact the emulator must answer in time
            if obj.shape != "mesh":
                object_law(obj, *obj.position, obj.height, self.radius, MAX_DEPTH_OVER_RADIUS * self.radius,
                           cache=self._laws, lateral=False)
        qpts, self._qw = sensel_quadrature(scene.fingertip, order)
        # quadrature points on the sphere in the fingertip frame (origin at the centre, pad facing -z)
        self._qpts_tip = np.concatenate(
            [qpts, -np.sqrt(np.maximum(self.radius**2 - np.sum(qpts**2, -1), 0.0))[..., None]], axis=-1)
        self._retable = float(retable)
        self.max_states = int(max_states)
        self._tables: dict[tuple, _Under] = {}
        self._lock = threading.RLock()
        self._t: list[float] = []
        self._angles: list[np.ndarray] = []
        self._last_load: tuple[bytes, np.ndarray] | None = None
        self._shape = (scene.fingertip.rows, scene.fingertip.cols)

    # ---- kinematics ----------------------------------------------------------------------------------------
    def joints_from_servo(self, servo_angles: np.ndarray) -> np.ndarray:
        """Joint angles, rad, from servo shaft angles (rad, 0 at the centre tick), in the finger's joint order."""
        return self._dirs * np.asarray(servo_angles, dtype=float).reshape(-1) + self._offs

    def _place(self, q: np.ndarray) -> None:
        self.data.qpos[:] = q
        self._mj.mj_kinematics(self.model, self.data)

    # ---- contact -------------------------------------------------------------------------------------------
    def _object_under(self, x: float, y: float) -> ObjectSpec | None:
        # plain-float footprint test: this runs for every force evaluation of the emulator
        for obj in self.scene.objects:
            dx, dy = x - obj.position[0], y - obj.position[1]
            if obj.shape == "cylinder":
                if dx * dx + dy * dy <= obj.size[0] ** 2:
                    return obj
            elif abs(dx) <= obj.size[0] / 2 and abs(dy) <= obj.size[1] / 2:
                return obj
        return None

    def _footprint(self, x: float, y: float) -> _Under | None:
        """What a sphere centred above (x, y) meets, or None when no object is under it. Cached per ``retable``
        cell (laws of laterally uniform points are shared by their stack)."""
        obj = self._object_under(x, y)
        if obj is None:
            return None
        key = (obj.name, round(x / self._retable), round(y / self._retable))
        table = self._tables.get(key)
        if table is not None:
            return table
        foot = contact_geometry(obj, np.array([x, y]), self.scene.fingertip, cells=self._cells)
        # the column's layers on the table (finite thickness, skins): the emulator answers in real time and cannot
        # wait for the axisymmetric solve of an inclusion or an edge within reach
        law = object_law(obj, x, y, foot.first_contact, self.radius, MAX_DEPTH_OVER_RADIUS * self.radius,
                         cache=self._laws, lateral=False)
        if len(self._tables) > 4096:  # a long session sweeping a curved top must not grow without bound
            self._tables.clear()
        table = self._tables[key] = _Under(footprint=foot, law=law, obj=obj)
        return table

    def _force(self, centre: np.ndarray, quick: bool = False) -> _Load:
        """The surface's push on a sphere centred at ``centre``; ``quick`` skips sampling the footprint above a
        flat top (the emulator asks at every packet, in real time)."""
        if quick:
            obj = self._object_under(float(centre[0]), float(centre[1]))
            if obj is None or (obj.shape != "mesh" and float(centre[2]) - self.radius >= obj.height):
                return _Load(0.0, 0.0, None)
        under = self._footprint(float(centre[0]), float(centre[1]))
        if under is None:
            return _Load(0.0, 0.0, None)
        foot = under.footprint
        s = float(centre[2]) - self.radius  # height of the sphere's lowest point
        if s >= foot.first_contact:
            return _Load(0.0, 0.0, under)
        depth = foot.first_contact - s
        return _Load(float(law_pressure(under.law, np.array([depth]), foot.radius)[0] @ foot.area), depth, under)

    def _joint_torque(self, centre: np.ndarray, force_z: float) -> np.ndarray:
        # MuJoCo's Jacobian of the contact point (the sphere's lowest point), after _place
        self._mj.mj_comPos(self.model, self.data)
        point = centre - np.array([0.0, 0.0, self.radius])
        self._mj.mj_jac(self.model, self.data, self._jacp, None, point, self._tip_body)
        return self._jacp[2] * force_z

    def contact(self, q: np.ndarray, *, sensels: bool = False) -> FingerContact:
        """Contact state for joint angles ``q`` (rad); with ``sensels`` also the sensel pressures (Pa)."""
        q = np.asarray(q, dtype=float).reshape(-1)
        if q.shape != (len(self.finger.joints),) or not np.all(np.isfinite(q)):
            raise ValidationError(f"finger {self.finger.name!r}: expected {len(self.finger.joints)} finite joint "
                                  f"angles (rad), got {q!r}")
        with self._lock:
            self._place(q)
            centre = self.data.xpos[self._tip_body].copy()
            rot = self.data.xmat[self._tip_body].reshape(3, 3).copy()
            quat = self.data.xquat[self._tip_body].copy()
            load = self._force(centre)
            torque = self._joint_torque(centre, load.force) if load.force > 0 else np.zeros(len(q))
        pressure = None
        if sensels:
            pressure = self._sensel_pressure(centre[None], rot[None], [load.under])[0]
        tip = centre + rot @ np.array([0.0, 0.0, -self.radius])
        return FingerContact(tip, centre, quat, np.array([0.0, 0.0, load.force]), load.depth, torque, pressure)

    def _sensel_pressure(self, centres: np.ndarray, rots: np.ndarray, tables: list[_Under | None]) -> np.ndarray:
        """Mean pressure over each sensel, Pa, (n, rows, cols), for n fingertip placements; vectorised over the
        placements that share a contact law (the emulator's thread must not wait on a Python loop)."""
        out = np.zeros((len(centres),) + self._shape)
        s = centres[:, 2] - self.radius
        touching = [i for i, tb in enumerate(tables) if tb is not None and s[i] < tb.footprint.first_contact]
        groups: dict[int, list[int]] = {}
        for i in touching:
            groups.setdefault(id(tables[i].law), []).append(i)
        for members in groups.values():
            idx = np.array(members)
            law, obj = tables[idx[0]].law, tables[idx[0]].obj
            g_ref = np.array([tables[i].footprint.first_contact for i in idx])
            # the pad's quadrature points, carried by the tilted fingertip, sample the surface under it
            world = np.einsum("rckj,nij->nrcki", self._qpts_tip, rots[idx])
            rel = world[..., :2]
            gap = surface_heights(obj, (centres[idx, None, None, None, :2] + rel).reshape(-1, 2)).reshape(
                rel.shape[:-1]) - cap_height(self.scene.fingertip, rel)
            r_eq = equivalent_radius(g_ref[:, None, None, None] - gap, self.radius)
            r_eq = np.where(world[..., 2] < 0.0, r_eq, np.inf)  # only the lower hemisphere can touch
            basis = law.basis_at(np.minimum(g_ref - s[idx], law.max_depth))
            b, c = basis.radii, basis.coeffs
            p = np.zeros(r_eq.shape)
            for k in range(b.shape[1]):
                p += c[:, k, None, None, None] * np.sqrt(np.maximum(b[:, k, None, None, None] ** 2 - r_eq**2, 0.0))
            out[idx] = p @ self._qw
        return out

    # ---- the emulator's hooks ------------------------------------------------------------------------------
    def load(self, servo_angles: np.ndarray) -> np.ndarray:
        """Emulator load model: external torque on each servo shaft, N*m, for shaft angles in rad."""
        angles = np.asarray(servo_angles, dtype=float).reshape(-1)
        key = angles.tobytes()
        with self._lock:
            if self._last_load is not None and self._last_load[0] == key:
                return self._last_load[1]  # servos at rest are asked again at every packet
            self._place(self._dirs * angles + self._offs)
            centre = self.data.xpos[self._tip_body].copy()
            force_z = self._force(centre, quick=True).force
            torque = self._joint_torque(centre, force_z) if force_z > 0 else np.zeros(len(angles))
            # a servo mounted mirrored feels the joint torque with the opposite sign
            out = self._dirs * torque
            self._last_load = (key, out)
            return out

    def observe(self, t: float, servo_angles: np.ndarray) -> None:
        """Emulator observer: remember the servos' angles (rad) at time ``t`` (s, emulator clock)."""
        with self._lock:
            if self._t and t <= self._t[-1]:
                return  # the emulator never goes back in time; a repeated stamp adds nothing
            self._t.append(float(t))
            self._angles.append(np.array(servo_angles, dtype=float))
            if len(self._t) > self.max_states:
                half = len(self._t) // 2
                del self._t[:half], self._angles[:half]

    def reset(self) -> None:
        """Forget the recorded history."""
        with self._lock:
            self._t.clear()
            self._angles.clear()

    # ---- streams -------------------------------------------------------------------------------------------
    def trace(self, t0: float = -math.inf, t1: float = math.inf) -> PhysicsTrace:
        """What the servos did between t0 and t1 (s, emulator clock) as a physics trace.

        Raises ValidationError if fewer than two states were recorded in that window (the servos were not
        read, or the emulator has no ``observer``).
        """
        with self._lock:
            t = np.array(self._t)
            keep = np.nonzero((t >= t0) & (t <= t1))[0]
            angles = [self._angles[i] for i in keep]
        if len(angles) < 2:
            raise ValidationError(f"finger physics recorded {len(angles)} state(s) between t={t0} and t={t1} s; "
                                  "at least 2 are needed (is the emulator's observer set to FingerPhysics.observe?)")
        n = len(angles)
        centre, rot, quat = np.empty((n, 3)), np.empty((n, 3, 3)), np.empty((n, 4))
        force, depth = np.empty(n), np.empty(n)
        tables = []
        with self._lock:
            for i, a in enumerate(angles):
                self._place(self._dirs * a + self._offs)
                centre[i] = self.data.xpos[self._tip_body]
                rot[i] = self.data.xmat[self._tip_body].reshape(3, 3)
                quat[i] = self.data.xquat[self._tip_body]
                load = self._force(centre[i])
                force[i], depth[i] = load.force, load.depth
                tables.append(load.under)
        pressure = self._sensel_pressure(centre, rot, tables)
        first = tables[0]
        surface_z = first.footprint.first_contact if first is not None else 0.0
        trace = PhysicsTrace(
            t=t[keep], tip_position=centre, tip_quaternion=quat, sensel_pressure=pressure, force=force,
            indentation=depth, surface_z=surface_z,
            material=local_material(first.obj, float(centre[0, 0]), float(centre[0, 1]), surface_z).name
            if first is not None else None,
            meta={"fidelity": "finger-rigid", "finger": self.finger.name})
        trace.check_finite()
        return trace

    def taxel_frames(self, t0: float, t1: float, rng: np.random.Generator) -> list[TaxelFrame]:
        """Taxel frames (``scene.taxels`` model, e.g. 50 Hz, 8-bit) over [t0, t1], s, on the emulator clock."""
        return sample_taxels(self.trace(t0, t1), self.scene.taxels, self.scene.fingertip, rng)

    def truth(self, t0: float, t1: float) -> GroundTruth:
        """Ground truth over [t0, t1]: force (N), indentation (m) and material, at the recorded states."""
        return ground_truth(self.trace(t0, t1))

    def actuator_streams(self, seed: int = 0):
        """A ``streams(t0, t1) -> (frames, truth)`` callable for ``FingerActuator``; the n-th call's sensor noise
        draws from (seed, n), so a session replays identically given the same motion."""
        calls = [0]

        def streams(t0: float, t1: float):
            rng = np.random.default_rng([int(seed), calls[0]])
            calls[0] += 1
            trace = self.trace(t0, t1)
            return sample_taxels(trace, self.scene.taxels, self.scene.fingertip, rng), ground_truth(trace)

        return streams


def build_finger_model(finger: FingerChain, scene: Scene):
    """Compile the finger over the scene's objects with ``mujoco.MjSpec``; returns (model, data).

    Bodies ``link0``.. carry hinge joints named as in the description (axis +y: positive angles curl the finger
    down, as in :mod:`palpate.hardware.dynamixel.finger`); body ``fingertip`` is the sphere, its centre one tip
    radius behind the end of the last link, its frame turned so that the pad faces the link's direction (-z of
    the fingertip frame), with site ``pad`` at the kinematic tip point and sites ``sensel_i_j``. Nothing collides:
    the contact law is evaluated outside MuJoCo.
    """
    import mujoco


    radius = scene.fingertip.radius
    spec = mujoco.MjSpec()
    spec.modelname = f"palpate_finger_{finger.name}"
    spec.option.gravity = [0.0, 0.0, 0.0]  # the press is quasi-static; the arm's weight is the servos' business
    spec.worldbody.add_geom(name="table", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0.5, 0.5, 0.01])
    for obj in scene.objects:
        if obj.shape == "mesh":
            raise ValidationError(f"object {obj.name!r}: the finger physics presses boxes and cylinders (flat tops); "
                                  "a mesh needs the force along its normal")
        add_object(spec, obj)
    parent = spec.worldbody
    pos = [float(c) for c in finger.base]
    for j in finger.joints:
        body = parent.add_body(name=f"link_{j.name}", pos=pos)
        body.add_joint(name=j.name, type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0.0, 1.0, 0.0],
                       range=[j.lower, j.upper], limited=True)
        body.add_geom(type=mujoco.mjtGeom.mjGEOM_CAPSULE, fromto=[0.0, 0.0, 0.0, j.link_length, 0.0, 0.0],
                      size=[0.004, 0, 0], contype=0, conaffinity=0, mass=0.02)
        parent, pos = body, [j.link_length, 0.0, 0.0]
    # R_y(-pi/2): the fingertip frame's -z runs along the link, so pointing straight down it is the world frame
    half = -math.pi / 4
    tip = parent.add_body(name="fingertip", pos=[finger.lengths[-1] - radius, 0.0, 0.0],
                          quat=[math.cos(half), 0.0, math.sin(half), 0.0])
    tip.add_geom(name="tip", type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[radius, 0, 0], contype=0, conaffinity=0,
                 mass=0.01)
    tip.add_site(name="pad", pos=[0.0, 0.0, -radius])
    sites = sensel_sites(scene.fingertip)
    for i, k in np.ndindex(sites.shape[:2]):
        tip.add_site(name=f"sensel_{i}_{k}", pos=[float(c) for c in sites[i, k]])
    model = spec.compile()
    return model, mujoco.MjData(model)
