"""The independent reference for the contact mechanics (sim/reference: axisymmetric FE, frictionless rigid sphere on
an elastic sample on a rigid base), checked against closed forms it does not use: Sneddon's sphere on a half-space
and Dimitriadis et al. (2002)'s bonded-layer correction for thin layers."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("skfem")

from palpate.core.errors import ValidationError  # noqa: E402
from palpate.core.world.scene import Layer, Material  # noqa: E402
from palpate.sim.hertz import (  # noqa: E402
    hertz_contact_radius,
    hertz_force,
    sneddon_sphere_contact_radius,
    sneddon_sphere_force_at_depth,
)
from palpate.sim.reference.bonded_layer import dimitriadis_factor  # noqa: E402
from palpate.sim.reference.fe import fe_press  # noqa: E402
from palpate.sim.reference.sample import AxisInclusion, AxisymmetricSample  # noqa: E402

R = 0.008
SOFT = Material("m", 2e5, 0.3)


def test_sneddons_sphere_tends_to_hertz_for_shallow_presses_and_is_softer_deeper():
    d = np.array([1e-6, 0.5e-3, 4e-3])
    f_s, f_h = sneddon_sphere_force_at_depth(1.0, R, d), hertz_force(1.0, R, d)
    assert abs(f_s[0] / f_h[0] - 1) < 1e-3
    # the exact sphere is narrower than the paraboloid: less force at the same depth, ~5% at d / R = 0.5
    assert 0.93 < f_s[2] / f_h[2] < 0.97 and f_s[1] < f_h[1]
    assert np.all(sneddon_sphere_contact_radius(R, d) <= hertz_contact_radius(R, d))


def test_coarse_fe_on_a_thick_block_is_sneddons_sphere_with_its_small_finite_thickness_stiffening():
    d = np.array([1.0, 2.0, 3.0]) * 1e-3
    fe = fe_press(AxisymmetricSample(SOFT, 0.06), R, d, refinement=0.5)
    exact = sneddon_sphere_force_at_depth(SOFT.effective_modulus, R, d) * dimitriadis_factor(
        np.sqrt(R * d) / 0.06, SOFT.poisson)
    np.testing.assert_allclose(fe.force, exact, rtol=0.01)
    np.testing.assert_allclose(fe.contact_radius, sneddon_sphere_contact_radius(R, d), atol=fe.h0)
    assert np.all(np.isfinite(fe.pressure)) and np.all(fe.pressure >= -1e-9 * fe.pressure.max())


def test_a_thin_layer_is_stiffer_than_a_thick_block_and_a_frictionless_base_softer_than_a_bonded_one():
    d = np.array([0.5, 1.0]) * 1e-3
    thick = fe_press(AxisymmetricSample(SOFT, 0.06), R, d, refinement=0.5).force
    bonded = fe_press(AxisymmetricSample(SOFT, 0.008), R, d, refinement=0.5).force
    sliding = fe_press(AxisymmetricSample(SOFT, 0.008, base="frictionless"), R, d, refinement=0.5).force
    assert np.all(bonded > sliding) and np.all(sliding > thick)


@pytest.mark.parametrize(
    ("make", "match"),
    [
        (lambda: AxisymmetricSample(SOFT, 0.0), "thickness"),
        (lambda: AxisymmetricSample(SOFT, 0.01, base="glued"), "base"),
        (lambda: AxisymmetricSample(SOFT, 0.01, layers=(Layer(SOFT, 0.02),)), "layers are thicker"),
        (lambda: AxisymmetricSample(SOFT, 0.01, inclusion=AxisInclusion(SOFT, "sphere", 0.005, 0.004)),
         "below the sample"),
        (lambda: AxisInclusion(SOFT, "cube", 0.001, 0.002), "shape"),
        (lambda: fe_press(AxisymmetricSample(SOFT, 0.02), R, [1e-3], refinement=0.0), "refinement"),
    ],
)
def test_bad_samples_and_settings_are_refused_naming_what_is_wrong(make, match):
    with pytest.raises(ValidationError, match=match):
        make()


@pytest.mark.physics
@pytest.mark.parametrize(("thickness", "poisson", "base"), [(0.01, 0.49, "bonded"), (0.01, 0.3, "bonded"),
                                                           (0.008, 0.3, "frictionless")])
def test_thin_layers_follow_the_published_bonded_layer_correction(thickness, poisson, base):
    """Dimitriadis et al. 2002 (a series in a / h): within 3% where a <= h / 2."""
    d = np.array([0.2, 0.5, 1.0]) * 1e-3
    layer = Material("m", 2e5, poisson)
    fe = fe_press(AxisymmetricSample(layer, thickness, base=base), R, d)
    series = dimitriadis_factor(np.sqrt(R * d) / thickness, poisson, base)
    np.testing.assert_allclose(fe.force, sneddon_sphere_force_at_depth(layer.effective_modulus, R, d) * series,
                               rtol=0.03)


@pytest.mark.physics
def test_refining_the_mesh_converges_and_an_inclusion_of_the_bulk_changes_nothing():
    d = np.array([0.5, 1.0, 2.0]) * 1e-3
    bulk = Material("b", 1e5, 0.45)
    forces = [fe_press(AxisymmetricSample(bulk, 0.02), R, d, refinement=k).force for k in (0.5, 1.0, 2.0)]
    change = [float(np.max(np.abs(f / forces[-1] - 1))) for f in forces[:2]]
    assert change[1] < 0.01 and change[1] < change[0]
    same = AxisymmetricSample(bulk, 0.03, inclusion=AxisInclusion(bulk, "sphere", 0.001, 0.004))
    plain = fe_press(AxisymmetricSample(bulk, 0.03), R, d)
    np.testing.assert_allclose(fe_press(same, R, d).force, plain.force, rtol=2e-3)
    hard = AxisymmetricSample(bulk, 0.03, inclusion=AxisInclusion(Material("h", 1e6, 0.4), "sphere", 0.001, 0.004))
    assert np.all(fe_press(hard, R, d).force > plain.force * (1 + 1e-2))
