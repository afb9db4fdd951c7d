"""The `flex` window's grid (node planes on material interfaces, a cylinder's whole disc) and its element
(the general hexahedron and its incompatible bending modes)."""

from __future__ import annotations

import numpy as np
import pytest

from palpate.core.errors import ValidationError
from palpate.core.world.scene import Inclusion, Layer, Material, ObjectSpec
from palpate.sim.flex import element as flex_element
from palpate.sim.flex import grid as flex_grid

BASE = Material("base", 1e5, 0.45)
STIFF = Material("stiff", 2e6, 0.4)
SOFT = Material("soft", 2e4, 0.3)


def _box(**kw) -> ObjectSpec:
    return ObjectSpec("b", "box", (0.2, 0.2, 0.03), (0.0, 0.0), BASE, **kw)


def test_a_stiff_skin_gets_node_planes_and_bending_cells_and_a_soft_one_is_mixed():
    g = flex_grid.flex_grid(_box(layers=(Layer(STIFF, 0.002),)), 0.0, 0.0)
    # the skin's bottom is a node plane, LAYER_CELLS cells through it, and only those cells bend
    np.testing.assert_allclose(g.z[-flex_grid.LAYER_CELLS - 1:], np.linspace(0.028, 0.03, flex_grid.LAYER_CELLS + 1))
    np.testing.assert_array_equal(g.bending, np.arange(g.cells[2]) >= g.cells[2] - flex_grid.LAYER_CELLS)
    assert g.bending_cells().sum() == g.cells[0] * g.cells[1] * flex_grid.LAYER_CELLS
    # a soft skin is squeezed, not bent: no plane of its own (the series mix of its cell is exact for a squeeze)
    soft = flex_grid.flex_grid(_box(layers=(Layer(SOFT, 0.002),)), 0.0, 0.0)
    assert not np.any(np.isclose(soft.z, 0.028)) and not soft.bending.any()
    np.testing.assert_allclose(np.diff(soft.z), 0.005)


def test_a_stiff_skin_gets_a_wide_graded_window_and_other_objects_keep_the_default_one():
    """A plate spreads its load far, so over a stiff layer the window is PLATE_WINDOW_SCALE times as wide (its sides
    pinned, the free calibration table's), fine at the press and coarser out; a soft skin and a homogeneous block
    keep the uniform default window, and plate=False gives a stiff skin that one too."""
    skin = _box(layers=(Layer(STIFF, 0.002),))
    res, win = flex_grid.DEFAULT_RESOLUTION, flex_grid.DEFAULT_WINDOW
    g = flex_grid.flex_grid(skin, 0.0, 0.0)
    for nodes in (g.x, g.y):
        assert nodes[-1] - nodes[0] == pytest.approx(flex_grid.PLATE_WINDOW_SCALE * win)
        steps = np.diff(nodes)
        core = np.abs(nodes[:-1] + steps / 2.0) < flex_grid.PLATE_CORE_CELLS * res
        np.testing.assert_allclose(steps[core], res)
        assert core.sum() == 2 * flex_grid.PLATE_CORE_CELLS and np.all(steps[~core] > res)
        assert np.all(np.diff(steps[nodes[:-1] >= 0.0]) >= 0.0)  # coarser away from the press, never finer
    assert g.far_sides and all(g.pinned)
    flat = flex_grid.flex_grid(skin, 0.0, 0.0, plate=False)
    np.testing.assert_allclose(flat.z, g.z)
    for obj, grid in ((skin, flat), (_box(layers=(Layer(SOFT, 0.002),)), None), (_box(), None)):
        grid = flex_grid.flex_grid(obj, 0.0, 0.0) if grid is None else grid
        assert not grid.far_sides and grid.size[0] == pytest.approx(win)
        np.testing.assert_allclose(np.diff(grid.x), res)
    # a cylinder narrow enough for the default window stays a whole disc, skin or not
    disc = flex_grid.flex_grid(ObjectSpec("c", "cylinder", (0.01, 0.03), (0.0, 0.0), BASE,
                                          layers=(Layer(STIFF, 0.002),)), 0.0, 0.0)
    assert disc.disc_radius == pytest.approx(0.01) and not disc.far_sides


def test_an_interface_near_a_node_moves_it_instead_of_cutting_a_sliver():
    nodes = np.array([0.0, 0.005, 0.010, 0.015, 0.020])
    out = flex_grid.with_planes(nodes, [0.0106, 0.0178, 0.0152, 0.03], snap=0.00125)
    # 0.0106 is 0.6 mm from 0.010: moved; 0.0178 is 2.2 mm from its nearest node, 0.020 (an end): inserted; 0.0152
    # is 0.2 mm from 0.015: moved; 0.03 is outside: ignored
    np.testing.assert_allclose(out, [0.0, 0.005, 0.0106, 0.0152, 0.0178, 0.020])


