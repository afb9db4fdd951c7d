"""Speed and accuracy of each simulation fidelity: wall time per press-and-release, real-time factor, and the
force error against the reference mechanics of the block (its contact law, confirmed by the FE reference within
~1%: tests/test_fe_reference.py) at small (0.2-0.5 mm) and larger (1-1.9 mm) indentation.

Run: .venv/bin/python benchmarks/sim_fidelity.py [--quick]
One core (BLAS threads pinned to 1). Each row presses a 3 cm block of one material to 2 mm at 10 mm/s
(robot motion) and reports the median over repeats; "physics" times the fidelity's trace alone, "end-to-end"
adds the press profile and the sensor models (taxel frames, pose samples, ground truth).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402

import numpy as np  # noqa: E402
from bench_timing import median_of  # noqa: E402

from palpate.core.session.sources import PressTarget
from palpate.core.world.scene import Material, ObjectSpec, Scene
from palpate.sim.analytic import run_analytic_press
from palpate.sim.contact.stack import object_law
from palpate.sim.controller import press_profile  # noqa: E402
from palpate.sim.rigid import run_rigid_press  # noqa: E402
from palpate.sim.source import SimSource  # noqa: E402


def _force_error(trace, law, d_lo: float, d_hi: float) -> float:
    """Largest |F / F_ref - 1| while loading with d_lo < indentation < d_hi (m); NaN if never in that range."""
    d, f = trace.indentation, trace.force
    loading = np.arange(len(d)) < int(np.argmax(d))
    band = loading & (d > d_lo) & (d < d_hi)
    if not band.any():
        return float("nan")
    return float(np.max(np.abs(f[band] / law.force_at(d[band]) - 1.0)))


def _physics_call(fid: str, scene: Scene, obj: ObjectSpec, target: PressTarget, prof):
    """The fidelity's physics alone, as a no-argument callable."""
    if fid == "analytic":
        return lambda: run_analytic_press(scene, obj, prof)
    if fid == "rigid":
        return lambda: run_rigid_press(scene, obj, prof, timestep=0.002)
    from palpate.sim.flex.press import run_flex_press

    models: dict = {}  # the window is built on the first call and reused, as a SimSource does
    return lambda: run_flex_press(scene, obj, target, prof, seed=0, models=models)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer repeats and materials")
    args = parser.parse_args()
    repeats = 3 if args.quick else 10
    materials = (2e5,) if args.quick else (2e4, 2e5, 2e6)
    fidelities = ["analytic", "rigid"]
    try:
        import palpate.sim.flex.press  # noqa: F401

        fidelities.append("flex")
    except ImportError:
        pass
    import mujoco  # noqa: F401  (imported once up front so no row pays for it)

    print(f"{'fidelity':9} {'E [kPa]':>8} {'press [s]':>9} {'physics [ms]':>12} {'RTF phys':>9} "
          f"{'end-to-end [ms]':>15} {'RTF e2e':>8} {'|F err| 0.2-0.5mm':>17} {'|F err| 1-1.9mm':>15}")
    for young in materials:
        obj = ObjectSpec("block", "box", (0.1, 0.1, 0.03), (0.0, 0.0), Material("m", young))
        scene = Scene((obj,))
        target = PressTarget(0.0, 0.0, depth=0.002, speed=0.01)
        radius = scene.fingertip.radius
        law = object_law(obj, 0.0, 0.0, obj.height, radius, 0.003)
        for fid in fidelities:
            prof = press_profile(target, obj.height, radius=radius, timestep=0.002)
            physics = _physics_call(fid, scene, obj, target, prof)
            reps = repeats if fid != "flex" else 1
            try:
                t_phys, trace = median_of(physics, reps)
                source = SimSource(scene, fidelity=fid, seed=0)
                t_e2e, _ = median_of(lambda s=source, g=target: s.press(g), reps)
            except Exception as exc:  # report and go on: one broken fidelity must not hide the others
                print(f"{fid:9} {young / 1e3:8.0f}  failed: {exc}")
                continue
            small = _force_error(trace, law, 2e-4, 5e-4)
            large = _force_error(trace, law, 1e-3, 1.9e-3)
            print(f"{fid:9} {young / 1e3:8.0f} {prof.duration:9.3f} {t_phys * 1e3:12.2f} "
                  f"{prof.duration / t_phys:9.3g} {t_e2e * 1e3:15.2f} {prof.duration / t_e2e:8.3g} {small:17.2%} "
                  f"{large:15.2%}")
    print()
    print("analytic is the reference law itself on this block; rigid adds the drive and the footprint quadrature; "
          "flex's 5 mm cells resolve contacts from ~0.2 mm deep. Where each is valid: palpate bench (validity).")


if __name__ == "__main__":
    main()
