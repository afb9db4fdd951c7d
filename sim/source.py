"""The simulation as a press source (entry point ``sim`` in ``palpate.sources``).

``SimSource(scene).press(target)`` runs one press-and-release at the chosen fidelity and returns the same raw
streams a Tekscan pad and a Polhemus tracker give, with ground truth beside them.

Fidelity ``auto`` models only what the pressed object requires (:func:`explain_fidelity` says why; the numbers
are from ``palpate bench`` / benchmarks/tradeoff.py, which measures them):
  - ``flex`` if the object has layers, inclusions or a haptic-material map (the local contact laws of the other
    levels cannot see below the surface), or the press is deeper than 20% of the object's height (large
    indentation: the half-space and local-kernel levels ignore the bottom);
  - ``analytic`` for a homogeneous box whose top is flat under the whole contact, at least 5 contact radii
    (a = sqrt(R d)) thick, with the press point at least 3 contact radii plus the tip radius from every edge, and
    depth <= 0.35 tip radii: there the sphere's force stays within 5% of Hertz (measured: 1% at d/R 0.06,
    3.7% at 0.25, 5.4% at 0.375, 7.2% at 0.5) at ~1/4 of rigid's cost per press;
  - ``rigid`` otherwise (cylinders near their rim, meshes and curved tops, thin or small objects, deeper presses):
    its kernel follows the real sphere and surface, converged already at 5 ms (0.05% from the 0.25 ms reference).
"""

from __future__ import annotations

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.perception.streams import PressRecording
from palpate.core.session.sources import PressTarget
from palpate.core.world.scene import ObjectSpec, Scene
from palpate.sim.analytic import run_analytic_press
from palpate.sim.controller import HUMAN, ROBOT, Variability, press_profile
from palpate.sim.effective_modulus import depth_for_force
from palpate.sim.flex import run_flex_press
from palpate.sim.rigid import run_rigid_press
from palpate.sim.scene import load_mesh, surface_at
from palpate.sim.sensors import ground_truth, sample_poses, sample_taxels

FIDELITIES = ("auto", "analytic", "rigid", "flex")


#: Largest depth / tip radius for ``analytic``: the sphere's force is within 5% of Hertz up to here.
ANALYTIC_MAX_DEPTH_OVER_RADIUS = 0.35
#: Depth / object height beyond which the press is "large indentation" and needs ``flex``.
FLEX_DEPTH_OVER_HEIGHT = 0.2


def explain_fidelity(obj: ObjectSpec, target: PressTarget, radius: float) -> tuple[str, str]:
    """The cheapest fidelity valid for pressing ``obj`` at ``target``, and a one-line reason (module docstring).

    A force-only target is taken as 0.25 tip radii deep (a typical palpation press).
    """
    if obj.layers or obj.inclusions or obj.material_map is not None:
        what = "layers" if obj.layers else "inclusions" if obj.inclusions else "a haptic-material map"
        return "flex", f"{obj.name}: has {what}; only flex resolves material below the surface"
    depth = target.depth if target.depth is not None else 0.25 * radius
    if depth > FLEX_DEPTH_OVER_HEIGHT * obj.height:
        return "flex", (f"{obj.name}: depth {depth * 1e3:.1f} mm is over {FLEX_DEPTH_OVER_HEIGHT:.0%} of its "
                        f"{obj.height * 1e3:.1f} mm height (large indentation: the bottom matters)")
    if obj.shape != "box":
        return "rigid", f"{obj.name}: {obj.shape} top is curved or finite; rigid follows the real surface"
    a = np.sqrt(radius * depth)
    half = np.asarray(obj.size[:2]) / 2.0
    edge = float(np.min(half - np.abs(np.array([target.x, target.y]) - np.asarray(obj.position))))
    if obj.height < 5.0 * a:
        return "rigid", (f"{obj.name}: {obj.height * 1e3:.1f} mm thick is under 5 contact radii "
                         f"({5e3 * a:.1f} mm); Hertz's half-space does not hold")
    if edge < 3.0 * a + radius:
        return "rigid", (f"{obj.name}: press {edge * 1e3:.1f} mm from an edge, under 3 contact radii + tip radius "
                         f"({(3 * a + radius) * 1e3:.1f} mm); Hertz's half-space does not hold")
    if depth > ANALYTIC_MAX_DEPTH_OVER_RADIUS * radius:
        return "rigid", (f"{obj.name}: depth {depth / radius:.2f} tip radii is over {ANALYTIC_MAX_DEPTH_OVER_RADIUS}; "
                         "the sphere's force departs from Hertz by more than 5%")
    return "analytic", (f"{obj.name}: homogeneous, thick and flat under the contact, depth {depth / radius:.2f} "
                        "tip radii; Hertz within 5% at ~1/4 of rigid's cost")


def choose_fidelity(obj: ObjectSpec, target: PressTarget, radius: float) -> str:
    """The cheapest fidelity valid for pressing ``obj`` at ``target`` (see :func:`explain_fidelity`)."""
    return explain_fidelity(obj, target, radius)[0]


