"""MuJoCo scenes built with ``mujoco.MjSpec`` from the plain description in :mod:`palpate.core.world.scene`.

A scene is a table (plane at z = 0), the objects (box, cylinder, or a trimesh-loaded mesh resting on the table)
and a fingertip: a sphere on a slide joint along the press axis, driven by a position actuator with joint
armature (the combination that tracked best on MuJoCo 4.0: a kinematic mocap tip gets no contact with a static
body), carrying a pose site and one site per sensel. Also here: the surface height and normal under a point,
which the controller and every fidelity level need. MuJoCo and trimesh are imported inside the functions.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.world.resources import models_dir
from palpate.core.world.scene import ObjectSpec, Scene
from palpate.sim.fingertip import sensel_sites

MODELS_DIR = models_dir()  # the shipped models/ (palpate.models), also from a wheel


@dataclass(frozen=True)
class FingerDrive:
    """The finger's drive: a position servo on a slide joint.

    Attributes:
        kp: servo stiffness, N/m.  kv: servo damping, N s/m.  armature: added inertia of the joint, kg.
        mass: fingertip body mass, kg.
    """

    kp: float = 5.0e4
    kv: float = 600.0
    armature: float = 0.5
    mass: float = 0.02

    def __post_init__(self) -> None:
        for name in ("kp", "kv", "armature", "mass"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValidationError(f"FingerDrive.{name} must be > 0, got {v!r}")


def load_mesh(obj: ObjectSpec):
    """The object's mesh as a trimesh.Trimesh in the world frame: scaled by obj.size, base on the table (z = 0),
    footprint centred on obj.position. Raises ValidationError naming the file if it is missing or not a mesh."""
    import trimesh

    path = Path(obj.mesh_path or "")
    if not path.is_absolute():
        path = MODELS_DIR / path
    if not path.is_file():
        raise ValidationError(f"object {obj.name!r}: mesh file {path} does not exist")
    try:
        mesh = trimesh.load(path, force="mesh")
    except Exception as exc:  # trimesh raises many types for bad files
        raise ValidationError(f"object {obj.name!r}: cannot read mesh {path}: {exc}") from exc
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise ValidationError(f"object {obj.name!r}: {path} holds no triangles")
    if not np.all(np.isfinite(mesh.vertices)):
        raise ValidationError(f"object {obj.name!r}: {path} has non-finite vertices")
    mesh = mesh.copy()
    mesh.apply_transform(np.diag([*map(float, obj.size), 1.0]))  # per-axis scale factors
    lo, hi = mesh.bounds
    mesh.apply_translation([obj.position[0] - (lo[0] + hi[0]) / 2, obj.position[1] - (lo[1] + hi[1]) / 2, -lo[2]])
    return mesh


def _top_hits(mesh, xy: np.ndarray, chunk: int = 256) -> tuple[np.ndarray, np.ndarray]:
    """Highest triangle of the mesh above each point (m, 2): its height (m; -inf where none) and face index.

    A vertical ray test in numpy (point-in-triangle in the xy plane, barycentric height), so no spatial-index
    package is needed; triangles are pre-filtered by their xy bounding boxes, points go in chunks.
    """
    tri = np.asarray(mesh.triangles, dtype=float)  # (T, 3, 3)
    lo = tri[:, :, :2].min(axis=1)
    hi = tri[:, :, :2].max(axis=1)
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    v0 = b[:, :2] - a[:, :2]
    v1 = c[:, :2] - a[:, :2]
    den = v0[:, 0] * v1[:, 1] - v1[:, 0] * v0[:, 1]
    ok = np.abs(den) > 1e-18  # triangles seen edge-on from above never hold the top surface
    height = np.full(len(xy), -np.inf)
    face = np.full(len(xy), -1)
    for start in range(0, len(xy), chunk):
        p = xy[start:start + chunk]
        cand = ok[None, :] & np.all((p[:, None, :] >= lo[None] - 1e-12) & (p[:, None, :] <= hi[None] + 1e-12), axis=2)
        pi, ti = np.nonzero(cand)
        if len(pi) == 0:
            continue
        d = p[pi] - a[ti, :2]
        u = (d[:, 0] * v1[ti, 1] - v1[ti, 0] * d[:, 1]) / den[ti]
        v = (v0[ti, 0] * d[:, 1] - d[:, 0] * v0[ti, 1]) / den[ti]
        inside = (u >= -1e-12) & (v >= -1e-12) & (u + v <= 1 + 1e-12)
        pi, ti, u, v = pi[inside], ti[inside], u[inside], v[inside]
        z = a[ti, 2] + u * (b[ti, 2] - a[ti, 2]) + v * (c[ti, 2] - a[ti, 2])
        order = np.lexsort((z, pi))  # per point, highest z last
        last = np.r_[pi[order][1:] != pi[order][:-1], True]
        sel = order[last]
        height[start + pi[sel]] = z[sel]
        face[start + pi[sel]] = ti[sel]
    return height, face


def surface_heights(obj: ObjectSpec, xy: np.ndarray, mesh=None) -> np.ndarray:
    """Height of the top surface under each point (m, 2), m; 0 (the table) off the object."""
    pts = np.atleast_2d(np.asarray(xy, dtype=float))
    if obj.shape in ("box", "cylinder"):
        return np.where(obj.contains_xy(pts), obj.height, 0.0)
    mesh = load_mesh(obj) if mesh is None else mesh
    height, _ = _top_hits(mesh, pts)
    return np.maximum(height, 0.0)


def surface_at(obj: ObjectSpec, x: float, y: float, mesh=None) -> tuple[float, np.ndarray]:
    """Surface height (m) and outward unit normal at (x, y) on the object's top. Raises if (x, y) misses it."""
    if obj.shape in ("box", "cylinder"):
        if not obj.contains_xy(np.array([[x, y]]))[0]:
            raise ValidationError(f"({x:.4f}, {y:.4f}) m is not on object {obj.name!r}")
        return obj.height, np.array([0.0, 0.0, 1.0])
    mesh = load_mesh(obj) if mesh is None else mesh
    height, face = _top_hits(mesh, np.array([[x, y]], dtype=float))
    if face[0] < 0:
        raise ValidationError(f"({x:.4f}, {y:.4f}) m is not on mesh object {obj.name!r}")
    normal = np.asarray(mesh.face_normals[face[0]], dtype=float)
    if normal[2] < 0:
        normal = -normal
    return float(height[0]), normal / np.linalg.norm(normal)


