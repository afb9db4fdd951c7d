"""The 3-D FE check of off-axis lumps (sim/reference/fe3d.py) and what it finds about the contact law beside a box
lump (sim/validity/offaxis.py; the table: benchmarks/fe_offaxis.py).

The 3-D FE is first checked against the axisymmetric reference on a homogeneous block (its own mesh error), then
the law is checked against it beside a stiff shallow lump, on rows its ring mixing was not chosen on.
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("skfem")

from palpate.core.errors import ValidationError  # noqa: E402
from palpate.core.world.scene import Material  # noqa: E402
from palpate.sim.contact.lcp import solve_contact  # noqa: E402
from palpate.sim.reference.fe import fe_press  # noqa: E402
from palpate.sim.reference.fe3d import BoxBlock, BoxLump  # noqa: E402
from palpate.sim.reference.fe3d_solve import fe3d_press  # noqa: E402
from palpate.sim.reference.sample import AxisymmetricSample  # noqa: E402
from palpate.sim.validity.offaxis import (  # noqa: E402
    BULK_E,
    DEPTHS,
    HALF,
    THICKNESS,
    TIP,
    OffAxisCase,
    compare,
)

pytestmark = pytest.mark.physics


def test_the_lcp_solver_releases_a_node_that_would_pull_and_keeps_the_rest_out_of_the_sphere():
    # pressing node 0 its gap drags node 1 down past its own gap (strong coupling): with both held at their gaps
    # node 1 would have to pull (f = [2.89, -2.11]); released, node 0 carries it all and node 1 sits below its gap
    c = np.array([[1.0, 0.9], [0.9, 1.0]])
    g = np.array([1.0, 0.5])
    assert np.linalg.solve(c, g)[1] < 0
    f, _ = solve_contact(c, g)
    np.testing.assert_allclose(f, [1.0, 0.0])
    assert np.all(c @ f >= g)
    np.testing.assert_array_equal(solve_contact(c, np.array([-1.0, -0.5]))[0], [0.0, 0.0])


def test_a_lump_outside_the_block_or_a_bad_depth_is_a_clear_error():
    bulk = Material("bulk", BULK_E, 0.3)
    with pytest.raises(ValidationError, match="lump must lie inside"):
        BoxBlock(bulk, 0.02, 0.04, 0.04, BoxLump(bulk, 0.03, 0.015, 0.02, 0.001, 0.01))
    with pytest.raises(ValidationError, match="depth"):
        BoxLump(bulk, 0.0, 0.015, 0.02, 0.0, 0.01)
    with pytest.raises(ValidationError, match="depths must lie"):
        fe3d_press(BoxBlock(bulk, 0.02, 0.04, 0.04), TIP, [0.0075])


@pytest.mark.parametrize("nu", [0.3, 0.45])
def test_the_3d_fe_of_a_homogeneous_block_matches_the_axisymmetric_reference(nu):
    # an independent solver (trilinear bricks, selective reduced integration, nodal contact) on the same sample:
    # the benchmark measures +-1.6% (nu 0.3) and +1-2% (nu 0.45); 3% leaves room for the square vs round side
    m = Material("bulk", BULK_E, nu)
    fe3 = fe3d_press(BoxBlock(m, THICKNESS, HALF, HALF), TIP, DEPTHS)
    ref = fe_press(AxisymmetricSample(m, THICKNESS), TIP, DEPTHS, refinement=1.0).force
    np.testing.assert_allclose(fe3.force, ref, rtol=0.03)
    assert np.all(np.diff(fe3.contact_nodes) > 0)


def test_the_law_is_within_ten_percent_of_the_3d_fe_beside_a_stiff_shallow_lump():
    """Off-axis lumps (issue 12): a 20x lump 1 mm down, pressed over its edge and 3 mm beside it, at nu 0.45. The
    law's ring mixing (geometric mean) was chosen on the nu 0.3 rows of benchmarks/fe_offaxis.py; these rows were
    not used. The arithmetic ring mean it replaced was +46..+58% here."""
    cache: dict = {}
    edge = compare(OffAxisCase(20.0, 0.001, 0.0, 0.45), cache=cache)
    aside = compare(OffAxisCase(20.0, 0.001, 0.003, 0.45), cache=cache)
    assert np.all(edge.fe_ratio > 1.2) and np.all(aside.fe_ratio > 1.0)
    assert np.all(aside.fe_ratio < edge.fe_ratio)
    for row in (edge, aside):
        assert np.all(np.abs(row.error) < 0.10), row.error


def test_the_law_is_within_ten_percent_of_the_3d_fe_beside_a_soft_shallow_pocket():
    """A 20x softer lump 1 mm down (a pocket under a skin), pressed over its edge and 3 mm beside it, at nu 0.3.
    The exponent of the sectors softer than the matrix was chosen on the nu 0.45 soft rows of
    benchmarks/fe_offaxis.py --soft; these rows were not used. The geometric ring mean before it was -40% and
    -10..-20% here: the stiff bulk bridges a soft pocket."""
    cache: dict = {}
    edge = compare(OffAxisCase(0.05, 0.001, 0.0, 0.3), cache=cache)
    aside = compare(OffAxisCase(0.05, 0.001, 0.003, 0.3), cache=cache)
    assert np.all(edge.fe_ratio < 0.6) and np.all(aside.fe_ratio < 0.9)
    assert np.all(aside.fe_ratio > edge.fe_ratio)
    for row in (edge, aside):
        assert np.all(np.abs(row.error) < 0.10), row.error
