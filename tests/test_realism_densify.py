"""A cellular material's densification (material.densify_strain): its law, its inverse, where it applies, and its
validation."""

from __future__ import annotations

import tomllib
from dataclasses import replace

import numpy as np
import pytest

from palpate.core.errors import ValidationError
from palpate.core.session.sources import PressTarget
from palpate.core.world.scene import Material, ObjectSpec, Scene
from palpate.sim.hertz import hertz_force
from palpate.sim.realism.finger import series_law
from palpate.sim.realism.material import (
    MAX_DOUBLINGS,
    cellular_depth_for_force,
    cellular_factor,
    densify_factor,
    plateau_depth,
    plateau_depth_for_force,
    plateau_factor,
)
from palpate.sim.realism.parameters import free_parameters, with_values
from palpate.sim.realism.profile import IDEAL, FingerPulp, MaterialRealism
from palpate.sim.realism.profile_file import parse_profile, profile_to_toml
from palpate.sim.source import SimSource

RADIUS = 0.008
E_STAR = 3e4 / (1 - 0.3**2)


def _hertz_depth(force: float) -> float:
    return float((3.0 * force / (4.0 * E_STAR * np.sqrt(RADIUS))) ** (2.0 / 3.0))


def test_past_its_onset_a_densifying_force_grows_by_the_indentation_over_the_onset():
    dd = plateau_depth(0.15, RADIUS)
    d = np.array([0.0, 0.5 * dd, dd, 2 * dd, 5 * dd])
    np.testing.assert_allclose(densify_factor(d, dd), [1, 1, 1, 2, 5])
    np.testing.assert_array_equal(densify_factor(d, 0.0), np.ones(5))
    dp = plateau_depth(0.05, RADIUS)
    np.testing.assert_allclose(cellular_factor(d, dp, dd), plateau_factor(d, dp) * densify_factor(d, dd))
    np.testing.assert_array_equal(cellular_factor(d, dp, 0.0), plateau_factor(d, dp))
    # on a plateau a Hertz force is linear in depth; densified it becomes quadratic
    deep = np.linspace(2 * dd, 6 * dd, 5)
    force = hertz_force(E_STAR, RADIUS, deep) * cellular_factor(deep, dp, dd)
    np.testing.assert_allclose(force / deep**2, force[0] / deep[0] ** 2, rtol=1e-12)


@pytest.mark.parametrize("plateau_strain", [0.0, 0.05])
def test_the_planned_depth_inverts_the_cellular_law_and_the_series_law_agrees(plateau_strain):
    dp, dd = plateau_depth(plateau_strain, RADIUS), plateau_depth(0.15, RADIUS)
    for force in (0.01, 0.3, 2.0, 8.0):
        d = cellular_depth_for_force(_hertz_depth, force, dp, dd)
        assert hertz_force(E_STAR, RADIUS, d) * float(cellular_factor(np.array(d), dp, dd)) == pytest.approx(force)
        # nothing densifies: the plateau's own iteration, to the bit
        assert cellular_depth_for_force(_hertz_depth, force, dp, 0.0) == plateau_depth_for_force(_hertz_depth,
                                                                                                 force, dp)
    assert cellular_depth_for_force(_hertz_depth, 8.0, dp, dd) < plateau_depth_for_force(_hertz_depth, 8.0, dp)
    pulp = FingerPulp(compliant=True)
    plain, dense = (series_law(E_STAR, RADIUS, pulp, 1.0, 0.02, plateau=dp, densify=x) for x in (0.0, dd))
    # shallower than the onset nothing changes; deeper the closed form is the inverse found above
    below = plain.object_depth <= dd
    np.testing.assert_array_equal(dense.object_depth[below], plain.object_depth[below])
    assert (~below).sum() > 50
    for f, d in zip(dense.force[~below][::40], dense.object_depth[~below][::40], strict=True):
        assert d == pytest.approx(cellular_depth_for_force(_hertz_depth, float(f), dp, dd), rel=1e-6)


def test_the_planned_depth_is_never_nan_at_the_ends_of_the_law():
    dp, dd = plateau_depth(0.05, RADIUS), plateau_depth(0.15, RADIUS)
    # no force needs no depth (a regula falsi step there would divide 0 by 0)
    assert cellular_depth_for_force(_hertz_depth, 0.0, dp, dd) == 0.0
    # a law that has no answer past the elastic depth: no depth reaches the force, and the search stops
    calls = []

    def runs_out(force: float) -> float:
        calls.append(force)
        return _hertz_depth(force) if len(calls) == 1 else float("nan")

    assert cellular_depth_for_force(runs_out, 2.0, dp, dd) == float("inf")
    assert len(calls) <= 3 + MAX_DOUBLINGS