def add_object(spec, obj: ObjectSpec, mesh=None) -> None:
    import mujoco

    body = spec.worldbody.add_body(name=f"obj_{obj.name}")
    if obj.shape == "box":
        sx, sy, sz = obj.size
        body.pos = [obj.position[0], obj.position[1], sz / 2.0]
        body.add_geom(name=f"geom_{obj.name}", type=mujoco.mjtGeom.mjGEOM_BOX, size=[sx / 2, sy / 2, sz / 2])
    elif obj.shape == "cylinder":
        r, h = obj.size
        body.pos = [obj.position[0], obj.position[1], h / 2.0]
        body.add_geom(name=f"geom_{obj.name}", type=mujoco.mjtGeom.mjGEOM_CYLINDER, size=[r, h / 2, 0])
    else:
        mesh = load_mesh(obj) if mesh is None else mesh
        m = spec.add_mesh(name=f"mesh_{obj.name}")
        m.uservert = np.asarray(mesh.vertices, dtype=float).reshape(-1).tolist()
        m.userface = np.asarray(mesh.faces, dtype=int).reshape(-1).tolist()
        body.add_geom(name=f"geom_{obj.name}", type=mujoco.mjtGeom.mjGEOM_MESH, meshname=f"mesh_{obj.name}")


def build_press_model(
    scene: Scene, start: np.ndarray, axis: np.ndarray, *, timestep: float, drive: FingerDrive | None = None,
    travel: float = 0.05, meshes: dict | None = None, finger_only: bool = False,
):
    """Compile the press scene.

    Args:
        scene: objects and fingertip.
        start: tip-sphere centre at joint position 0, m (world frame).
        axis: unit press axis (the surface normal, pointing out of the object); the joint coordinate q moves the
            tip by q * axis.
        timestep: physics step, s.
        drive: finger servo parameters.
        travel: joint range either side of the start, m.
        meshes: pre-loaded trimesh meshes by object name (avoids reading files twice).
        finger_only: the finger's body, joint and drive alone (no table, objects or sites): its dynamics are the
            same when a fidelity applies its own contact law, and each step costs less.

    Returns:
        (model, data) with joint "press", actuator "press", site "pose" and sites "sensel_i_j" (not with
        ``finger_only``). The tip sphere does not collide (contype 0): each fidelity applies its own contact law.
    """
    import mujoco

    drive = FingerDrive() if drive is None else drive
    if not (np.isfinite(timestep) and timestep > 0):
        raise ValidationError(f"build_press_model: timestep must be > 0 s, got {timestep!r}")
    spec = mujoco.MjSpec()
    spec.modelname = "palpate_press"
    spec.option.timestep = float(timestep)
    spec.option.gravity = [0.0, 0.0, 0.0]  # the arm carries the finger; its weight is not part of the press
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    if not finger_only:
        spec.worldbody.add_geom(name="table", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0.5, 0.5, 0.01])
        for obj in scene.objects:
            add_object(spec, obj, (meshes or {}).get(obj.name))
    tip = scene.fingertip
    finger = spec.worldbody.add_body(name="fingertip", pos=[float(c) for c in start])
    finger.add_joint(name="press", type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[float(c) for c in axis],
                     armature=drive.armature, range=[-travel, travel], limited=True)
    finger.add_geom(name="tip", type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[tip.radius, 0, 0], mass=drive.mass,
                    contype=0, conaffinity=0)
    if not finger_only:
        finger.add_site(name="pose", pos=[0.0, 0.0, 0.0])
        sites = sensel_sites(tip)
        for i, j in np.ndindex(sites.shape[:2]):
            finger.add_site(name=f"sensel_{i}_{j}", pos=[float(c) for c in sites[i, j]],
                            size=[tip.sensel_size / 2, tip.sensel_size / 2, 1e-4], type=mujoco.mjtGeom.mjGEOM_BOX)
    act = spec.add_actuator(name="press", target="press", trntype=mujoco.mjtTrn.mjTRN_JOINT)
    act.set_to_position(kp=drive.kp, kv=drive.kv)
    act.ctrllimited = True
    act.ctrlrange = [-travel, travel]
    model = spec.compile()
    return model, mujoco.MjData(model)
