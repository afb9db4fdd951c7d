"""The 3-D FE image reference: the sensel integration of nodal forces (sim/reference/fe3d_image.py), the
condensation and mesh of the 3-D solve (sim/reference/fe3d_solve.py, fe3d.py), the cases
(sim/validity/image_cases.py) and the cached images (models/image_reference.json).

The default tests check the pieces against closed forms and the shipped file's shape; the physics ones recompute
a case against the cache and check the model against itself (half against full, a wall turned a quarter) and its
convergence.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from palpate.core.errors import ValidationError
from palpate.core.world.scene import FingertipSpec, Material, material_index_at
from palpate.sim.reference.fe3d import BoxBlock, Wall, block_grids
from palpate.sim.reference.fe3d_image import field_image, sensel_forces, tributary_edges
from palpate.sim.reference.fe3d_solve import SurfaceContact, condensed_compliance, dissection_rank
from palpate.sim.validity.image import image_errors
from palpate.sim.validity.image_cases import DEPTHS, STAIR_NEAR, core_cases, image_cases, wall_case
from palpate.sim.validity.image_reference import (
    IMAGE_REFERENCE_PATH,
    compute_case,
    load_image_reference,
    reference_image,
)

TIP = FingertipSpec()


def _field(x, y, force) -> SurfaceContact:
    return SurfaceContact(depth=np.array([0.001]), x=np.asarray(x), y=np.asarray(y), force=force[None],
                          contact_nodes=np.array([1]), dofs=3, h=0.001, half=False)


def test_a_uniform_pressure_reads_the_same_on_every_sensel_and_a_node_splits_by_its_strip():
    # nodes on an uneven grid carrying p0 times their dual cells: each footprint lies inside the grid, so every
    # sensel reads p0 exactly
    x = np.concatenate([np.linspace(-0.008, 0.0, 9), [0.0013, 0.004, 0.0061, 0.008]])
    y = np.linspace(-0.007, 0.007, 11)
    wx, wy = np.diff(tributary_edges(x)), np.diff(tributary_edges(y))
    p0 = 3.0e4
    image = field_image(_field(x, y, p0 * wy[:, None] * wx[None, :]), TIP)
    np.testing.assert_allclose(image.pressure[0], p0, rtol=1e-12)
    # one node at x = 0 (strip -0.5..+0.5 mm) on y = 1.25 mm: the pad's columns 1 and 2 end 0.15 mm either side
    # of x = 0, so each sees 0.35 / 1 of the node's force
    x = np.array([-0.001, 0.0, 0.001])
    y = np.array([0.00025, 0.00125, 0.00225])
    force = np.zeros((3, 3))
    force[1, 1] = 1.0
    got = sensel_forces(_field(x, y, force), TIP)[0]
    expected = np.zeros((4, 4))
    expected[1, 1] = expected[1, 2] = 0.35  # row 1 spans y 0.15..2.35 mm, holding the whole strip in y
    np.testing.assert_allclose(got, expected, atol=1e-12)


def test_tributary_edges_are_midpoints_with_mirrored_ends():
    np.testing.assert_allclose(tributary_edges([0.0, 1.0, 3.0]), [-0.5, 0.5, 2.0, 4.0])


def test_the_share_beyond_a_wall_is_exact_off_it_and_halves_a_square_it_crosses_diagonally():
    soft, hard = Material("a", 1e4), Material("b", 1e5)
    block = BoxBlock(soft, 0.03, 0.04, 0.04, wall=Wall(hard, math.radians(45), 0.0))
    got = block.far_fraction([-1.0, 1.0, -3.0], [1.0, 2.0, -2.0], [-1.0, 1.0, -3.0], [1.0, 2.0, -2.0])
    np.testing.assert_allclose(got, [0.5, 1.0, 0.0], atol=1e-12)
    assert not block.symmetric_y
    assert BoxBlock(soft, 0.03, 0.04, 0.04, wall=Wall(hard, 0.0, 0.001)).symmetric_y


def test_an_axis_aligned_wall_is_a_grid_line_flanked_a_quarter_cell_either_side():
    for offset in (-4, -2, 0, 1, 2, 6):
        case = wall_case(20, 115, 0.45, 0, offset)
        x = block_grids(case.block, 0.0065, 0.0007).x
        at = offset * 1e-3
        for line in (at - 0.000175, at, at + 0.000175):
            assert np.min(np.abs(x - line)) < 1e-12, (offset, line)
        assert np.diff(x).min() > 0.00017


def test_nested_dissection_numbers_every_node_once():
    rank = dissection_rank((7, 5, 9), leaf=8)
    np.testing.assert_array_equal(np.sort(rank), np.arange(7 * 5 * 9))


def test_the_condensed_compliance_is_the_inverse_of_the_schur_complement():
    # a symmetric positive definite 'stiffness' on a 6 x 5 x 4 grid (a 27-point stencil, 3 dofs a node): the
    # condensation onto some top dofs equals the block of the dense inverse
    import scipy.sparse as sp

    shape = (6, 5, 4)
    n = int(np.prod(shape))
    rng = np.random.default_rng(3)
    one = [sp.diags([-1.0, 3.0, -1.0], [-1, 0, 1], shape=(m, m)) for m in shape]
    lap = sp.kron(sp.kron(one[0], one[1]), one[2])
    k = sp.kron(lap, np.eye(3) + 0.2 * np.ones((3, 3))).tocsr()
    k = k + sp.diags(rng.uniform(0.1, 1.0, 3 * n))
    free = np.arange(3, 3 * n)  # the first node fixed
    surface = 3 * np.flatnonzero(np.indices(shape).reshape(3, -1)[2] == shape[2] - 1) + 2
    surface = surface[surface >= 3]
    node_rank = np.repeat(dissection_rank(shape), 3)
    got = condensed_compliance(k, free, surface, node_rank)
    at = -np.ones(3 * n, dtype=int)
    at[free] = np.arange(len(free))
    dense = np.linalg.inv(k[free][:, free].toarray())[np.ix_(at[surface], at[surface])]
    np.testing.assert_allclose(got, dense, rtol=1e-9, atol=1e-12 * np.abs(dense).max())


def test_the_cases_are_unique_a_third_held_out_and_their_scenes_hold_the_fe_materials():
    cases = image_cases()
    names = [c.name for c in cases]
    assert len(set(names)) == len(names)
    assert {c.family for c in cases} == {"block", "wall", "lump", "skin"}
    report = sum(c.split == "report" for c in cases) / len(cases)
    assert 0.25 < report < 0.45
    for family in ("block", "wall", "lump", "skin"):
        assert {c.split for c in cases if c.family == family} == {"tuning", "report"}
    assert {c.name for c in core_cases()} <= set(names) and len(core_cases()) == 8
    rng = np.random.default_rng(0)
    for case in cases:
        b = case.block
        obj = case.object_spec()
        assert obj.size == (2 * b.half_x, 2 * b.half_y, b.thickness) and case.press_point == (0.0, 0.0)
        pts = np.column_stack([rng.uniform(-0.012, 0.012, 4000), rng.uniform(-0.012, 0.012, 4000),
                               rng.uniform(0.0, b.thickness, 4000)])
        young, _ = b.materials_at(pts[:, 0], pts[:, 1], b.thickness - pts[:, 2])
        names = [m.name for m in obj.materials()]
        scene_young = np.array([obj.materials()[i].young for i in material_index_at(obj, pts, names)])
        keep = np.ones(len(pts), dtype=bool)
        if b.wall is not None:  # the staircase of a rotated wall may differ within one strip of it
            c, s = b.wall.normal
            keep = np.abs(c * pts[:, 0] + s * pts[:, 1] - b.wall.offset) > STAIR_NEAR
        np.testing.assert_array_equal(scene_young[keep], young[keep], err_msg=case.name)


def test_the_shipped_image_reference_holds_every_case_well_formed():
    reference = load_image_reference()
    assert set(reference.cases) == {c.name for c in image_cases()}
    for case in image_cases():
        image = reference_image(reference, case)
        np.testing.assert_allclose(image.depth, DEPTHS)
        assert image.pressure.shape == (len(DEPTHS), TIP.rows, TIP.cols)
        # the pad sees at most the whole force, and a real share of it
        seen = image.pressure.sum(axis=(1, 2)) * TIP.sensel_area
        assert np.all(seen <= image.force * (1 + 1e-9)) and np.all(seen > 0.3 * image.force)
        assert reference.cases[case.name].split == case.split
    assert len({c.case for c in reference.convergence}) >= 5
    for change in reference.convergence:
        assert np.all(change.rms_share < 0.05) and np.all(np.abs(change.force_change) < 0.03), change


def test_a_bad_image_reference_file_is_a_clear_error(tmp_path):
    doc = json.loads(IMAGE_REFERENCE_PATH.read_text())
    name = next(iter(doc["cases"]))
    doc["cases"][name]["pressure"] = doc["cases"][name]["pressure"][:-1]
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(ValidationError, match="pressure"):
        load_image_reference(path)
    path.write_text(json.dumps({**doc, "version": 99}))
    with pytest.raises(ValidationError, match="version"):
        load_image_reference(path)
    with pytest.raises(ValidationError, match="image_reference.py --write"):
        load_image_reference(tmp_path / "missing.json")


@pytest.mark.physics
def test_a_recomputed_case_matches_the_cache():
    pytest.importorskip("skfem")
    reference = load_image_reference()
    case = next(c for c in core_cases() if c.name == "wall_20-115kPa_t0_o+2mm_nu0.45")
    entry = compute_case(case, TIP)
    np.testing.assert_allclose(entry["force"], reference_image(reference, case).force, rtol=1e-6)
    np.testing.assert_allclose(entry["pressure"], reference_image(reference, case).pressure, rtol=1e-6,
                               atol=1e-6 * np.max(entry["pressure"]))


@pytest.mark.physics
def test_the_image_converges_under_refinement_beside_a_wall():
    # h -> h / sqrt(2) on the 20|115 kPa wall on the axis (the pressure jumps under the pad's centre line): the
    # image changes by under 3% of its peak sensel and the force by under 1%
    pytest.importorskip("skfem")
    from palpate.sim.reference.fe3d_image import fe3d_image
    from palpate.sim.validity.image_reference import GROWTH, H

    case = wall_case(20, 115, 0.45, 0, 0)
    coarse, _ = fe3d_image(case.block, TIP, DEPTHS, h=H, growth=GROWTH)
    fine, _ = fe3d_image(case.block, TIP, DEPTHS, h=H / math.sqrt(2), growth=GROWTH)
    err = image_errors(coarse, fine, TIP)
    assert np.all(err.rms_share < 0.03), err.rms_share
    assert np.all(np.abs(err.force_error) < 0.01), err.force_error
    assert np.all(err.reference_asymmetry > 0.5)  # the stiff side (+x) carries most of the load


@pytest.mark.physics
def test_the_full_model_matches_the_half_model_and_a_wall_turned_a_quarter_turns_the_image():
    pytest.importorskip("skfem")
    from palpate.sim.reference.fe3d_image import fe3d_image

    depths = (0.001, 0.003)
    block = BoxBlock(Material("115kPa", 115e3, 0.45), 0.03, 0.04, 0.04)
    half, field = fe3d_image(block, TIP, depths, h=0.001)
    full, _ = fe3d_image(block, TIP, depths, h=0.001, half=False)
    assert field.half
    np.testing.assert_allclose(full.force, half.force, rtol=1e-6)
    np.testing.assert_allclose(full.pressure, half.pressure, rtol=1e-6, atol=1e-6 * half.pressure.max())
    along_y, _ = fe3d_image(wall_case(20, 115, 0.45, 0, 2).block, TIP, depths, h=0.001, half=False)
    along_x, _ = fe3d_image(wall_case(20, 115, 0.45, 90, 2).block, TIP, depths, h=0.001)
    np.testing.assert_allclose(along_x.force, along_y.force, rtol=1e-6)
    # the stiff side at +x loads the right columns; turned to +y it loads the top rows (row 0 at +y)
    np.testing.assert_allclose(along_x.pressure, np.rot90(along_y.pressure, k=1, axes=(1, 2)), rtol=1e-6,
                               atol=1e-6 * along_y.pressure.max())
    with pytest.raises(ValidationError, match="not symmetric"):
        fe3d_image(wall_case(20, 115, 0.45, 90, 2).block, TIP, depths, h=0.001, half=True)


@pytest.mark.physics
def test_the_plain_block_image_matches_the_axisymmetric_fe():
    # an independent solver (axisymmetric quadratic elements) on the same block's disc: its pressure profile over
    # the sensel squares against the 3-D image (the benchmark: force +0.2..+0.7%, image rms 0.1-0.8% of the peak)
    pytest.importorskip("skfem")
    from palpate.sim.reference.fe import fe_press
    from palpate.sim.reference.fe3d_image import fe3d_image, radial_image
    from palpate.sim.reference.sample import AxisymmetricSample
    from palpate.sim.validity.image_reference import GROWTH, H

    case = next(c for c in image_cases() if c.name == "block_115kPa_nu0.45")
    image, _ = fe3d_image(case.block, TIP, DEPTHS, h=H, growth=GROWTH)
    axi = fe_press(AxisymmetricSample(case.block.material, case.block.thickness), TIP.radius, DEPTHS)
    err = image_errors(image, radial_image(axi.depth, axi.force, axi.r, axi.pressure, TIP), TIP)
    assert np.all(np.abs(err.force_error) < 0.015), err.force_error
    assert np.all(err.rms_share < 0.02), err.rms_share
    np.testing.assert_array_equal(err.active, err.reference_active)


@pytest.mark.physics
def test_the_nearly_incompressible_mesh_matches_the_axisymmetric_fe():
    # at nu 0.49 the default mesh's tall bricks under the contact stiffen the block (+6..+9%, the benchmark); the
    # mesh the reference uses there holds force within 3% from 1 mm deep and the image within 3% of its peak
    pytest.importorskip("skfem")
    from palpate.sim.reference.fe import fe_press
    from palpate.sim.reference.fe3d_image import fe3d_image, radial_image
    from palpate.sim.reference.sample import AxisymmetricSample
    from palpate.sim.validity.image_reference import NEAR_INCOMPRESSIBLE, case_mesh

    case = next(c for c in image_cases() if c.name == "block_115kPa_nu0.49")
    assert case_mesh(case) == NEAR_INCOMPRESSIBLE
    image, _ = fe3d_image(case.block, TIP, DEPTHS, **case_mesh(case))
    axi = fe_press(AxisymmetricSample(case.block.material, case.block.thickness), TIP.radius, DEPTHS)
    err = image_errors(image, radial_image(axi.depth, axi.force, axi.r, axi.pressure, TIP), TIP)
    deep = np.asarray(DEPTHS) >= 0.001
    assert np.all(np.abs(err.force_error[deep]) < 0.03), err.force_error
    assert np.all(err.rms_share[deep] < 0.03), err.rms_share
