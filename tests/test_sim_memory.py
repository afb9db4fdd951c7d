"""End to end in simulation: rigid-fidelity presses -> core signal path -> haptic memory.

Three reference materials (20 kPa, 200 kPa, 2 MPa blocks) are pressed the way a person would (human-like
variability in speed, depth, force and position, seeded), each press goes through the same stack a hardware
recording would (sync -> features -> segmentation -> 3/2-law fits), and the per-press parameters train a
haptic memory that must tell the materials apart in leave-one-out cross-validation, as in seed 000 sec. 6.8.2.
"""

from __future__ import annotations

import numpy as np
import pytest

from palpate.core.perception.crossval import leave_one_out
from palpate.core.perception.fit import fit_press
from palpate.core.perception.memory import HapticMemory
from palpate.core.perception.pipeline import presses_from_recording
from palpate.core.session.sources import PressTarget
from palpate.core.world.scene import Material, ObjectSpec, Scene
from palpate.sim.source import SimSource

MATERIALS = {"soft": 2e4, "medium": 2e5, "hard": 2e6}  # Pa
PRESSES = 10  # per material, as in the thesis experiment
# Press to 4 mm unless 15 N comes first: the soft and medium blocks reach the depth, the hard one stops on
# force near 1.5 mm (about 10-13 N after the drive's compliance), where its contact has spread past the inner
# four sensels of the 2.5 mm pad; at 5 N it stays inside them, c_A is constant and the cutaneous fit undefined.
TARGET = dict(depth=0.004, force=15.0, speed=0.01)


def _press_params(name: str, young: float, seed: int, n: int) -> tuple[np.ndarray, list[dict]]:
    """(n, 4) [n1, n2, a1, a2] of n human-like presses on a block, and each press's provenance."""
    block = ObjectSpec("block", "box", (0.1, 0.1, 0.03), (0.0, 0.0), Material(name, young))
    source = SimSource(Scene((block,)), fidelity="rigid", seed=seed, variability="human")
    rows, metas = [], []
    for _ in range(n):
        rec = source.press(PressTarget(0.0, 0.0, **TARGET))
        seg = presses_from_recording(rec)
        assert len(seg.presses) == 1, f"{name}: expected one press, rejected {seg.rejected}"
        rows.append(fit_press(seg.presses[0]).params)
        metas.append(rec.meta)
    return np.array(rows), metas


@pytest.fixture(scope="module")
def training():
    params, labels, metas = [], [], {}
    for k, (name, young) in enumerate(MATERIALS.items()):
        p, metas[name] = _press_params(name, young, seed=100 + k, n=PRESSES)
        params.append(p)
        labels += [name] * PRESSES
    return np.vstack(params), labels, metas


def test_presses_vary_like_a_person_and_stop_at_depth_or_force(training):
    params, labels, metas = training
    assert np.all(np.isfinite(params))
    depths = {name: np.array([m["profile"]["depth"] for m in ms]) for name, ms in metas.items()}
    forced = {name: [m["profile"]["force_target"] is not None for m in ms] for name, ms in metas.items()}
    assert not any(forced["soft"]) and not any(forced["medium"])
    assert all(forced["hard"])
    assert depths["hard"].max() < 0.5 * depths["soft"].min()
    for name in MATERIALS:
        assert depths[name].std() > 0  # human-like: no two presses alike
        xs = [m["profile"]["speed_in"] for m in metas[name]]
        assert np.std(xs) > 0


def test_kinesthetic_stiffness_is_ordered_by_young_modulus(training):
    params, labels, _ = training
    n1 = {name: params[[lab == name for lab in labels], 0] for name in MATERIALS}
    assert n1["soft"].max() < n1["medium"].min()
    assert n1["medium"].max() < n1["hard"].min()


def test_leave_one_out_accuracy_is_at_least_point_nine_for_every_material(training):
    params, labels, _ = training
    cv = leave_one_out(params, labels)
    assert cv.materials == list(MATERIALS)
    assert np.all(cv.per_material_accuracy >= 0.9), cv.to_dict()
    # the posterior is confident on the correct material on average, not just its argmax
    assert np.all(np.diag(cv.mean_posterior) > 0.8), cv.mean_posterior


def test_memory_recognises_new_presses_from_another_seed(training):
    params, labels, _ = training
    memory = HapticMemory().fit(params, labels)
    for k, (name, young) in enumerate(MATERIALS.items()):
        fresh, _ = _press_params(name, young, seed=900 + k, n=2)
        assert memory.predict(fresh) == [name, name]
