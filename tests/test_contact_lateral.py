"""Lateral variation in the closed-form rungs' contact law (sim/contact): small effects by first-order
perturbation from the column's strain-energy shares, large ones by the coarse axisymmetric FE."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("skfem")

from palpate.core.world.scene import Inclusion, Material, ObjectSpec  # noqa: E402
from palpate.sim.contact import stack  # noqa: E402
from palpate.sim.contact.axisymmetric import FIRST_ORDER_LIMIT, free_side, lateral_effect  # noqa: E402
from palpate.sim.validity.cases import validity_cases  # noqa: E402
from palpate.sim.validity.reference import load_reference, reference_force  # noqa: E402

R = 0.008
RUBBER, HARD = Material("rubber", 1e5, 0.45), Material("hard", 5e5, 0.4)
BLOCK = ObjectSpec("block", "box", (0.12, 0.08, 0.03), (0.06, 0.04), RUBBER,
                   inclusions=(Inclusion(HARD, "box", (0.025, 0.02, 0.019), (0.02, 0.02, 0.02)),))


def _paths(monkeypatch):
    """Count which path each law takes."""
    taken = []
    real_fe, real_first = stack.axisymmetric_law, stack.first_order_law

    def fe(*a, **k):
        taken.append("fe")
        return real_fe(*a, **k)

    def first(*a, **k):
        taken.append("first_order")
        return real_first(*a, **k)

    monkeypatch.setattr(stack, "axisymmetric_law", fe)
    monkeypatch.setattr(stack, "first_order_law", first)
    return taken


def test_a_distant_free_side_is_taken_to_first_order_and_matches_the_fe_reference(monkeypatch):
    """A cylinder's side 25 mm from the press (a full ring of void): ~1-2% softer, against the cached reference."""
    taken = _paths(monkeypatch)
    (case,) = [c for c in validity_cases() if c.name == "edge_25mm"]
    law = stack.sample_law(case.sample, R, 1.05 * max(case.depths))
    assert taken == ["first_order"]
    ref = reference_force(load_reference(), case)
    np.testing.assert_allclose(law.force_at(np.array(case.depths)), ref, rtol=0.02)
    column = stack.solve_contact_law(stack.column_stack(stack.sample_lookup(case.sample), case.sample.thickness, []),
                                     R, 1.05 * max(case.depths))
    assert np.all(law.force_at(np.array(case.depths)) < column.force_at(np.array(case.depths)))


def test_a_rim_within_the_contacts_reach_is_a_free_side_and_the_law_matches_the_fe_reference(monkeypatch):
    """A cylinder 6 mm wide pressed 3 mm at its centre: the void past its rim, averaged in so the mesh runs on, was
    a surface the sphere touched (the contact disc held open out to it, tension in between: -13% force)."""
    taken = _paths(monkeypatch)
    (case,) = [c for c in validity_cases() if c.name == "edge_6mm"]
    law = stack.sample_law(case.sample, R, 1.05 * max(case.depths))
    assert taken == ["fe"]
    np.testing.assert_allclose(law.force_at(np.array(case.depths)), reference_force(load_reference(), case),
                               rtol=0.02)


def test_the_free_side_is_where_no_azimuth_has_material():
    (case,) = [c for c in validity_cases() if c.name == "edge_6mm"]
    assert free_side(stack.sample_lookup(case.sample), 0.008, [0.006]) == 0.006
    cylinder = ObjectSpec("c", "cylinder", (0.006, 0.02), (0.01, 0.0), RUBBER)
    assert abs(free_side(stack.object_lookup(cylinder, 0.01, 0.0, 0.02), 0.008) - 0.006) <= 0.008 / 256
    # a corner has material on a quarter of the azimuths out to any reach, and the middle of a block all round
    assert free_side(stack.object_lookup(BLOCK, 0.0005, 0.0005, 0.03), 0.01) == np.inf
    assert free_side(stack.object_lookup(BLOCK, 0.06, 0.04, 0.03), 0.01) == np.inf


def test_first_order_agrees_with_the_fe_where_it_is_used_and_the_fe_runs_where_the_effect_is_large(monkeypatch):
    taken = _paths(monkeypatch)
    d = np.array([1.0, 3.0, 5.5]) * 1e-3
    near_lump = stack.object_law(BLOCK, 0.045, 0.025, 0.03, R, 0.006)  # the lump's side 10 mm away
    far = stack.object_law(BLOCK, 0.06, 0.045, 0.03, R, 0.006)
    assert taken == ["fe", "first_order"]
    # the same point through the FE: the first-order law is within 1.5% of it
    lookup = stack.object_lookup(BLOCK, 0.06, 0.045, 0.03)
    breaks = stack.object_breaks(BLOCK, 0.03)
    column = stack.point_law(lookup, 0.03, breaks, R, 0.006, lateral=False)

    def column_lookup(offsets, depths):
        young, poisson, _ = lookup(np.zeros_like(offsets), depths)
        return young, poisson, np.ones(len(depths), dtype=bool)

    fe = stack.axisymmetric_law(lookup, 0.03, R, 0.006, breaks_z=breaks,
                                breaks_r=stack.object_radial_breaks(BLOCK, 0.06, 0.045),
                                surface=RUBBER, column=column, column_lookup=column_lookup)
    np.testing.assert_allclose(far.force_at(d), fe.force_at(d), rtol=0.015)
    # the lump 10 mm aside stiffens the deepest press by more than first order may take, and every press somewhat
    near_column = stack.point_law(stack.object_lookup(BLOCK, 0.045, 0.025, 0.03), 0.03, breaks, R, 0.006,
                                  lateral=False)
    assert near_lump.force_at(d[-1:])[0] > near_column.force_at(d[-1:])[0] * (1 + FIRST_ORDER_LIMIT)
    assert np.all(near_lump.force_at(d) > near_column.force_at(d))


def test_no_lateral_variation_has_no_first_order_effect():
    lookup = stack.object_lookup(BLOCK, 0.06, 0.04, 0.03)

    def column_lookup(offsets, depths):
        young, poisson, _ = lookup(np.zeros_like(offsets), depths)
        return young, poisson, np.ones(len(depths), dtype=bool)

    energy = stack._column_energy(column_lookup, 0.03, [], R, 0.006, "bonded", None)
    np.testing.assert_allclose(energy.element_energy.sum(axis=1), 1.0, rtol=1e-9)
    assert np.all(lateral_effect(column_lookup, column_lookup, energy) == 0.0)
