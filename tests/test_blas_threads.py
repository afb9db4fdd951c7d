"""The contact laws' FE solves (an inclusion within reach) run with BLAS on one thread wherever a press asks for a
law: the source, the analytic and the rigid rung called directly; BLAS's own thread count is back afterwards."""

from __future__ import annotations

import pytest

pytest.importorskip("skfem")
threadpoolctl = pytest.importorskip("threadpoolctl")

from palpate.core.session.sources import PressTarget  # noqa: E402
from palpate.core.world.scene import FingertipSpec, Inclusion, Material, ObjectSpec, Scene  # noqa: E402
from palpate.sim import analytic, rigid, source  # noqa: E402
from palpate.sim.controller import press_profile  # noqa: E402

R = 0.008


def _blas_threads() -> list[int]:
    return [i["num_threads"] for i in threadpoolctl.threadpool_info() if i["user_api"] == "blas"]


def _lump() -> ObjectSpec:
    return ObjectSpec("lump", "box", (0.08, 0.08, 0.03), (0.0, 0.0), Material("foam", 1e5, 0.45),
                      inclusions=(Inclusion(Material("hard", 2e6, 0.4), "sphere", (0.0, 0.0, 0.024), (0.005,)),))


@pytest.mark.parametrize("module", [source, analytic, rigid], ids=["source", "analytic", "rigid"])
def test_a_press_asks_for_its_law_on_one_blas_thread(monkeypatch, module):
    seen = []
    real = module.press_law

    def spy(*args, **kwargs):
        seen.append(_blas_threads())
        return real(*args, **kwargs)

    monkeypatch.setattr(module, "press_law", spy)
    obj = _lump()
    scene = Scene(objects=(obj,), fingertip=FingertipSpec(radius=R))
    target = PressTarget(0.0, 0.0, depth=0.001, speed=0.01)
    before = _blas_threads()
    if module is source:
        source.SimSource(scene, fidelity="analytic").press(target)
    else:
        profile = press_profile(target, obj.height, radius=R, timestep=0.002)
        run = analytic.run_analytic_press if module is analytic else rigid.run_rigid_press
        run(scene, obj, profile)
    assert seen and all(s and set(s) == {1} for s in seen), seen
    assert _blas_threads() == before