def test_only_a_layer_stiffer_than_what_lies_under_it_gets_a_plane():
    """A stiff 2 mm skin over a soft 4 mm layer over the base: the skin's bottom is a plane (it bends on the soft
    layer), the soft layer's is not (it is squeezed between two stiffer ones); a lump gets none (mixed cells)."""
    lump = Inclusion(STIFF, "sphere", (0.0, 0.0, 0.0165), (0.004,))
    g = flex_grid.flex_grid(_box(layers=(Layer(STIFF, 0.002), Layer(SOFT, 0.004)), inclusions=(lump,)), 0.0, 0.0)
    assert np.any(np.isclose(g.z, 0.028)) and not np.any(np.isclose(g.z, 0.024))
    for planes in (0.0125, 0.0205):
        assert not np.any(np.isclose(g.z, planes))
    assert not np.any(np.isclose(np.abs(g.x), 0.004))
    assert g.bending.sum() == flex_grid.LAYER_CELLS


def test_a_narrow_cylinder_is_meshed_to_its_free_curved_side():
    obj = ObjectSpec("c", "cylinder", (0.006, 0.02), (0.01, -0.02), BASE)
    g = flex_grid.flex_grid(obj, 0.01, -0.02)
    assert g.disc_radius == pytest.approx(0.006) and g.pinned == (False, False, False, False)
    nodes = g.nodes().reshape(g.cells[0] + 1, g.cells[1] + 1, g.cells[2] + 1, 3)
    r = np.hypot(nodes[..., 0] - 0.01, nodes[..., 1] + 0.02)
    ring = np.zeros(r.shape, dtype=bool)
    ring[[0, -1], :, :] = ring[:, [0, -1], :] = True
    np.testing.assert_allclose(r[ring], 0.006, rtol=1e-12)  # the grid's sides lie on the curved side
    assert np.all(r[~ring] < 0.006)
    assert np.min(r) == pytest.approx(0.0, abs=1e-12)  # a node column on the axis
    # the cells fill the disc: their volumes add up to the cylinder's (to the polygon's chords)
    vol = flex_element.hex_volumes(g.cell_corners()).sum()
    assert vol == pytest.approx(np.pi * 0.006**2 * 0.02, rel=0.06) and vol < np.pi * 0.006**2 * 0.02
    # the bottom is pinned and nothing else
    assert len(g.pinned_nodes()) == (g.cells[0] + 1) * (g.cells[1] + 1)
    # a cylinder too wide for the window keeps the square inscribed in it, cut (pinned) by the window
    wide = flex_grid.flex_grid(ObjectSpec("w", "cylinder", (0.05, 0.02), (0.0, 0.0), BASE), 0.0, 0.0)
    assert wide.disc_radius == 0.0 and all(wide.pinned)


def test_the_general_hexahedron_is_the_box_cell_and_an_inverted_cell_is_refused():
    """On an axis-aligned cell the isoparametric element reduces to the closed form: the (div u)^2 part of a
    uniform dilatation u = x is vol * 9 (trace 3), the centre-point part has rank 1, the 2 e:e part of a shear
    u_x = y is vol * 1 (2 * 2 * (1/2)^2)."""
    h = np.array([0.005, 0.004, 0.002])
    c = flex_element.box_corners(h)
    vol_full, vol_centre, ee = (-k for k in flex_element.hex_bases(c))
    dilate, shear = c.ravel(), np.column_stack([c[:, 1], 0 * c[:, 1], 0 * c[:, 1]]).ravel()
    assert dilate @ vol_full @ dilate == pytest.approx(9.0 * h.prod(), rel=1e-12)
    assert dilate @ vol_centre @ dilate == pytest.approx(9.0 * h.prod(), rel=1e-12)
    assert shear @ ee @ shear == pytest.approx(h.prod(), rel=1e-12)
    assert np.linalg.matrix_rank(vol_centre, tol=1e-9 * np.abs(vol_full).max()) == 1
    # a distorted cell integrates to its own volume; one turned inside out is an error, not a negative stiffness
    bent = c.copy()
    bent[7] += [0.001, 0.0005, 0.0003]
    assert flex_element.hex_volumes(bent[None])[0] > h.prod()
    flipped = c.copy()
    flipped[:, 2] *= -1
    with pytest.raises(ValidationError, match="inverted"):
        flex_element.hex_bases(flipped)


