"""A cellular material's stress plateau (material.plateau_strain): its law, where it applies, and its validation."""

from __future__ import annotations

import tomllib
from dataclasses import replace

import numpy as np
import pytest

from palpate.core.errors import ValidationError
from palpate.core.perception.fit import fit_power_law
from palpate.core.session.sources import PressTarget
from palpate.core.world.scene import Material, ObjectSpec, Scene
from palpate.sim.hertz import hertz_force
from palpate.sim.realism.finger import series_law
from palpate.sim.realism.material import plateau_depth, plateau_depth_for_force, plateau_factor
from palpate.sim.realism.profile import IDEAL, FingerPulp, MaterialRealism
from palpate.sim.realism.profile_file import parse_profile, profile_to_toml
from palpate.sim.source import SimSource

RADIUS = 0.008
E_STAR = 3e4 / (1 - 0.3**2)


def _hertz_depth(force: float) -> float:
    return float((3.0 * force / (4.0 * E_STAR * np.sqrt(RADIUS))) ** (2.0 / 3.0))


def test_the_plateau_starts_at_tabors_strain_and_then_the_force_grows_as_the_area():
    # mean strain 0.2 a / R with a = sqrt(R d): 5% strain at d = R / 16
    assert plateau_depth(0.05, RADIUS) == pytest.approx(RADIUS / 16)
    dp = plateau_depth(0.05, RADIUS)
    d = np.array([0.0, 0.5 * dp, dp, 2 * dp, 8 * dp])
    np.testing.assert_allclose(plateau_factor(d, dp), [1, 1, 1, np.sqrt(0.5), np.sqrt(1 / 8)])
    np.testing.assert_array_equal(plateau_factor(d, 0.0), np.ones(5))
    # past the plateau a Hertz force becomes linear in depth (constant mean pressure over an area pi R d)
    deep = np.linspace(2 * dp, 10 * dp, 5)
    force = hertz_force(E_STAR, RADIUS, deep) * plateau_factor(deep, dp)
    np.testing.assert_allclose(np.diff(force) / np.diff(deep), (force[1] - force[0]) / (deep[1] - deep[0]))


def test_the_planned_depth_inverts_the_plateau_law():
    dp = plateau_depth(0.05, RADIUS)
    for force in (0.01, 0.5, 3.0):
        d = plateau_depth_for_force(_hertz_depth, force, dp)
        assert hertz_force(E_STAR, RADIUS, d) * float(plateau_factor(np.array(d), dp)) == pytest.approx(force)
        assert plateau_depth_for_force(_hertz_depth, force, 0.0) == _hertz_depth(force)
    # the series law's object depth is the same law in closed form, and Hertz's below the plateau
    pulp = FingerPulp(compliant=True)
    plain, foam = (series_law(E_STAR, RADIUS, pulp, 1.0, 0.02, plateau=p) for p in (0.0, dp))
    below = plain.object_depth <= dp
    np.testing.assert_array_equal(foam.object_depth[below], plain.object_depth[below])
    for f, d in zip(foam.force[~below][::50], foam.object_depth[~below][::50], strict=True):
        assert d == pytest.approx(plateau_depth_for_force(_hertz_depth, float(f), dp), rel=1e-6)


def _press(material: str, depth: float, plateau: float = 0.05, force: float | None = None, pulp=None,
           speed: float = 0.01):
    block = ObjectSpec("b", "box", (0.08, 0.08, 0.04), (0.0, 0.0), Material(material, 3e4, 0.3))
    realism = replace(IDEAL, material=MaterialRealism(plateau_strain=plateau, plateau_materials=("foam",)))
    if pulp is not None:
        realism = replace(realism, finger=pulp)
    src = SimSource(Scene((block,)), fidelity="analytic", seed=1, variability="robot", realism=realism)
    return src.press(PressTarget(0.0, 0.0, depth=depth, force=force, speed=speed))


