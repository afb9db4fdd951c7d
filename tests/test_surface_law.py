"""The contact law of a press beside a wall from the surface solve (sim/bem/law.py): against the 3-D FE image
reference (models/image_reference.json, an independent solver), and equal to the axisymmetric law where the top
does not change within the contact."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from palpate.core.world.scene import Inclusion, Material, ObjectSpec
from palpate.sim.bem.law import press_law, surface_law
from palpate.sim.contact.stack import object_law
from palpate.sim.validity.image_cases import image_cases
from palpate.sim.validity.image_reference import load_image_reference

SOFT, HARD = Material("soft", 20e3, 0.45), Material("hard", 115e3, 0.45)


def _worst_force_errors(law_of) -> float:
    """The worst |force error| against the FE over every wall case of the reference, at depths from 1 mm."""
    ref = load_image_reference()
    worst = 0.0
    for case in image_cases():
        if case.family != "wall" or case.name not in ref.cases:
            continue
        image = ref.cases[case.name].image
        obj = case.object_spec()
        keep = image.depth >= 1e-3 - 1e-12
        law = law_of(obj, *case.press_point, ref.tip, 1.05 * float(image.depth[-1]))
        err = law.force_at(image.depth[keep]) / image.force[keep] - 1.0
        worst = max(worst, float(np.max(np.abs(err))))
    return worst


def test_a_press_beside_a_wall_feels_the_force_of_the_3d_fe():
    surface = _worst_force_errors(lambda obj, x, y, tip, d: press_law(obj, x, y, obj.height, tip, d))
    averaged = _worst_force_errors(lambda obj, x, y, tip, d: object_law(obj, x, y, obj.height, tip.radius, d))
    assert surface <= 0.03, surface
    assert averaged > 0.3  # the axisymmetric average this replaces beside walls


def _block(inclusions=()) -> ObjectSpec:
    return ObjectSpec("block", "box", (0.08, 0.08, 0.03), (0.0, 0.0), SOFT, inclusions=tuple(inclusions))


def test_where_the_top_does_not_change_the_law_is_the_axisymmetric_one_bit_for_bit():
    lump = Inclusion(HARD, "box", (0.0, 0.0, 0.022), (0.01, 0.01, 0.004))  # buried: the top is one material
    for obj in (_block(), _block([lump])):
        tip = _tip()
        got = press_law(obj, 0.002, 0.0, 0.03, tip, 0.004, cache={})
        want = object_law(obj, 0.002, 0.0, 0.03, tip.radius, 0.004, cache={})
        for name in ("depth", "force", "contact_radius", "coeffs"):
            assert np.array_equal(getattr(got, name), getattr(want, name))


def _tip():
    from palpate.core.world.scene import FingertipSpec

    return FingertipSpec()


def _wall_block(hard: Material) -> ObjectSpec:
    column = Inclusion(hard, "column", (0.02, 0.0, 0.015), (0.04, 0.08))  # x from 0 to 40 mm
    return _block([column])


def test_a_cached_surface_law_is_reused_and_missed_when_a_material_changes():
    tip, cache = _tip(), {}
    obj = _wall_block(HARD)
    first = press_law(obj, -0.002, 0.0, 0.03, tip, 0.004, cache=cache)
    assert press_law(obj, -0.002, 0.0, 0.03, tip, 0.004, cache=cache) is first
    stiffer = press_law(_wall_block(replace(HARD, young=4 * HARD.young)), -0.002, 0.0, 0.03, tip, 0.004, cache=cache)
    assert stiffer is not first
    assert stiffer.force[-1] > first.force[-1] * 1.05
    # on the soft side 2 mm from a stiffer wall: stiffer than the soft column, softer than the hard one
    soft = object_law(_block(), 0.0, 0.0, 0.03, tip.radius, 0.004)
    assert soft.force_at(0.003) < first.force_at(0.003)


def test_walls_on_one_material_share_the_uniform_reference_solve_and_their_laws_are_as_if_solved_alone(monkeypatch):
    import palpate.sim.bem.law as law_mod

    solved = []
    real = law_mod.uniform_surface
    monkeypatch.setattr(law_mod, "uniform_surface", lambda *a: solved.append(a[1]) or real(*a))
    law_of = law_mod.press_law  # the patched module's own (another test may have imported it anew)
    tip, cache = _tip(), {}
    # three press points beside the wall, on the soft side: one uniform reference for all three
    points = (-0.002, -0.0015, -0.001)
    kept = [law_of(_wall_block(HARD), x, 0.0, 0.03, tip, 0.004, cache=cache) for x in points]
    assert len(solved) == 1
    for x, law in zip(points, kept, strict=True):
        alone = law_of(_wall_block(HARD), x, 0.0, 0.03, tip, 0.004, cache={})
        for name in ("force", "coeffs"):
            assert np.array_equal(getattr(law, name), getattr(alone, name))
    # another material under the press point, or another depth: another reference
    law_of(_wall_block(HARD), 0.002, 0.0, 0.03, tip, 0.004, cache=cache)  # on the hard side
    law_of(_wall_block(HARD), -0.002, 0.0, 0.03, tip, 0.003, cache=cache)
    assert len(solved) == 1 + 3 + 2


def test_no_surface_law_where_an_edge_lies_within_the_contact():
    tip = _tip()
    obj = _wall_block(HARD)
    column = object_law(obj, 0.0385, 0.0, 0.03, tip.radius, 0.004, lateral=False)
    # 1.5 mm from the object's side (x = 40 mm), with the wall 1.5 mm the other way
    assert surface_law(obj, 0.0385, 0.0, 0.03, tip, 0.004, column) is None
    assert surface_law(obj, -0.0015, 0.0, 0.03, tip, 0.004,
                       object_law(obj, -0.0015, 0.0, 0.03, tip.radius, 0.004, lateral=False)) is not None


@pytest.mark.parametrize("depth", [0.002, 0.004])
def test_the_surface_law_grows_with_depth_and_integrates_to_its_force(depth):
    tip = _tip()
    law = press_law(_wall_block(HARD), -0.001, 0.0, 0.03, tip, depth)
    assert np.all(np.diff(law.force) > 0)
    basis = law.basis_at(law.depth[1:])
    b3 = basis.radii**3
    integral = 2.0 * np.pi / 3.0 * np.sum(basis.coeffs * b3, axis=1)
    np.testing.assert_allclose(integral, law.force[1:], rtol=1e-3)  # as the column law it scales


def test_the_quick_check_never_misses_a_change_of_material_at_the_top():
    from palpate.sim.bem.law import may_change_at_top, surface_columns, top_changes

    rng = np.random.default_rng(4)
    missed = checked = 0
    for _ in range(150):
        shape = rng.choice(["sphere", "box", "column"])
        c = (float(rng.uniform(-0.02, 0.02)), float(rng.uniform(-0.02, 0.02)), float(rng.uniform(0.015, 0.032)))
        size = {"sphere": (float(rng.uniform(0.001, 0.008)),),
                "box": tuple(float(v) for v in rng.uniform(0.002, 0.015, 3)),
                "column": tuple(float(v) for v in rng.uniform(0.002, 0.015, 2))}[str(shape)]
        obj = _block([Inclusion(HARD, str(shape), c, size)])
        x, y = (float(v) for v in rng.uniform(-0.02, 0.02, 2))
        changes = top_changes(*surface_columns(obj, x, y, 0.03, 0.006))
        quick = may_change_at_top(obj, x, y, 0.03, 0.006)
        missed += changes and not quick
        checked += changes
    assert checked >= 10 and missed == 0


def test_a_cached_surface_law_is_missed_when_only_a_layer_under_the_far_side_changes():
    tip, cache = _tip(), {}

    def wall_over(sub: Material) -> ObjectSpec:
        # the hard side is a 3 mm skin over ``sub``; the soft side and the press point's column do not change
        return ObjectSpec("block", "box", (0.08, 0.08, 0.03), (0.0, 0.0), SOFT, inclusions=(
            Inclusion(HARD, "box", (0.02, 0.0, 0.0285), (0.04, 0.08, 0.003)),
            Inclusion(sub, "box", (0.02, 0.0, 0.0135), (0.04, 0.08, 0.027))))

    first = press_law(wall_over(SOFT), -0.0015, 0.0, 0.03, tip, 0.004, cache=cache)
    stiff = press_law(wall_over(replace(HARD, name="base", young=8 * HARD.young)), -0.0015, 0.0, 0.03, tip, 0.004,
                      cache=cache)
    assert stiff is not first and stiff.force[-1] > first.force[-1] * 1.01