def _press(material: str, densify: float, depth: float = 0.005):
    block = ObjectSpec("b", "box", (0.08, 0.08, 0.04), (0.0, 0.0), Material(material, 3e4, 0.3))
    realism = replace(IDEAL, material=MaterialRealism(plateau_strain=0.05, plateau_materials=("foam",),
                                                      densify_strain=densify))
    src = SimSource(Scene((block,)), fidelity="analytic", seed=1, variability="robot", realism=realism)
    return src.press(PressTarget(0.0, 0.0, depth=depth, speed=0.01))


def test_a_deep_press_on_a_densifying_foam_stiffens_and_a_rubber_does_not():
    dense, plateau_only = _press("foam", 0.1), _press("foam", 0.0)
    d = dense.truth.indentation
    np.testing.assert_array_equal(d, plateau_only.truth.indentation)
    dd = plateau_depth(0.1, RADIUS)
    assert d.max() > 2 * dd
    np.testing.assert_allclose(dense.truth.force, plateau_only.truth.force * densify_factor(np.maximum(d, 0), dd),
                               rtol=1e-12)
    # the pad carries the force: its counts rise with it
    counts = [np.array([fr.counts for fr in r.frames], dtype=float).sum(axis=(1, 2)).max()
              for r in (dense, plateau_only)]
    assert counts[0] > 1.2 * counts[1]
    rubber, rubber_plain = _press("rubber", 0.1), _press("rubber", 0.0)
    np.testing.assert_array_equal(rubber.truth.force, rubber_plain.truth.force)


@pytest.mark.parametrize("doc, match", [
    ({"material": {"densify_strain": 0.2}}, r"bad\.toml: material\.plateau_materials: densify_strain > 0 needs"),
    ({"material": {"densify_strain": 0.7, "plateau_materials": ["a"]}}, r"bad\.toml: material\.densify_strain"),
    ({"material": {"densify_strain": -0.1, "plateau_materials": ["a"]}}, r"bad\.toml: material\.densify_strain"),
    ({"material": {"plateau_strain": 0.1, "densify_strain": 0.08, "plateau_materials": ["a"]}},
     r"bad\.toml: material\.densify_strain: must exceed plateau_strain"),
])
def test_bad_densifications_are_refused_naming_the_file_and_the_key(doc, match):
    with pytest.raises(ValidationError, match=match):
        parse_profile(doc, "bad.toml")


def test_densification_round_trips_is_not_ideal_and_is_a_calibration_parameter():
    p = parse_profile({"material": {"plateau_strain": 0.05, "densify_strain": 0.2, "plateau_materials": ["foam_A"]}})
    assert not p.is_ideal and p.material.densify_of("foam_A") == 0.2 and p.material.densify_of("rubber") == 0.0
    assert parse_profile(tomllib.loads(profile_to_toml(p))) == p
    assert not parse_profile({"material": {"densify_strain": 0.2, "plateau_materials": ["x"]}}).is_ideal
    with pytest.raises(ValidationError, match="must exceed plateau_strain"):
        MaterialRealism(plateau_strain=0.2, densify_strain=0.1, plateau_materials=("x",))
    free = free_parameters(["material.densify_strain"])
    fitted = with_values(replace(IDEAL, material=MaterialRealism(plateau_materials=("x",))), free, [0.25])
    assert fitted.material.densify_strain == 0.25


def test_a_force_limited_press_through_the_finger_stops_shallower_on_a_densifying_foam():
    pulp = FingerPulp(compliant=True, stiffness=500.0, stiffening=1000.0)
    deepest = []
    for densify in (0.0, 0.1):
        block = ObjectSpec("b", "box", (0.08, 0.08, 0.04), (0.0, 0.0), Material("foam", 3e4, 0.3))
        realism = replace(IDEAL, finger=pulp, material=MaterialRealism(plateau_strain=0.05, plateau_materials=(
            "foam",), densify_strain=densify))
        src = SimSource(Scene((block,)), fidelity="analytic", seed=1, variability="robot", realism=realism)
        rec = src.press(PressTarget(0.0, 0.0, depth=0.006, force=0.3, speed=0.01))
        deepest.append((rec.truth.indentation.max(), rec.truth.force.max()))
    (d_plain, f_plain), (d_dense, f_dense) = deepest
    # on a plateau F = k sqrt(d_p) d, densified F = k sqrt(d_p) d^2 / d_d: the same force at sqrt(d d_d)
    assert d_plain > plateau_depth(0.1, RADIUS)
    assert d_dense == pytest.approx(np.sqrt(d_plain * plateau_depth(0.1, RADIUS)), rel=0.02)
    assert f_dense == pytest.approx(f_plain, rel=0.02)
