"""A careless press (``press.tail_dof``): heavy-tailed press-to-press deviations, off by default."""

from __future__ import annotations

import tomllib
from dataclasses import replace

import numpy as np
import pytest
from scipy import stats

from palpate.core.errors import ValidationError
from palpate.core.session.sources import PressTarget
from palpate.core.world.scene import FingertipSpec, TaxelSensorSpec
from palpate.sim.controller import HUMAN, TAIL_SCALE_MAX, press_profile, tail_scale
from palpate.sim.realism.parameters import free_parameters
from palpate.sim.realism.profile import LAB
from palpate.sim.realism.profile_file import parse_profile, profile_to_toml
from palpate.sim.realism.stage import RealismSession

TARGET = PressTarget(0.0, 0.0, depth=2.5e-3, speed=0.01)
KW = dict(radius=0.008, timestep=0.002)


def _depth_deviations(variability, seeds) -> np.ndarray:
    """Each press's drawn depth deviation in units of depth_cv (a standard normal for a careful person)."""
    depth = np.array([press_profile(TARGET, 0.04, variability=variability, seed=s, **KW).meta["depth"]
                      for s in seeds])
    return (depth / TARGET.depth - 1.0) / variability.depth_cv


def test_off_draws_exactly_as_before():
    # tail_dof = 0 is today's press: the same numbers, and nothing new in the press's record
    for seed in (0, 7, 123456):
        old = press_profile(TARGET, 0.04, variability=replace(HUMAN, tilt_std=0.05, slip_std=0.05), seed=seed, **KW)
        new = press_profile(TARGET, 0.04, variability=replace(HUMAN, tilt_std=0.05, slip_std=0.05, tail_dof=0.0),
                            seed=seed, **KW)
        assert np.array_equal(old.t, new.t) and np.array_equal(old.z, new.z)
        assert (old.x, old.y, old.meta) == (new.x, new.y, new.meta)
        assert "tail_scale" not in new.meta
    assert tail_scale(0.0, 5) == 1.0


def test_the_deviations_are_students_t_with_the_given_degrees_of_freedom():
    seeds = range(1500)
    careful = _depth_deviations(HUMAN, seeds)
    careless = _depth_deviations(replace(HUMAN, tail_dof=3.0), seeds)
    # the same press stream, one scale per press: each careless deviation is a careful one times w >= 0
    ratio = careless / careful
    assert np.all(ratio > 0) and np.all(ratio <= TAIL_SCALE_MAX + 1e-9)
    assert stats.kurtosis(careful) == pytest.approx(0.0, abs=0.4)
    assert stats.kurtosis(careless) > 2.0
    # against Student's t itself (the cap at TAIL_SCALE_MAX moves ~2% of presses, only in the far tails)
    assert stats.kstest(careless, stats.t(3.0).cdf).statistic < 0.04
    assert stats.kstest(careful, stats.t(3.0).cdf).statistic > stats.kstest(careless, stats.t(3.0).cdf).statistic
    # many degrees of freedom are a normal again: the scale goes to 1 continuously
    nearly_off = _depth_deviations(replace(HUMAN, tail_dof=1000.0), range(200))
    np.testing.assert_allclose(nearly_off, careful[:200], rtol=0.15, atol=0.02)


def test_one_scale_widens_where_and_how_deep_a_press_goes():
    v = replace(HUMAN, tilt_std=0.05, slip_std=0.05)
    seed = next(s for s in range(200) if tail_scale(2.0, s) > 2.0)
    w = tail_scale(2.0, seed)
    old = press_profile(TARGET, 0.04, variability=v, seed=seed, **KW)
    new = press_profile(TARGET, 0.04, variability=replace(v, tail_dof=2.0), seed=seed, **KW)
    assert new.meta["tail_scale"] == w
    assert new.meta["depth"] / TARGET.depth - 1 == pytest.approx(w * (old.meta["depth"] / TARGET.depth - 1))
    # the person's pace is not widened
    assert (new.meta["speed_in"], new.meta["speed_out"], new.meta["hold"]) == \
        (old.meta["speed_in"], old.meta["speed_out"], old.meta["hold"])
    assert new.x == pytest.approx(w * old.x) and new.y == pytest.approx(w * old.y)
    np.testing.assert_allclose(new.meta["slip"], w * np.asarray(old.meta["slip"]))
    np.testing.assert_allclose(new.meta["tilt"], np.clip(w * np.asarray(old.meta["tilt"]), -np.pi / 6, np.pi / 6))


def test_the_pulp_stiffness_of_a_careless_press_spreads_by_the_same_scale():
    tip, taxels = FingertipSpec(), TaxelSensorSpec()
    profile = replace(LAB, finger=replace(LAB.finger, stiffness_cv=0.4))
    s = np.sqrt(np.log1p(0.4**2))

    def normal(stream: int, spread: float | None) -> float:
        """The press's pulp draw as a standard normal (what log-normal factor of CV 0.4 it is)."""
        session = RealismSession(profile, tip, taxels, seed=3)
        kw = {} if spread is None else {"tail_scale": spread}
        real = session.press("block", 0.0, 0.0, lambda f: 1e-3 * (f / 5.0) ** (2 / 3), 0.01,
                             np.random.default_rng(stream), **kw)
        return (np.log(real.stiffness_scale) + 0.5 * s * s) / s

    checked = 0
    for stream in range(40):
        z = normal(stream, None)
        assert normal(stream, 1.0) == z  # a careful press draws as before
        if 0.2 < abs(z) < 1.5:
            assert normal(stream, 2.0) == pytest.approx(2.0 * z)
            # no pulp goes past the careful press's 3-sigma range, however careless the press
            assert normal(stream, 10.0) == pytest.approx(3.0 * np.sign(z))
            checked += 1
    assert checked > 10


@pytest.mark.parametrize("value", [0.5, -1.0, 2000.0, "3", float("nan")])
def test_bad_degrees_of_freedom_name_the_file_and_the_key(value):
    with pytest.raises(ValidationError, match=r"bad\.toml: press[.]tail_dof"):
        parse_profile({"press": {"tail_dof": value}}, "bad.toml")


@pytest.mark.parametrize("value", [0.5, -2.0, float("inf"), float("nan")])
def test_bad_degrees_of_freedom_in_code_are_refused(value):
    with pytest.raises(ValidationError, match="Variability.tail_dof"):
        replace(HUMAN, tail_dof=value)


def test_the_parameter_round_trips_and_is_calibratable():
    p = parse_profile({"press": {"tail_dof": 3.5}}, "x.toml", "x")
    assert p.press.tail_dof == 3.5
    assert parse_profile(tomllib.loads(profile_to_toml(p)), "y.toml", "x") == p
    assert parse_profile({}, "x.toml", "x").press.tail_dof == 0.0
    (free,) = free_parameters(["press.tail_dof"])
    # a start with the tail off begins at the gentlest tail of the box, not at its heaviest
    assert free.position(0.0) == 1.0 and free.value(1.0) == pytest.approx(free.hi)


@pytest.mark.parametrize("dof", [0.7, 1.0, 3.0, 12.5])
def test_the_scale_is_the_chi2_quantile_of_the_press_stream(dof):
    from palpate.sim.controller import TAIL_STREAM

    for seed in (0, 5, 99991):
        u = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(TAIL_STREAM,))).uniform()
        want = min(np.sqrt(dof / stats.chi2.ppf(u, dof)), TAIL_SCALE_MAX)
        assert tail_scale(dof, seed) == want
