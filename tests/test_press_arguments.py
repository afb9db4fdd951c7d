"""Arguments of a press and of the scene it presses, from a careless or hostile caller: each refused with a
ValidationError naming it, before any work (no TypeError from deep inside, no array of 1e300 samples, no NaN let
through a range check)."""

from __future__ import annotations

import numpy as np
import pytest

from palpate.core.errors import ValidationError
from palpate.core.session.sources import PressTarget, check_seed
from palpate.core.world.scene import FingertipSpec, Material, ObjectSpec, PoseSensorSpec, Scene, TaxelSensorSpec
from palpate.sim.api import simulate_press
from palpate.sim.controller import press_profile
from palpate.sim.source import SimSource

SCENE = Scene((ObjectSpec("b", "box", (0.1, 0.1, 0.03), (0.0, 0.0), Material("m", 5e4, 0.4)),))


@pytest.mark.parametrize("field, value", [("x", "0"), ("y", np.nan), ("depth", np.inf), ("force", True),
                                          ("speed", None), ("hold", np.inf)])
def test_a_press_target_refuses_what_is_not_a_finite_number(field, value):
    with pytest.raises(ValidationError, match=f"PressTarget: {field} must be a finite number"):
        PressTarget(**({"x": 0.0, "y": 0.0, "depth": 0.002} | {field: value}))


def test_a_press_target_takes_numpy_numbers_and_refuses_a_negative_hold():
    target = PressTarget(np.float32(0.01), np.int64(0), depth=np.float64(0.002))
    assert target.x == pytest.approx(0.01) and target.y == 0
    with pytest.raises(ValidationError, match="PressTarget.hold must be >= 0 s"):
        PressTarget(0.0, 0.0, hold=-0.1)


@pytest.mark.parametrize("seed", [np.nan, np.inf, -1, 2.5, "3", True, None])
def test_seeds_are_whole_numbers_at_least_zero(seed):
    with pytest.raises(ValidationError, match="here must be a whole number >= 0"):
        check_seed(seed, "here")
    with pytest.raises(ValidationError, match="SimSource: seed must be a whole number"):
        SimSource(SCENE, fidelity="analytic", seed=seed)
    with pytest.raises(ValidationError, match="simulate_press: seed must be a whole number"):
        simulate_press(5e4, 0.4, "analytic", 0.002, 0.01, seed)


def test_a_whole_seed_of_any_number_type_presses_as_its_integer():
    assert check_seed(np.int64(7), "seed") == 7 and check_seed(7.0, "seed") == 7
    a = simulate_press(5e4, 0.4, "analytic", 0.002, seed=7.0, variability="human")
    b = simulate_press(5e4, 0.4, "analytic", 0.002, seed=7, variability="human")
    assert len(a.frames) == len(b.frames)
    assert all(np.array_equal(f.counts, g.counts) for f, g in zip(a.frames, b.frames, strict=True))


@pytest.mark.parametrize("name, args", [("young", ("soft", 0.4, "analytic", 0.002)),
                                        ("poisson", (5e4, None, "analytic", 0.002)),
                                        ("depth", (5e4, 0.4, "analytic", "2 mm")),
                                        ("speed", (5e4, 0.4, "analytic", 0.002, [0.01]))])
def test_simulate_press_names_an_argument_that_is_not_a_number(name, args):
    with pytest.raises(ValidationError, match=f"simulate_press: {name} must be a number"):
        simulate_press(*args)


def test_a_press_too_slow_to_sample_is_refused_before_its_trajectory_is_built():
    with pytest.raises(ValidationError, match=r"needs over 1e\+07 samples: raise the speed \(now 1e-300 m/s\)"):
        press_profile(PressTarget(0.0, 0.0, depth=0.002, speed=1e-300), 0.03, radius=0.008, timestep=0.002)
    with pytest.raises(ValidationError, match="raise the speed"):
        simulate_press(5e4, 0.4, "analytic", 0.002, 1e-300)
    slow = press_profile(PressTarget(0.0, 0.0, depth=0.002, speed=1e-4), 0.03, radius=0.008, timestep=0.002)
    assert slow.duration == pytest.approx(2 * 0.004 / 1e-4, rel=1e-9)  # a minute-long press is still pressed


@pytest.mark.parametrize("make, field", [
    (lambda v: Material("m", v), "young"), (lambda v: Material("m", 5e4, v), "poisson"),
    (lambda v: Material("m", 5e4, 0.3, v), "damping"), (lambda v: FingertipSpec(radius=v), "radius"),
    (lambda v: FingertipSpec(pitch=v), "pitch"), (lambda v: TaxelSensorSpec(rate=v), "rate"),
    (lambda v: TaxelSensorSpec(noise_std=v), "noise_std"), (lambda v: TaxelSensorSpec(clock_offset=v), "clock_offset"),
    (lambda v: PoseSensorSpec(noise_std=v), "noise_std"), (lambda v: PoseSensorSpec(jitter=v), "jitter"),
])
@pytest.mark.parametrize("value", [np.nan, np.inf, "1", None, [1.0], True])
def test_scene_parts_refuse_what_is_not_a_finite_number(make, field, value):
    # NaN passes the range checks (every comparison is False): a NaN noise would put NaN into every frame
    with pytest.raises(ValidationError, match=f"{field} must be a finite number"):
        make(value)


@pytest.mark.parametrize("size, position", [((0.1, np.nan, 0.03), (0.0, 0.0)), (0.1, (0.0, 0.0)),
                                            ((0.1, 0.1, 0.03), (0.0, "0")), ((0.1, 0.1, 0.03), None)])
def test_an_object_refuses_sizes_and_positions_that_are_not_finite_numbers(size, position):
    with pytest.raises(ValidationError, match="object 'b': (size|position) must be a tuple of finite numbers"):
        ObjectSpec("b", "box", size, position, Material("m", 5e4))


def test_a_pad_has_a_whole_number_of_rows_and_columns():
    with pytest.raises(ValidationError, match="FingertipSpec: rows and cols must be whole numbers"):
        FingertipSpec(rows=4.0)
    assert FingertipSpec(rows=np.int64(3)).sensel_centres().shape == (3, 4, 2)


@pytest.mark.parametrize("options, message", [
    ({"variability": 0.5}, "variability must be 'robot', 'human' or a Variability"),
    ({"variability": "careful"}, "variability must be 'robot', 'human' or a Variability"),
    ({"laws": [1]}, "laws must be a dict"),
    ({"timestep": "1 ms"}, "timestep must be a finite number"),
    ({"tolerance": None}, "tolerance must be a finite number"),
    ({"timestep": -0.001}, "timestep must be > 0 s"),
])
def test_a_simulated_source_names_a_bad_option(options, message):
    with pytest.raises(ValidationError, match=f"SimSource: {message}"):
        SimSource(SCENE, fidelity="analytic", **options)


def test_a_simulated_source_needs_a_scene_and_press_targets():
    with pytest.raises(ValidationError, match="SimSource: scene must be a Scene, got str"):
        SimSource("scene.toml")
    with pytest.raises(ValidationError, match="a press target must be a PressTarget, got tuple"):
        SimSource(SCENE, fidelity="analytic").press((0.0, 0.0))