def test_incompatible_modes_bend_a_thin_cell_exactly_and_keep_its_rigid_and_linear_fields():
    """Pure bending u_x = x z, u_z = -x^2 / 2 (centred) has 2 e:e = 2 z^2, energy 2 hx hy hz^3 / 12 per unit mu:
    the enriched cell gives it exactly; the plain trilinear cell adds spurious shear (locking), several times more
    on a cell five times wider than thick. Rigid motions cost nothing and a linear field (the patch test) costs
    exactly its energy, also on a distorted cell."""
    h = np.array([0.005, 0.005, 0.001])
    c = flex_element.box_corners(h) - h / 2.0
    plain = -flex_element.hex_bases(c)[2]
    enriched = -flex_element.bending_ee(c[None])[0]
    x, z = c[:, 0], c[:, 2]
    u = np.column_stack([x * z, 0 * x, -x**2 / 2.0]).ravel()
    exact = 2.0 * h[0] * h[1] * h[2] ** 3 / 12.0
    assert u @ enriched @ u == pytest.approx(exact, rel=1e-9)
    assert u @ plain @ u > 5.0 * exact
    rng = np.random.default_rng(3)
    distorted = c + rng.uniform(-2e-4, 2e-4, c.shape)
    k = -flex_element.bending_ee(distorted[None])[0]
    a = rng.normal(size=(3, 3))
    e = (a + a.T) / 2.0
    vol = flex_element.hex_volumes(distorted[None])[0]
    linear = (distorted @ a.T).ravel()
    assert linear @ k @ linear == pytest.approx(2.0 * vol * np.sum(e * e), rel=1e-9)
    spin = np.cross([0.3, -0.2, 1.0], distorted).ravel() + np.tile([1.0, 2.0, 3.0], 8)
    assert abs(spin @ k @ spin) < 1e-9 * np.abs(k).max()


def test_the_mixing_correction_is_the_layered_law_of_the_mixed_column_over_the_layers():
    from palpate.sim.contact.law import solve_contact_law
    from palpate.sim.flex.mixing import SUBCELL, mixing_correction
    from palpate.sim.reference.sample import AxisymmetricSample

    base = Material("base", 2e5, 0.45)
    obj = ObjectSpec("b", "box", (0.2, 0.2, 0.03), (0.0, 0.0), base, layers=(Layer(SOFT, 0.001),))
    mix = mixing_correction(obj, flex_grid.flex_grid(obj, 0.0, 0.0), 0.008)
    # by hand: the top 5 mm cell samples SUBCELL points down its column, one of them (0.625 mm down) in the skin
    n_skin = 1
    assert SUBCELL == 4
    young = 1.0 / (n_skin / SUBCELL / SOFT.young + (SUBCELL - n_skin) / SUBCELL / base.young)
    nu = (n_skin * SOFT.poisson + (SUBCELL - n_skin) * base.poisson) / SUBCELL
    depths = np.array([0.2, 0.5, 1.0, 2.0, 4.0]) * 1e-3
    mixed = solve_contact_law(AxisymmetricSample(base, 0.03, layers=(Layer(Material("m", young, nu), 0.005),)),
                              0.008, 0.006).force_at(depths)
    true = solve_contact_law(AxisymmetricSample(base, 0.03, layers=obj.layers), 0.008, 0.006).force_at(depths)
    np.testing.assert_allclose([mix.at(d) for d in depths], mixed / true, rtol=0.01)
    # the mix is stiffer than the skin under a contact narrower than the cell
    assert mix.at(0.5e-3) > 1.1
    # where the press reads the mesh correction: the mixed column's contact radius over that of a homogeneous block
    # of the object's height and the skin's Poisson ratio (any modulus: a block's contact radius has none in it),
    # wider than the block's (a softer top)
    column = solve_contact_law(AxisymmetricSample(base, 0.03, layers=(Layer(Material("m", young, nu), 0.005),)),
                               0.008, 0.006)
    block = solve_contact_law(AxisymmetricSample(Material("h", 7e3, SOFT.poisson), 0.03), 0.008, 0.006)
    np.testing.assert_allclose([mix.contact_at(d) for d in depths],
                               column.contact_radius_at(depths) / block.contact_radius_at(depths), rtol=0.01)
    assert min(mix.contact_at(d) for d in depths[1:]) > 1.02
    # no correction where no cell mixes: a homogeneous block, a stiff skin (node planes), a skin one cell thick
    for layers in ((), (Layer(STIFF, 0.002),), (Layer(SOFT, 0.005),)):
        o = ObjectSpec("b", "box", (0.2, 0.2, 0.03), (0.0, 0.0), base, layers=layers)
        assert mixing_correction(o, flex_grid.flex_grid(o, 0.0, 0.0), 0.008) is None