class SimSource:
    """A simulated finger pressing objects of a scene.

    Args:
        scene: objects, fingertip and sensor models.
        fidelity: "auto", "analytic", "rigid" or "flex".
        seed: seed of everything random (press variability, sensor noise); the n-th press of a source draws
            from (seed, n), so a source replays identically.
        variability: "robot" (exact), "human" (default human-like variability) or a Variability.
        timestep: physics step, s (rigid default 2 ms, flex default 5 ms; analytic samples at the taxel rate).
    """

    #: modules every fidelity imports when it presses (checked by the run before any work starts)
    requires = ("mujoco",)

    def __init__(self, scene: Scene, fidelity: str = "auto", seed: int = 0,
                 variability: str | Variability = "robot", timestep: float | None = None):
        if fidelity not in FIDELITIES:
            raise ValidationError(f"SimSource: fidelity must be one of {FIDELITIES}, got {fidelity!r}")
        if isinstance(variability, str):
            if variability not in ("robot", "human"):
                raise ValidationError(f"SimSource: variability must be 'robot', 'human' or a Variability, "
                                      f"got {variability!r}")
            variability = ROBOT if variability == "robot" else HUMAN
        if timestep is not None and not (np.isfinite(timestep) and timestep > 0):
            raise ValidationError(f"SimSource: timestep must be > 0 s, got {timestep!r}")
        self.scene = scene
        self.fidelity = fidelity
        self.seed = int(seed)
        self.variability = variability
        self.timestep = timestep
        self._presses = 0
        self._meshes: dict = {}

    def _mesh(self, obj: ObjectSpec):
        if obj.shape != "mesh":
            return None
        if obj.name not in self._meshes:
            self._meshes[obj.name] = load_mesh(obj)
        return self._meshes[obj.name]

    def explain(self, target: PressTarget) -> tuple[str, str]:
        """The fidelity a press at ``target`` would use, and why (for ``auto``: the rule that chose it)."""
        obj = self.scene.object_under(target.x, target.y)
        if obj is None:
            raise ValidationError(f"no object under the press target ({target.x:.4f}, {target.y:.4f}) m")
        if self.fidelity != "auto":
            return self.fidelity, f"{obj.name}: fidelity {self.fidelity!r} set by the scenario"
        return explain_fidelity(obj, target, self.scene.fingertip.radius)

    def press(self, target: PressTarget) -> PressRecording:
        """One press-and-release at ``target``: taxel frames, pose samples and ground truth."""
        obj = self.scene.object_under(target.x, target.y)
        if obj is None:
            raise ValidationError(f"no object under the press target ({target.x:.4f}, {target.y:.4f}) m")
        tip = self.scene.fingertip
        fidelity = self.fidelity if self.fidelity != "auto" else choose_fidelity(obj, target, tip.radius)
        mesh = self._mesh(obj)
        surface_z, normal = surface_at(obj, target.x, target.y, mesh)
        s_profile, s_taxel, s_pose = np.random.SeedSequence([self.seed, self._presses]).spawn(3)
        self._presses += 1
        timestep = self.timestep or 0.002
        profile = press_profile(
            target, surface_z, radius=tip.radius, timestep=min(timestep, 0.002), variability=self.variability,
            seed=int(s_profile.generate_state(1)[0]), normal=tuple(normal),
            # E*_eff at the radius the press reaches (layers, inclusions): exactly Hertz on one material
            depth_for_force=lambda f: depth_for_force(obj, target.x, target.y, surface_z, tip.radius, f),
        )
        if fidelity == "analytic":
            trace = run_analytic_press(self.scene, obj, profile)
        elif fidelity == "rigid":
            trace = run_rigid_press(self.scene, obj, profile, timestep=timestep, mesh=mesh)
        else:
            # flex has its own default step (5 ms: >= 1x real time at the default resolution, see
            # benchmarks/flex_resolution.py); the rigid default of 2 ms would make it 2.5x slower.
            trace = run_flex_press(self.scene, obj, target, profile, timestep=self.timestep,
                                   seed=int(s_profile.generate_state(1)[0]))
        frames = sample_taxels(trace, self.scene.taxels, tip, np.random.default_rng(s_taxel))
        poses = sample_poses(trace, self.scene.pose, np.random.default_rng(s_pose))
        meta = {
            "source": "sim", "fidelity": fidelity, "object": obj.name, "material": trace.material,
            "seed": self.seed, "press_index": self._presses - 1,
            "target": {"x": target.x, "y": target.y, "depth": target.depth, "force": target.force,
                       "speed": target.speed, "hold": target.hold, "label": target.label},
            "profile": {k: v for k, v in profile.meta.items() if k != "phases"}, "phases": profile.meta["phases"],
            "physics": trace.meta,
        }
        return PressRecording(frames=frames, poses=poses, truth=ground_truth(trace), meta=meta)