def test_a_deep_press_on_a_foam_is_concave_and_a_shallow_one_or_a_rubber_is_elastic():
    # the same press on the same modulus: "rubber" is not among the plateau's materials, so it stays elastic
    deep, elastic = _press("foam", 0.004), _press("rubber", 0.004)
    dp = plateau_depth(0.05, RADIUS)
    d, f, f_el = deep.truth.indentation, deep.truth.force, elastic.truth.force
    np.testing.assert_array_equal(d, elastic.truth.indentation)
    np.testing.assert_allclose(f, f_el * plateau_factor(np.maximum(d, 0), dp), rtol=1e-12)
    # the kinesthetic fit c_P = n1 c_D^1.5 + n2 of the loading: the elastic law is near Hertz's (n2 ~ 0), the
    # plateau's concave (n2 > 0) and softer (smaller n1)
    load = (np.arange(len(d)) <= np.argmax(d)) & (d > 0)
    hertz, foam = (fit_power_law(d[load] * 1e3, y[load]) for y in (f_el, f))
    assert abs(hertz.k2) < 0.01 * f_el.max()
    assert foam.k2 > 0.05 * f.max() and foam.k1 < 0.6 * hertz.k1
    # below the plateau's strain nothing changes
    shallow, shallow_elastic = (_press(m, 0.8 * dp, speed=0.001) for m in ("foam", "rubber"))
    assert shallow.truth.force.max() > 0
    np.testing.assert_array_equal(shallow.truth.force, shallow_elastic.truth.force)
    # the pad carries the force: its pressure is scaled with it
    counts = [np.array([fr.counts for fr in r.frames], dtype=float).sum(axis=(1, 2)) for r in (deep, elastic)]
    assert counts[0].max() < 0.6 * counts[1].max()


def test_a_force_limited_press_on_a_foam_goes_deeper_through_the_finger():
    pulp = FingerPulp(compliant=True, stiffness=500.0, stiffening=1000.0)
    plain = _press("foam", 0.006, plateau=0.0, force=0.3, pulp=pulp)
    foam = _press("foam", 0.006, force=0.3, pulp=pulp)
    assert foam.truth.indentation.max() > 1.5 * plain.truth.indentation.max()
    assert foam.truth.force.max() == pytest.approx(plain.truth.force.max(), rel=0.1)


@pytest.mark.parametrize("doc, match", [
    ({"material": {"plateau_strain": 0.05}}, r"bad\.toml: material\.plateau_materials: plateau_strain > 0 needs"),
    ({"material": {"plateau_strain": 0.6, "plateau_materials": ["a"]}}, r"bad\.toml: material\.plateau_strain"),
    ({"material": {"plateau_strain": -0.1, "plateau_materials": ["a"]}}, r"bad\.toml: material\.plateau_strain"),
    ({"material": {"plateau_materials": "a"}}, r"bad\.toml: material\.plateau_materials"),
    ({"material": {"plateau_materials": ["a", ""]}}, r"bad\.toml: material\.plateau_materials"),
    ({"material": {"plateau_materials": ["a", "a"]}}, r"bad\.toml: material\.plateau_materials: names repeat"),
])
def test_bad_plateaus_are_refused_naming_the_file_and_the_key(doc, match):
    with pytest.raises(ValidationError, match=match):
        parse_profile(doc, "bad.toml")


def test_a_plateau_round_trips_and_off_is_ideal():
    p = parse_profile({"material": {"plateau_strain": 0.05, "plateau_materials": ["Material_1", "foam_A"]}})
    assert not p.is_ideal and p.material.plateau_of("foam_A") == 0.05 and p.material.plateau_of("rubber") == 0.0

    assert parse_profile(tomllib.loads(profile_to_toml(p))) == p
    assert parse_profile({"material": {"plateau_materials": ["Material_1"]}}).is_ideal
    with pytest.raises(ValidationError, match="needs plateau_materials"):
        MaterialRealism(plateau_strain=0.05)