@pytest.mark.parametrize("obj", [_box(), ObjectSpec("c", "cylinder", (0.01, 0.02), (0.003, -0.002), BASE)])
def test_the_cells_lookup_finds_each_cell_from_its_centre_also_through_the_disc_map(obj):
    from palpate.sim.flex.mixing import cell_lookup

    grid = flex_grid.flex_grid(obj, 0.004, -0.001)
    n = int(np.prod(grid.cells))
    young, poisson = np.arange(1.0, n + 1.0), np.linspace(0.1, 0.4, n)
    x, y = 0.004, -0.001
    centres = grid.cell_centres()  # mapped onto the disc, if any
    e, nu, inside = cell_lookup(obj, grid, young, poisson, x, y)(centres[:, :2] - [x, y], obj.height - centres[:, 2])
    np.testing.assert_array_equal(e, young)
    np.testing.assert_allclose(nu, poisson)
    assert inside.all()


def test_the_lateral_mixing_correction_is_one_where_cells_hold_the_lump_and_not_under_a_shallow_sphere():
    """An inclusion whose faces lie on the cells' faces is not mixed (its cells are the object): no correction. A
    5 mm sphere 1 mm under the top is spread over the four 5 mm cells around the axis, and their mix is softer than
    a hard sphere (stiffer than a soft one) under a contact narrower than a cell, by less once the contact spans
    the cells."""
    from palpate.sim.flex.mixing import cell_moduli, lateral_mixing_correction

    aligned = _box(inclusions=(Inclusion(STIFF, "box", (0.0, 0.0, 0.0225), (0.01, 0.01, 0.005)),))
    grid = flex_grid.flex_grid(aligned, 0.0, 0.0)
    young, poisson = cell_moduli(aligned, grid)
    stiff = np.isclose(young, STIFF.young)
    assert stiff.sum() == 4 and np.all(stiff | np.isclose(young, BASE.young))
    corr = lateral_mixing_correction(aligned, grid, young, poisson, 0.008, 0.0, 0.0)
    np.testing.assert_allclose(corr.ratio, 1.0, rtol=1e-9)
    for lump, below in ((STIFF, True), (Material("pocket", 1e4, 0.3), False)):
        obj = _box(inclusions=(Inclusion(lump, "sphere", (0.0, 0.0, 0.024), (0.005,)),))
        grid = flex_grid.flex_grid(obj, 0.0, 0.0)
        corr = lateral_mixing_correction(obj, grid, *cell_moduli(obj, grid), 0.008, 0.0, 0.0)
        shallow, deep = corr.at(0.5e-3), corr.at(4e-3)
        assert (shallow < 0.9) if below else (shallow > 1.1)
        assert abs(deep - 1.0) < abs(shallow - 1.0)


def test_the_lateral_mixing_correction_solves_on_one_blas_thread_and_gives_the_default_threads_answer(monkeypatch):
    """The correction's FE solves (two fields on one mesh) run with BLAS on one thread (on a busy machine
    OpenBLAS's threads waited for cores and then spun beside MuJoCo) and BLAS's thread count is back afterwards;
    the ratio is the one computed at BLAS's own thread count (the previous form) within rounding."""
    import contextlib

    from threadpoolctl import threadpool_info

    from palpate.sim.flex import mixing as flex_mixing

    def blas_threads() -> list[int]:
        return [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]

    obj = _box(inclusions=(Inclusion(STIFF, "sphere", (0.0, 0.0, 0.024), (0.005,)),))
    grid = flex_grid.flex_grid(obj, 0.0, 0.0)
    moduli = flex_mixing.cell_moduli(obj, grid)
    seen, real = [], flex_mixing.fe_presses

    def spy(*args, **kwargs):
        seen.append(blas_threads())
        return real(*args, **kwargs)

    monkeypatch.setattr(flex_mixing, "fe_presses", spy)
    before = blas_threads()
    limited = flex_mixing.lateral_mixing_correction(obj, grid, *moduli, 0.008, 0.0, 0.0)
    assert len(seen) == 1 and all(s and set(s) == {1} for s in seen)
    assert blas_threads() == before
    monkeypatch.setattr(flex_mixing, "one_blas_thread", contextlib.nullcontext)
    free = flex_mixing.lateral_mixing_correction(obj, grid, *moduli, 0.008, 0.0, 0.0)
    assert len(seen) == 2 and seen[1] == before
    np.testing.assert_allclose(limited.ratio, free.ratio, rtol=1e-9)
