"""A source draws the pad's image only at the physics rows its 50 Hz frames read: the rows are exactly those, and
a press's recording equals the one whose image is drawn at every physics step."""

from __future__ import annotations

import numpy as np
import pytest

import palpate.sim.source as source_module
from palpate.core.session.sources import PressTarget
from palpate.core.world.scene import FingertipSpec, Material, ObjectSpec, Scene, TaxelSensorSpec
from palpate.sim import rigid
from palpate.sim.controller import press_profile
from palpate.sim.sensors import sample_taxels
from palpate.sim.source import SimSource
from palpate.sim.trace import PhysicsTrace, frame_rows


def _trace(n: int = 700, dt: float = 0.00137) -> PhysicsTrace:
    rng = np.random.default_rng(5)
    t = 0.013 + dt * np.arange(n)
    return PhysicsTrace(t=t, tip_position=np.zeros((n, 3)), tip_quaternion=np.tile([1.0, 0, 0, 0], (n, 1)),
                        sensel_pressure=rng.uniform(0.0, 3e4, (n, 4, 4)), force=np.ones(n), indentation=np.ones(n),
                        surface_z=0.0)


def _counts(trace: PhysicsTrace, spec: TaxelSensorSpec) -> np.ndarray:
    frames = sample_taxels(trace, spec, FingertipSpec(), np.random.default_rng(1))
    return np.array([f.counts for f in frames])


def test_frame_rows_are_exactly_the_rows_the_frames_read():
    trace, spec = _trace(), TaxelSensorSpec()
    rows = frame_rows(trace.t, spec.rate)
    assert 0 < rows.sum() <= 2 * (trace.t[-1] - trace.t[0]) * spec.rate + 2 < len(rows) / 4
    before = _counts(trace, spec)
    trace.sensel_pressure[~rows] = 0.0  # what the frames never read
    assert np.array_equal(_counts(trace, spec), before)
    for k in np.flatnonzero(rows)[[0, 7, -1]]:  # each row read changes what a frame reports
        changed = _trace()
        changed.sensel_pressure[k] *= 0.5
        assert not np.array_equal(_counts(changed, spec), before)


def _scene() -> Scene:
    block = ObjectSpec("block", "box", (0.06, 0.06, 0.03), (0.0, 0.0), Material("gel", 2e5, 0.45))
    return Scene(objects=(block,))


def _record_all_rows(monkeypatch):
    """The source as it was before it drew only the frames' rows: every row's image, in the physics and the
    finger."""
    run = source_module.run_rigid_press

    def every_row(*args, pressure_rows=None, **kwargs):
        return run(*args, **kwargs)

    monkeypatch.setattr(source_module, "run_rigid_press", every_row)
    monkeypatch.setattr(source_module, "frame_rows", lambda t, rate: np.ones(len(t), dtype=bool))


@pytest.mark.parametrize(("variability", "realism"), [("robot", None), ("human", "thesis_ch6")])
def test_a_press_records_what_drawing_the_image_at_every_step_records(monkeypatch, variability, realism):
    targets = [PressTarget(x=0.001, y=-0.002, depth=0.003), PressTarget(x=-0.004, y=0.0, force=2.0)]

    def presses():
        src = SimSource(_scene(), fidelity="rigid", seed=3, variability=variability, realism=realism)
        return [src.press(t) for t in targets]

    fast = presses()
    _record_all_rows(monkeypatch)
    full = presses()
    for a, b in zip(fast, full, strict=True):
        assert len(a.frames) == len(b.frames) > 20
        assert np.array_equal([f.counts for f in a.frames], [f.counts for f in b.frames])
        assert max(int(f.counts.max()) for f in a.frames) > 0
        assert np.array_equal([f.t for f in a.frames], [f.t for f in b.frames])
        assert np.array_equal([p.position for p in a.poses], [p.position for p in b.poses])
        assert np.array_equal(a.truth.force, b.truth.force)


def test_the_rigid_rung_draws_the_rows_asked_and_leaves_the_others_zero():
    scene = _scene()
    profile = press_profile(PressTarget(x=0.0, y=0.0, depth=0.003), 0.03, radius=scene.fingertip.radius,
                            timestep=0.002)
    full = rigid.run_rigid_press(scene, scene.objects[0], profile)
    asked = rigid.run_rigid_press(scene, scene.objects[0], profile, pressure_rows=lambda t: frame_rows(t, 50.0))
    rows = frame_rows(full.t, 50.0)
    assert np.array_equal(asked.sensel_pressure[rows], full.sensel_pressure[rows])
    assert not asked.sensel_pressure[~rows].any() and full.sensel_pressure[~rows].any()
    assert np.array_equal(asked.force, full.force)
