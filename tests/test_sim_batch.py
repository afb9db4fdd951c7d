"""Batched simulated presses equal the same presses made one at a time, bit for bit.

The batch integrates every analytic press's sensel pressures in one vectorised call; each value is still computed
from that press's own samples by elementwise operations and per-sample reductions in the same order, and each press
draws its noise from its own seeded streams, so nothing is allowed to differ: the comparisons are exact.
"""

from __future__ import annotations

import numpy as np
import pytest

from palpate.core.errors import ValidationError
from palpate.core.session.sources import PressTarget
from palpate.core.world.scene import Material, ObjectSpec, Scene
from palpate.sim.api import simulate_press
from palpate.sim.batch import (
    PressSpec,
    press_across,
    press_batch,
    register_backend,
    simulate_presses,
    unregister_backend,
)
from palpate.sim.batch.analytic import cpu_analytic_traces
from palpate.sim.source import SimSource


def assert_same(a, b) -> None:
    """Two recordings are equal in every frame, pose, truth sample and metadata entry."""
    assert len(a.frames) == len(b.frames) and len(a.poses) == len(b.poses)
    for f, g in zip(a.frames, b.frames, strict=True):
        assert f.t == g.t and f.sensel_area == g.sensel_area and f.sensor_id == g.sensor_id
        assert f.counts.dtype == g.counts.dtype == np.uint8 and np.array_equal(f.counts, g.counts)
    for p, q in zip(a.poses, b.poses, strict=True):
        assert p.t == q.t and np.array_equal(p.position, q.position) and np.array_equal(p.quaternion, q.quaternion)
    for name in ("t", "force", "indentation"):
        assert np.array_equal(getattr(a.truth, name), getattr(b.truth, name))
    assert a.truth.material == b.truth.material
    assert a.meta == b.meta


MIXED = [
    PressSpec(40e3, 0.45, "analytic", depth=0.003, seed=1),
    PressSpec(200e3, 0.3, "analytic", depth=0.002, seed=2, options={"thickness": 0.02}),
    PressSpec(40e3, 0.45, "analytic", depth=0.003, seed=7),  # a robot press: shares the first one's law
    PressSpec(800e3, 0.4, "analytic", depth=0.0015, speed=0.02, seed=3, options={"variability": "human"}),
    PressSpec(100e3, 0.3, "analytic", depth=None, seed=4, options={"force": 1.5}),
    PressSpec(60e3, 0.35, "analytic", depth=0.0025, seed=5, options={"hold": 0.1, "size": 0.06}),
]


def test_mixed_batch_equals_the_loop():
    batch = simulate_presses(MIXED)
    assert len(batch) == len(MIXED)
    for spec, rec in zip(MIXED, batch, strict=True):
        alone = simulate_press(spec.young, spec.poisson, spec.fidelity, spec.depth, spec.speed, spec.seed,
                               **spec.options)
        assert_same(alone, rec)
    # the presses differ from each other: equality above is not one recording compared with itself
    assert batch[0].truth.force.max() != batch[1].truth.force.max()
    assert any(not np.array_equal(f.counts, g.counts) for f, g in zip(batch[0].frames, batch[2].frames, strict=True))


@pytest.mark.parametrize("variability, realism", [("robot", None), ("human", None), ("human", "thesis_ch6")])
def test_source_batch_equals_its_loop(variability, realism):
    mats = [Material("soft", 30e3, 0.45), Material("hard", 600e3, 0.3)]
    scene = Scene(tuple(ObjectSpec(f"b{i}", "box", (0.3, 0.3, 0.04), (0.4 * i, 0.0), m) for i, m in enumerate(mats)))
    targets = [PressTarget(0.4 * (k % 2), 0.0, depth=0.002 + 0.0005 * (k % 3), speed=0.01) for k in range(7)]
    loop = SimSource(scene, fidelity="analytic", seed=11, variability=variability, realism=realism)
    batched = SimSource(scene, fidelity="analytic", seed=11, variability=variability, realism=realism)
    expected = [loop.press(t) for t in targets]
    got = batched.press_many(targets)
    for a, b in zip(expected, got, strict=True):
        assert_same(a, b)
    # the source moved on as the loop's did: its next press is the loop's next press
    assert_same(loop.press(targets[0]), batched.press(targets[0]))


def test_empty_and_single_batches():
    assert simulate_presses([]) == []
    spec = PressSpec(50e3, 0.4, "analytic", depth=0.002, seed=9)
    (one,) = simulate_presses([spec])
    assert_same(simulate_press(50e3, 0.4, "analytic", 0.002, seed=9), one)
    source = SimSource(Scene((ObjectSpec("b", "box", (0.1, 0.1, 0.03), (0.0, 0.0), Material("m", 5e4, 0.4)),)),
                       fidelity="analytic")
    assert press_batch(source, []) == []


