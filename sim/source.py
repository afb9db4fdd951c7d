"""The simulation as a press source (entry point ``sim`` in ``palpate.sources``).

``SimSource(scene).press(target)`` runs one press-and-release at the chosen fidelity and returns the same raw
streams a Tekscan pad and a Polhemus tracker give, with ground truth beside them.

Fidelity ``auto`` picks, per press, the cheapest fidelity whose force error against the FE reference, measured
in the validity table (models/validity_table.json, written by ``palpate bench``), is within the source's
``tolerance`` (a scenario's ``tolerance_pct``, default 5%); :mod:`palpate.sim.validity.choice` places the press in
the table and the reason it returns says where and with what predicted errors.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.perception.streams import PressRecording
from palpate.core.session.sources import PressTarget, check_seed
from palpate.core.world.scene import ObjectSpec, Scene, check_finite
from palpate.sim.analytic import material_under, run_analytic_press
from palpate.sim.bem.law import press_law
from palpate.sim.bem.press import run_bem_press
from palpate.sim.bem.wall import load_wall_table
from palpate.sim.blas import blas_controller, one_blas_thread
from palpate.sim.controller import ROBOT, PressProfile, Variability, press_profile
from palpate.sim.flex.model import SOLVER_ITERATIONS
from palpate.sim.flex.press import run_flex_press
from palpate.sim.flex.tables import FlexTables, load_flex_tables
from palpate.sim.footprint import rigid_depth_for_force
from palpate.sim.limits import MAX_DEPTH_OVER_THICKNESS, depth_refusal, layer_refusal, poisson_refusal
from palpate.sim.planned import PlannedPress
from palpate.sim.realism.profile import RealismProfile
from palpate.sim.realism.profile_file import resolve_profile
from palpate.sim.realism.stage import RealismSession
from palpate.sim.rigid import run_rigid_press
from palpate.sim.scene import load_mesh, surface_at
from palpate.sim.sensors import ground_truth, sample_poses, sample_taxels
from palpate.sim.stability import MAX_DEPTH_OVER_RADIUS, MAX_STEPS, check_iterations, law_depth
from palpate.sim.trace import PhysicsTrace, frame_rows
from palpate.sim.validity.choice import DEFAULT_TOLERANCE, Choice, explain_fidelity, image_note
from palpate.sim.validity.image_table import load_image_table
from palpate.sim.validity.table import load_table

FIDELITIES = ("auto", "analytic", "bem", "rigid", "flex")
class SimSource:
    """A simulated finger pressing objects of a scene.

    Args:
        scene: objects, fingertip and sensor models.
        fidelity: "auto", "analytic", "rigid" or "flex".
        seed: seed of everything random (press variability, sensor noise); the n-th press of a source draws
            from (seed, n), so a source replays identically.
        variability: "robot" (exact), "human" (the realism profile's human-like press) or a Variability.
        timestep: physics step, s (rigid default 2 ms, flex its own; analytic samples at the taxel rate).
        tolerance: largest predicted force error ``auto`` accepts, fraction (default 5%).
        max_steps: physics steps one press may take; a longer one is refused before it runs.
        flex_iterations: MuJoCo's iteration limit for a ``flex`` press (see
            :func:`palpate.sim.flex.press.run_flex_press`).
        realism: a realism profile (:mod:`palpate.sim.realism`): a preset or shipped profile's name, a TOML path,
            or a RealismProfile; None is ``ideal`` (the simulation exactly as without profiles). One source is one
            session (one pad equilibration, one clock synchronisation). Its finger pulp is in series with the
            press point's contact law; the validity table (``auto``) is about the mechanics alone.
        laws: a dict of contact laws (and the FE energies, meshes and wall references they keep) to share with
            other sources of the same fingertip, e.g. every source of a run; each entry keyed on all it depends
            on. A law solved deeper than a press needs serves it, so a source's numbers may depend on what the
            others pressed before, to within the law's tabulation.
    """

    #: modules every fidelity imports when it presses (checked by the run before any work starts)
    requires = ("mujoco",)

    def __init__(self, scene: Scene, fidelity: str = "auto", seed: int = 0,
                 variability: str | Variability = "robot", timestep: float | None = None,
                 tolerance: float = DEFAULT_TOLERANCE, max_steps: int = MAX_STEPS,
                 realism: str | Path | RealismProfile | None = None, flex_iterations: int = SOLVER_ITERATIONS,
                 laws: dict | None = None):
        if not isinstance(scene, Scene):
            raise ValidationError(f"SimSource: scene must be a Scene, got {type(scene).__name__}")
        if fidelity not in FIDELITIES:
            raise ValidationError(f"SimSource: fidelity must be one of {FIDELITIES}, got {fidelity!r}")
        if not (variability in ("robot", "human") if isinstance(variability, str) else
                isinstance(variability, Variability)):
            raise ValidationError(f"SimSource: variability must be 'robot', 'human' or a Variability, "
                                  f"got {variability!r}")
        if laws is not None and not isinstance(laws, dict):
            raise ValidationError(f"SimSource: laws must be a dict (a shared law cache) or None, got {laws!r}")
        self.realism = resolve_profile(realism)
        if isinstance(variability, str):
            variability = ROBOT if variability == "robot" else self.realism.press
        check_finite("SimSource", tolerance=tolerance, **({} if timestep is None else {"timestep": timestep}))
        if timestep is not None and not timestep > 0:
            raise ValidationError(f"SimSource: timestep must be > 0 s, got {timestep!r}")
        if not 0 < tolerance < 1:
            raise ValidationError(f"SimSource: tolerance must be a fraction in (0, 1), got {tolerance!r}")
        self.tolerance = float(tolerance)
        if not (isinstance(max_steps, int) and max_steps > 0):
            raise ValidationError(f"SimSource: max_steps must be a positive integer, got {max_steps!r}")
        self.max_steps = max_steps
        self.flex_iterations = check_iterations(flex_iterations, "SimSource: flex_iterations")
        self._table = None  # the validity table, read on the first ``auto`` decision
        self._images = None  # its image columns, likewise
        self._walls = None  # the bem rung's wall table, read on its first press
        self._blas = None  # the BLAS libraries' thread controller, found on the first contact law
        self.scene = scene
        self.fidelity = fidelity
        self.seed = check_seed(seed, "SimSource: seed")
        self.variability = variability
        self.timestep = timestep
        self._presses = 0
        self._meshes: dict = {}
        # contact laws by stack or press point (palpate.sim.contact.stack.point_law); given, shared with other sources
        self._laws: dict = {} if laws is None else laws
        self._law_memo: dict = {}  # the last law of each press point's arguments, while the law cache is unchanged
        self._pads: dict = {}  # the pad's sensel footprints by fingertip and contact centre (analytic)
        self._rigid_models: dict = {}  # compiled rigid press models (palpate.sim.rigid.press_model)
        self._force_tables: dict = {}  # rigid force against depth by law and footprint (rigid_depth_for_force)
        self._flex_models: dict = {}  # built flex windows (palpate.sim.flex.press.run_flex_press)
        self._flex_tables: FlexTables | None = None  # its calibration tables, read on the first flex press
        self._session = (None if self.realism.is_ideal else
                         RealismSession(self.realism, scene.fingertip, scene.taxels, self.seed))

    def _mesh(self, obj: ObjectSpec):
        if obj.shape == "mesh" and obj.name not in self._meshes:
            self._meshes[obj.name] = load_mesh(obj)
        return self._meshes[obj.name] if obj.shape == "mesh" else None

    def _blas_controller(self):
        """The BLAS libraries' thread controller, found once (palpate.sim.blas)."""
        if self._blas is None:
            self._blas = blas_controller()
        return self._blas

    def _law(self, obj: ObjectSpec, x: float, y: float, surface_z: float, max_depth: float):
        """The contact law at (x, y) (m), cached per press point; its FE solves (an inclusion, an edge within
        reach) run with BLAS on one thread."""
        # while the cache holds the same laws (no solve since, here or in a source sharing it), the last answer for
        # these arguments stands (saves the lookup's material probe of every repeated press point)
        key = (obj, x, y, surface_z, max_depth)
        try:
            hash(key)
        except TypeError:  # an object that cannot be hashed (e.g. its material map): by identity, kept alive below
            key = (id(obj), x, y, surface_z, max_depth)
        held = tuple(map(id, self._laws.values()))
        hit = self._law_memo.get(key)
        if hit is not None and hit[1] == held:
            return hit[0]
        with one_blas_thread(self._blas_controller()):
            law = press_law(obj, x, y, surface_z, self.scene.fingertip, max_depth, cache=self._laws)
        if len(self._law_memo) > 512:
            self._law_memo.clear()
        kept = tuple(self._laws.values())  # held, so that no id in the snapshot is reused while it is kept
        self._law_memo[key] = (law, tuple(map(id, kept)), kept, obj)
        return law

    def explain(self, target: PressTarget) -> Choice:
        """The fidelity a press at ``target`` would use, and why (for ``auto``: the rule that chose it)."""
        obj = self.scene.object_under(target.x, target.y)
        if obj is None:
            raise ValidationError(f"no object under the press target ({target.x:.4f}, {target.y:.4f}) m")
        if self.fidelity != "auto":
            if self._images is None:
                self._images = load_image_table()
            note = image_note(self.fidelity, self._images)
            return Choice(self.fidelity, f"{obj.name}: fidelity {self.fidelity!r} set by the scenario"
                          + (f"; note: {note}" if note else ""))
        return self._auto(obj, target)

    def _auto(self, obj: ObjectSpec, target: PressTarget, at: tuple[float, float] | None = None) -> Choice:
        """``auto``'s decision for a press at ``target`` (a force target's depth from the contact law at ``at``, m:
        where the press lands, default the target)."""
        if self._table is None:
            self._table = load_table()
        tip = self.scene.fingertip
        surface_z, _ = surface_at(obj, target.x, target.y, self._mesh(obj))
        depth = target.depth
        if target.force is not None:
            x, y = (target.x, target.y) if at is None else at
            deepest = min(MAX_DEPTH_OVER_RADIUS * tip.radius, MAX_DEPTH_OVER_THICKNESS * surface_z)
            law = self._law(obj, x, y, surface_z, deepest)
            reach = law.depth_for_force(target.force) if target.force < law.force[-1] else law.max_depth
            depth = reach if depth is None else min(depth, reach)
        if self._images is None:
            self._images = load_image_table()
        return explain_fidelity(obj, target, tip.radius, tolerance=self.tolerance, table=self._table, depth=depth,
                                images=self._images, surface_z=surface_z)

    def press(self, target: PressTarget) -> PressRecording:
        """One press-and-release at ``target``: taxel frames, pose samples and ground truth."""
        plan = self._plan(target)
        return self._record(plan, *self._sense(plan, self._physics(plan)))

    def press_many(self, targets, backend: str = "cpu") -> list[PressRecording]:
        """``[self.press(t) for t in targets]``, the analytic presses' physics batched on ``backend``
        (:func:`palpate.sim.batch.press_batch`)."""
        from palpate.sim.batch.press import press_batch  # the batch module builds on this one
        return press_batch(self, targets, backend)

    @staticmethod
    def press_across(pairs, backend: str = "cpu") -> list[PressRecording]:
        """``[source.press(target) for source, target in pairs]`` for several simulated sources (the environments of
        a vector) in one batch (:func:`palpate.sim.batch.press_across`)."""
        from palpate.sim.batch.press import press_across
        return press_across(pairs, backend)

    def _plan(self, target: PressTarget) -> PlannedPress:
        """Everything of a press before its physics, in press order (it draws the press's seeds and advances the
        source's press count): :func:`palpate.sim.batch.simulate_presses` plans a batch with it."""
        if not isinstance(target, PressTarget):
            raise ValidationError(f"SimSource: a press target must be a PressTarget, got {type(target).__name__}")
        obj = self.scene.object_under(target.x, target.y)
        if obj is None:
            raise ValidationError(f"no object under the press target ({target.x:.4f}, {target.y:.4f}) m")
        tip = self.scene.fingertip
        mesh = self._mesh(obj)
        surface_z, normal = surface_at(obj, target.x, target.y, mesh)
        # a fourth child for the realism keeps the first three (press, taxels, pose) as they always were
        s_profile, s_taxel, s_pose, s_real = np.random.SeedSequence([self.seed, self._presses]).spawn(4)
        timestep = self.timestep or 0.002
        seed = int(s_profile.generate_state(1)[0])
        by_radius = MAX_DEPTH_OVER_RADIUS * tip.radius
        # no deeper than the share of the material over the rigid base that every rung holds
        deepest = min(by_radius, MAX_DEPTH_OVER_THICKNESS * surface_z)
        capped = False
        if target.depth is not None and target.depth > deepest and target.force is not None:
            # "this force, but no deeper than ...": no press goes past the deepest allowed either
            target, capped = replace(target, depth=deepest), deepest < by_radius

        def profile_for(depth_for_force) -> PressProfile:
            # a person's press varies in depth (and a force limit may lie past the depth limit), but no finger
            # presses past what it can: the same draws, stopped at the deepest press allowed
            return press_profile(target, surface_z, radius=tip.radius, timestep=min(timestep, 0.002),
                                 variability=self.variability, seed=seed, normal=tuple(normal),
                                 depth_for_force=depth_for_force,
                                 max_depth=deepest if target.depth is not None else None)

        point = None
        if self.fidelity == "auto" and target.force is not None:
            # auto finds a force target's depth from the law where the press lands (the press's own draws put it
            # off the target by a fraction of a millimetre), which is the law the press then feels: one solve
            try:
                point = profile_for(lambda force: 1e-3)
            except ValidationError:
                self._presses += 1  # a press refused here was always counted (its decision came first)
                raise
            choice = self._auto(obj, target, at=(point.x, point.y))
        else:
            choice = self.explain(target)
        fidelity = choice.fidelity
        self._presses += 1
        # a material or a layer the rung does not hold: refused before its contact law is solved
        held = poisson_refusal(obj, fidelity) or layer_refusal(obj, fidelity)
        if held is not None:
            raise ValidationError(f"{obj.name}: {held}")
        if target.depth is not None and target.depth > deepest:
            if deepest < by_radius:
                raise ValidationError(f"{obj.name}: {depth_refusal(target.depth, surface_z)}")
            raise ValidationError(f"press target depth {target.depth * 1e3:.2f} mm is over {MAX_DEPTH_OVER_RADIUS} tip "
                                  f"radii ({tip.radius * 1e3:.1f} mm tip): the contact would reach the sphere's "
                                  f"equator; press at most {deepest * 1e3:.2f} mm deep")

        law = None
        real = None
        if target.force is None and self._session is None:
            profile = profile_for(None)
            if fidelity in ("analytic", "rigid"):
                law = self._law(obj, profile.x, profile.y, surface_z, law_depth(profile))
        else:
            # the same seed draws the same press point whatever the depth: find it, then invert the law felt there
            point = profile_for(lambda force: 1e-3) if point is None else point
            law = self._law(obj, point.x, point.y, surface_z, deepest)

            def depth_for_force(force: float) -> float:
                try:
                    if fidelity == "rigid":
                        # the force rigid will feel on this geometry (edges, curved tops), not the flat law's
                        centre = np.array([point.x, point.y]) + tip.radius * normal[:2]
                        return rigid_depth_for_force(obj, centre, tip, law, force, mesh, self._force_tables)
                    return law.depth_for_force(force)
                except ValidationError:
                    if target.depth is not None:
                        return float("inf")  # the depth comes first: the force limit is never reached
                    if deepest < by_radius:
                        raise ValidationError(
                            f"{obj.name}: the {force:.3g} N force target is not reached within the depth limit of "
                            f"{deepest * 1e3:.2f} mm ({MAX_DEPTH_OVER_THICKNESS:.0%} of the {surface_z * 1e3:.2f} mm "
                            "of material over the rigid base): use a lower force target or a thicker sample") from None
                    raise

            if self._session is None:
                profile = profile_for(depth_for_force)
            else:
                real = self._realism(obj, point, target, law, depth_for_force, s_real)
                profile = profile_for(real.bone_depth_for_force)
        if capped and profile.meta.get("force_target") is None:
            # the depth limit, not the user's, would stop this press short of its force: refused, not silent
            raise ValidationError(
                f"{obj.name}: the {target.force:.3g} N force target is not reached within the depth limit of "
                f"{deepest * 1e3:.2f} mm ({MAX_DEPTH_OVER_THICKNESS:.0%} of the {surface_z * 1e3:.2f} mm of material "
                "over the rigid base): use a lower force target or a thicker sample")
        physics_profile = profile
        if real is not None:
            # the pulp's share taken out of the bone's press; the force the person stops at is applied after the
            # physics (through the pulp and the softened material): the physics is held to the depth alone
            physics_profile = real.object_profile(profile)
            physics_profile = replace(physics_profile, meta=dict(physics_profile.meta, force_target=None))
        return PlannedPress(target, obj, choice, mesh, profile, physics_profile, law, real, timestep, seed, s_taxel,
                            s_pose, self._presses - 1)

    def _physics(self, plan: PlannedPress) -> PhysicsTrace:
        """The press's physics at its fidelity (the one step a batch backend may take over for analytic presses); a
        rigid press's sensel pressures only at the rows its frames read (:func:`~palpate.sim.trace.frame_rows`)."""
        obj, physics_profile, law, timestep, mesh = plan.obj, plan.physics_profile, plan.law, plan.timestep, plan.mesh
        fidelity, target, seed = plan.choice.fidelity, plan.target, plan.seed
        if fidelity == "analytic":
            trace = run_analytic_press(self.scene, obj, physics_profile, law=law, pads=self._pads)
        elif fidelity == "bem":
            if self._walls is None:
                self._walls = load_wall_table()
            def law_for(max_depth: float):  # a buried change's force comes from the point's law, cached here
                return self._law(obj, physics_profile.x, physics_profile.y, physics_profile.surface_z, max_depth)

            with one_blas_thread(self._blas_controller()):
                trace = run_bem_press(self.scene, obj, physics_profile, walls=self._walls, law_for=law_for)
        elif fidelity == "rigid":
            # rows no frame reads (all when the realism draws the image anew) would cost a table read a step for nothing
            rate, drawn = self.scene.taxels.rate, plan.real is not None and plan.real.draws_image(plan.profile)
            rows = (lambda t: np.zeros(len(t), dtype=bool)) if drawn else (lambda t: frame_rows(t, rate))
            # its tables' BLAS products are small: other threads would only wait for a core and spin
            with one_blas_thread(self._blas_controller()):
                trace = run_rigid_press(self.scene, obj, physics_profile, timestep=timestep, mesh=mesh, law=law,
                                        max_steps=self.max_steps, models=self._rigid_models, pressure_rows=rows)
        else:
            # flex has its own default step (up to 10 ms, palpate.sim.flex.press.default_timestep; implicit elasticity)
            if self._flex_tables is None:
                self._flex_tables = load_flex_tables()
            trace = run_flex_press(self.scene, obj, target, physics_profile, timestep=self.timestep, seed=seed,
                                   models=self._flex_models, max_steps=self.max_steps,
                                   iterations=self.flex_iterations, tables=self._flex_tables)
        return trace

    def _sense(self, plan: PlannedPress, trace: PhysicsTrace):
        """The trace as the sensors see it: (trace, pose spec, tracker latency s, taxel response or None) after the
        press's realism, when it has one (its pad image drawn at the rows the frames read)."""
        real, profile = plan.real, plan.profile
        pose_spec, latency, response = self.scene.pose, 0.0, None
        if real is not None:
            trace = real.finish(trace, profile, frame_rows(trace.t, self.scene.taxels.rate))
            pose_spec, latency, response = real.pose_spec(pose_spec), real.latency, real.taxel_response
        return trace, pose_spec, latency, response

    def _record(self, plan: PlannedPress, trace: PhysicsTrace, pose_spec, latency: float, response,
                frames=None, poses=None) -> PressRecording:
        """The press's recording: its sensors sampled from ``trace`` (or the ``frames`` and ``poses`` a batch
        sampled alike), ground truth and provenance."""
        real, profile, target, obj = plan.real, plan.profile, plan.target, plan.obj
        fidelity, choice, tip = plan.choice.fidelity, plan.choice, self.scene.fingertip
        if frames is None:
            frames = sample_taxels(trace, self.scene.taxels, tip, np.random.default_rng(plan.s_taxel),
                                   response=response)
        if poses is None:
            poses = sample_poses(trace, pose_spec, np.random.default_rng(plan.s_pose), latency=latency)
        meta = {
            "source": "sim", "fidelity": fidelity, "fidelity_reason": choice.reason, "object": obj.name,
            "material": trace.material, "seed": self.seed, "press_index": plan.index,
            "target": {"x": target.x, "y": target.y, "depth": target.depth, "force": target.force,
                       "speed": target.speed, "hold": target.hold, "label": target.label},
            "profile": {k: v for k, v in profile.meta.items() if k != "phases"}, "phases": profile.meta["phases"],
            "physics": trace.meta,
            # counted beside the taxel frames' saturation (palpate.core.perception.streams.solver_warning_steps)
            "solver_warning_steps": int(trace.meta.get("solver_warnings", {}).get("inertia_steps", 0)),
        }
        if real is not None:
            meta["realism"] = real.meta()
        return PressRecording(frames=frames, poses=poses, truth=ground_truth(trace), meta=meta)

    def _realism(self, obj: ObjectSpec, point: PressProfile, target: PressTarget, law, depth_for_force,
                 stream: np.random.SeedSequence):
        """This press's realism (:meth:`RealismSession.press`) at the drawn press point, planned on its law."""

        def planning_depth(force: float) -> float:
            try:
                d = depth_for_force(force) if force < law.force[-1] else float("inf")
            except ValidationError:
                d = float("inf")
            if np.isfinite(d):
                return d
            # past the deepest press allowed: Hertz's shape from the law's end, only to tabulate the series law
            return law.max_depth * (force / law.force[-1]) ** (2.0 / 3.0)

        planned = target.depth if target.depth is not None else planning_depth(target.force)
        under = material_under(obj, point.x, point.y, point.surface_z)
        return self._session.press(obj.name, point.x, point.y, planning_depth, 2.0 * planned + 0.01,
                                   np.random.default_rng(stream), tail_scale=point.meta.get("tail_scale", 1.0),
                                   material=None if under is None else under.name)
