"""The analytic, rigid and flex rungs against plain references of the same physics, measured in one run.

One 4 mm press at 10 mm/s (about 1.4 s of press) on a 200 kPa block 30 mm thick, its contact law solved once (a
SimSource keeps it, with the analytic rung's pad footprints and the rigid rung's compiled model: what every press
after a point's first one pays):

- analytic: :func:`palpate.sim.analytic.run_analytic_press` (the law's force and per-sensel pressure at every taxel
  sample) against a vectorised numpy press of the same samples: Hertz's force and Hertz's pressure averaged over
  each sensel by a 6x6 Gauss-Legendre rule (the plain reference: what the rung computes, on a half-space; the rung
  integrates each footprint in closed form);
- rigid: :func:`palpate.sim.rigid.run_rigid_press` (the MuJoCo finger under the law, stepped by MuJoCo's step
  read as an affine map; force table, sensel image) against bare MuJoCo stepping of the same compiled model, the
  servo driven along the same setpoints with a constant applied force (the plain reference: the stepping alone);
- flex: :func:`palpate.sim.flex.press.run_flex_press` (the deformable block's window, built once and kept as a
  SimSource keeps it; contact forces, mesh correction and sensel image every step) against bare MuJoCo stepping of
  the same compiled window along the very controls the rung gave its drive;
- and each rung's whole press through ``SimSource.press`` (profile, rung, taxel and pose sampling) beside them.

Rounds interleave rung and reference, so the machine's load hits both alike; each prints its median CPU time
(``time.process_time``) per press and the ratio to its reference.

Run: .venv/bin/python benchmarks/speed_rungs.py [--rounds 20]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from palpate.core.session.sources import PressTarget
from palpate.core.world.scene import FingertipSpec, Material, ObjectSpec, Scene
from palpate.sim.analytic import run_analytic_press
from palpate.sim.controller import press_profile
from palpate.sim.fingertip import sensel_quadrature
from palpate.sim.flex.press import run_flex_press
from palpate.sim.flex.tables import load_flex_tables
from palpate.sim.rigid import run_rigid_press
from palpate.sim.scene import build_press_model
from palpate.sim.source import SimSource
from palpate.sim.stability import law_depth

TIMESTEP = 0.002


def block_scene() -> Scene:
    """A 200 kPa, nu 0.45 block 30 mm thick under the default fingertip."""
    obj = ObjectSpec("block", "box", (0.1, 0.1, 0.03), (0.0, 0.0), Material("gel", 2e5, 0.45))
    return Scene(objects=(obj,), fingertip=FingertipSpec())


def numpy_press(depth: np.ndarray, young_eff: float, radius: float, points: np.ndarray, weights: np.ndarray):
    """The plain reference: Hertz force (N) and mean Hertz pressure per sensel (Pa) at indentations ``depth`` (m),
    over quadrature ``points`` (rows, cols, q, 2) m with ``weights`` (q,)."""
    force = 4.0 / 3.0 * young_eff * np.sqrt(radius) * depth**1.5
    a2 = radius * depth
    r2 = np.sum(points**2, axis=-1)
    p = 2.0 * young_eff / (np.pi * radius) * np.sqrt(np.maximum(a2[:, None, None, None] - r2[None], 0.0))
    return force, p @ weights


def bare_stepping(model, data, ctrl: list[float], force: float) -> None:
    """The plain reference of rigid and flex: MuJoCo steps of the press model along ``ctrl``, a constant force
    applied to the first degree of freedom."""
    import mujoco

    step = mujoco.mj_step
    qfrc, dctrl = data.qfrc_applied, data.ctrl
    for c in ctrl:
        qfrc[0] = force
        dctrl[0] = c
        step(model, data)


def recorded_controls(run) -> list[float]:
    """The control of every MuJoCo step ``run()`` takes, in order (what a rung told its drive)."""
    import mujoco

    ctrl: list[float] = []
    step = mujoco.mj_step

    def recording(model, data) -> None:
        ctrl.append(float(data.ctrl[0]))
        step(model, data)

    mujoco.mj_step = recording
    try:
        run()
    finally:
        mujoco.mj_step = step
    return ctrl


def _cpu(fn) -> float:
    c0 = time.process_time()
    fn()
    return time.process_time() - c0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=20, help="interleaved presses of each kind (default 20)")
    args = ap.parse_args()
    if args.rounds < 1:
        ap.error("--rounds must be >= 1")

    import mujoco

    scene = block_scene()
    obj, tip = scene.objects[0], scene.fingertip
    target = PressTarget(0.0, 0.0, depth=0.004, speed=0.01)
    profile = press_profile(target, obj.height, radius=tip.radius, timestep=TIMESTEP)
    source = {f: SimSource(scene, fidelity=f, seed=0) for f in ("analytic", "rigid", "flex")}
    law = source["rigid"]._law(obj, profile.x, profile.y, profile.surface_z, law_depth(profile))
    for s in source.values():
        s.press(target)  # each source solves its law once

    # the analytic rung's samples, for the reference
    pads: dict = {}  # the pad's footprints, kept as a SimSource keeps them
    models: dict = {}  # the rigid rung's compiled model, likewise
    trace = run_analytic_press(scene, obj, profile, law=law, pads=pads)
    depth = trace.indentation
    points, weights = sensel_quadrature(tip, 6)
    young_eff = obj.material.effective_modulus

    # the rigid rung's model (the finger alone) and setpoints, for the reference
    centres = profile.centres()
    model, data = build_press_model(scene, centres[0], np.array([0.0, 0.0, 1.0]), timestep=TIMESTEP,
                                    finger_only=True)
    model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
    n = int(np.ceil(profile.duration / TIMESTEP)) + 1
    t = profile.t[0] + TIMESTEP * np.arange(n)
    ctrl = np.interp(t, profile.t, profile.z - profile.z[0]).tolist()

    def bare() -> None:
        mujoco.mj_resetData(model, data)
        bare_stepping(model, data, ctrl, 1.0)

    # the flex rung's window and controls, for the reference
    flex_models: dict = {}
    tables = load_flex_tables()

    def flex() -> None:
        run_flex_press(scene, obj, target, profile, models=flex_models, tables=tables)

    flex_ctrl = recorded_controls(flex)
    ((flex_model, flex_data),) = flex_models.values()

    def flex_bare() -> None:
        mujoco.mj_resetData(flex_model.model, flex_data)
        mujoco.mj_forward(flex_model.model, flex_data)
        bare_stepping(flex_model.model, flex_data, flex_ctrl, 0.0)

    cases = {
        "analytic": (lambda: run_analytic_press(scene, obj, profile, law=law, pads=pads),
                     lambda: numpy_press(depth, young_eff, tip.radius, points, weights)),
        "rigid": (lambda: run_rigid_press(scene, obj, profile, timestep=TIMESTEP, law=law, models=models), bare),
        "flex": (flex, flex_bare),
    }
    times: dict[str, list[tuple[float, float, float]]] = {k: [] for k in cases}
    for _ in range(args.rounds):
        for name, (rung, ref) in cases.items():
            times[name].append((_cpu(rung), _cpu(ref), _cpu(lambda name=name: source[name].press(target))))

    print(f"one {target.depth * 1e3:.0f} mm press at {target.speed * 1e3:.0f} mm/s ({profile.duration:.2f} s), "
          f"{len(depth)} taxel samples, {n} MuJoCo steps; median CPU over {args.rounds} rounds")
    print(f"{'rung':10s} {'rung ms':>9s} {'reference ms':>13s} {'ratio':>7s} {'SimSource.press ms':>19s} "
          f"{'ratio':>7s}  reference")
    refs = {"analytic": "numpy Hertz force + sensel image", "rigid": "bare MuJoCo stepping, same model",
            "flex": f"bare MuJoCo stepping, same window, same {len(flex_ctrl)} controls"}
    for name, rows in times.items():
        rung, ref, whole = np.median(np.array(rows), axis=0) * 1e3
        print(f"{name:10s} {rung:9.3f} {ref:13.3f} {rung / ref:7.2f} {whole:19.3f} {whole / ref:7.2f}  {refs[name]}")


if __name__ == "__main__":
    main()