def test_bad_input_is_named():
    with pytest.raises(ValidationError, match="unknown batch simulation backend 'gpu'.*cpu"):
        simulate_presses([PressSpec(5e4, fidelity="analytic")], backend="gpu")
    with pytest.raises(ValidationError, match="spec 1 must be a PressSpec"):
        simulate_presses([PressSpec(5e4, fidelity="analytic"), {"young": 5e4}])
    with pytest.raises(ValidationError, match="PressSpec: young must be a number"):
        PressSpec("soft", fidelity="analytic")
    with pytest.raises(ValidationError, match="PressSpec: seed must be a whole number >= 0"):
        PressSpec(5e4, fidelity="analytic", seed=1.5)
    with pytest.raises(ValidationError, match="unknown scene option"):
        simulate_presses([PressSpec(5e4, fidelity="analytic", options={"colour": "red"})])
    source = SimSource(Scene((ObjectSpec("b", "box", (0.1, 0.1, 0.03), (0.0, 0.0), Material("m", 5e4, 0.4)),)),
                       fidelity="analytic")
    with pytest.raises(ValidationError, match="target 0 must be a PressTarget"):
        press_batch(source, [(0.0, 0.0)])
    with pytest.raises(ValidationError, match="'cpu' is palpate's own"):
        register_backend("cpu", cpu_analytic_traces)


def test_a_registered_backend_takes_the_analytic_physics():
    calls = []

    def counting(jobs):
        calls.append(len(jobs))
        return cpu_analytic_traces(jobs)

    def short(jobs):
        return cpu_analytic_traces(jobs)[:-1]

    register_backend("counting", counting)
    register_backend("short", short)
    try:
        got = simulate_presses(MIXED[:3], backend="counting")
        assert calls == [3]
        for a, b in zip(simulate_presses(MIXED[:3]), got, strict=True):
            assert_same(a, b)
        with pytest.raises(ValidationError, match="returned 1 traces for 2 presses"):
            simulate_presses(MIXED[:2], backend="short")
    finally:
        unregister_backend("counting")
        unregister_backend("short")


def test_other_rungs_fall_back_to_the_loop_inside_the_batch():
    specs = [PressSpec(100e3, 0.3, "rigid", depth=0.002, speed=0.02, seed=1),
             PressSpec(100e3, 0.3, "auto", depth=0.002, speed=0.02, seed=2),
             PressSpec(300e3, 0.3, "analytic", depth=0.002, seed=3)]
    calls = []

    def counting(jobs):
        calls.append([j.profile.meta["seed"] for j in jobs])
        return cpu_analytic_traces(jobs)

    register_backend("counting", counting)
    try:
        got = simulate_presses(specs, backend="counting")
    finally:
        unregister_backend("counting")
    assert [r.meta["fidelity"] for r in got] == ["rigid", "analytic", "analytic"]
    assert len(calls) == 1 and len(calls[0]) == 2  # the rigid press ran alone, not on the backend
    for spec, rec in zip(specs, got, strict=True):
        assert_same(simulate_press(spec.young, spec.poisson, spec.fidelity, spec.depth, spec.speed, spec.seed), rec)


def test_presses_across_sources_equal_each_sources_loop():
    def sources():
        mats = [Material("soft", 30e3, 0.45), Material("hard", 600e3, 0.3)]
        return [SimSource(Scene((ObjectSpec("b", "box", (0.1, 0.1, 0.03), (0.0, 0.0), m),)), fidelity="analytic",
                          seed=s, variability="human") for s, m in zip((1, 2), mats, strict=True)]

    targets = [PressTarget(0.001 * k, 0.0, depth=0.002 + 0.0003 * k) for k in range(4)]
    a, b = sources(), sources()
    order = [(0, 0), (1, 0), (1, 1), (0, 1), (0, 2), (1, 2)]
    expected = [a[s].press(targets[k]) for s, k in order]
    got = press_across([(b[s], targets[k]) for s, k in order])
    for x, y in zip(expected, got, strict=True):
        assert_same(x, y)
    with pytest.raises(ValidationError, match="item 0 must be a \\(SimSource, PressTarget\\) pair"):
        press_across([targets[0]])


def test_a_kept_law_is_dropped_when_a_shared_cache_changes():
    # two sources sharing one law cache: B's deeper press at the same point replaces the law A was given, and A's
    # next press there is served what the cache now holds, as without the kept answer
    laws: dict = {}
    scene = Scene((ObjectSpec("b", "box", (0.1, 0.1, 0.03), (0.0, 0.0), Material("m", 5e4, 0.4)),))
    a = SimSource(scene, fidelity="analytic", laws=laws)
    b = SimSource(scene, fidelity="analytic", laws=laws)
    first = a.press(PressTarget(0.0, 0.0, depth=0.002)).meta["physics"]["contact_law_max_depth"]
    deeper = b.press(PressTarget(0.0, 0.0, depth=0.004)).meta["physics"]["contact_law_max_depth"]
    again = a.press(PressTarget(0.0, 0.0, depth=0.002)).meta["physics"]["contact_law_max_depth"]
    assert deeper > first and again == deeper
