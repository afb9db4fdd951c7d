"""The ``bem`` rung: its influence coefficients, contact solve and image against independent references (closed
forms, the exact axisymmetric layered contact law), its wall model and its refusals."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
from scipy.integrate import dblquad
from scipy.interpolate import RegularGridInterpolator

from palpate.core.errors import ValidationError
from palpate.core.session.sources import PressTarget
from palpate.core.world.scene import FingertipSpec, Inclusion, Layer, Material, ObjectSpec, Scene
from palpate.sim import simulate_press
from palpate.sim.analytic import law_sensel_pressure
from palpate.sim.bem.kernel import influence, love_rectangle
from palpate.sim.bem.press import run_bem_press
from palpate.sim.bem.solve import solve_ladder
from palpate.sim.bem.surface import ROWS, build_surface, column_kinds, column_stacks, stack_compliance
from palpate.sim.bem.wall import NEAR_WALL, Wall, WallTable, find_wall, load_wall_table
from palpate.sim.contact.lcp import solve_contact
from palpate.sim.contact.stack import object_law
from palpate.sim.controller import press_profile
from palpate.sim.fingertip import sensel_bounds
from palpate.sim.validity.image import asymmetry

TIP = FingertipSpec()
R = TIP.radius
CELL = 0.5e-3


@pytest.mark.parametrize("dx, dy", [(0.7e-3, 0.0), (1.3e-3, -2.1e-3), (-4e-3, 3e-3)])
def test_love_rectangle_is_the_integral_of_one_over_distance(dx, dy):
    half = 0.25e-3
    exact, _ = dblquad(lambda y, x: 1.0 / np.hypot(x, y), dx - half, dx + half, dy - half, dy + half,
                       epsabs=1e-14, epsrel=1e-10)
    assert love_rectangle(np.array(dx), np.array(dy), half) == pytest.approx(exact, rel=1e-6)


def test_love_rectangle_at_its_own_centre():
    """Over a square of half side h about the point: 8 h ln(1 + sqrt 2)."""
    assert love_rectangle(np.array(0.0), np.array(0.0), 1e-3) == pytest.approx(8e-3 * np.log(1 + np.sqrt(2)),
                                                                             rel=1e-12)


def _block(young, poisson, thickness=0.03, layers=()):
    return ObjectSpec("block", "box", (0.08, 0.08, thickness), (0.0, 0.0), Material("m", young, poisson),
                      layers=layers)


def _bem_and_law(obj, depths):
    depths = np.asarray(depths)
    thickness = obj.height
    a = np.sqrt(R * depths[-1])
    surface = build_surface(obj, 0.0, 0.0, thickness, TIP, min(1.2 * a + 2 * CELL, 0.97 * R), CELL, a)
    force, pressure = solve_ladder(surface, R, depths)
    law = object_law(obj, 0.0, 0.0, thickness, R, 1.05 * depths[-1])
    law_p = law_sensel_pressure(law, depths, sensel_bounds(TIP)).reshape(len(depths), -1)
    return surface, force, pressure, law.force_at(depths), law_p


@pytest.mark.parametrize("poisson, thickness", [(0.3, 0.03), (0.45, 0.03), (0.49, 0.03), (0.45, 0.005)])
def test_block_force_and_image_match_the_exact_layered_law(poisson, thickness):
    """The layered law solves the axisymmetric problem exactly (a Fredholm equation, another method); the surface
    solve on 0.5 mm cells holds it within 1% in force and 1.5% of the peak per sensel."""
    depths = [0.5e-3, 1e-3, 2e-3, 3e-3] if thickness < 0.01 else [0.5e-3, 1e-3, 2e-3, 4e-3]
    surface, force, pressure, law_force, law_p = _bem_and_law(_block(115e3, poisson, thickness), depths)
    assert surface.mixing == "uniform"
    np.testing.assert_allclose(force, law_force, rtol=0.01)
    rms = np.sqrt(np.mean((pressure - law_p) ** 2, axis=1)) / law_p.max(axis=1)
    assert rms.max() < 0.015


def test_a_soft_skin_matches_the_exact_layered_law():
    skin = (Layer(Material("skin", 20e3, 0.45), 1e-3),)
    surface, force, pressure, law_force, law_p = _bem_and_law(_block(200e3, 0.45, layers=skin), [1e-3, 2e-3, 3e-3])
    assert len(surface.stacks) == 1 and len(surface.stacks[0].thickness) == 2
    np.testing.assert_allclose(force, law_force, rtol=0.02)
    assert (np.sqrt(np.mean((pressure - law_p) ** 2, axis=1)) / law_p.max(axis=1)).max() < 0.03


def test_contact_solve_is_complementary_and_warm_starts_to_the_same_answer():
    rng = np.random.default_rng(3)
    pts = rng.uniform(-3e-3, 3e-3, (60, 2))
    dist = np.hypot(*(pts[:, None, :] - pts[None, :, :]).transpose(2, 0, 1))
    compliance = 1e-9 / (dist + 0.3e-3)  # positive definite (a completely monotone kernel of distance)
    gap = 1e-4 - np.sum(pts**2, axis=1) / 0.016
    p, active = solve_contact(compliance, gap)
    settle = compliance @ p
    assert np.all(p >= 0) and np.all(settle >= gap - 1e-12)
    assert np.allclose((settle - gap)[active], 0.0, atol=1e-12)
    assert np.all(p[~active] == 0)
    warm, _ = solve_contact(compliance, gap, active=np.ones(60, dtype=bool))
    np.testing.assert_allclose(warm, p, rtol=1e-9, atol=1e-9 * p.max())


def _wall_object(offset, soft=20e3, hard=115e3, nu=0.45):
    half = 0.04
    inc = Inclusion(Material("hard", hard, nu), "column", ((offset + half) / 2, 0.0, 0.0), (half - offset, 2 * half))
    return ObjectSpec("wall", "box", (2 * half, 2 * half, 0.03), (0.0, 0.0), Material("soft", soft, nu),
                      inclusions=(inc,))


@pytest.mark.parametrize("angle_deg, offset", [(0.0, 1.3e-3), (90.0, -2.2e-3), (30.0, 0.4e-3), (135.0, 3.1e-3)])
def test_find_wall_locates_a_straight_boundary_at_any_angle(angle_deg, offset):
    n = np.array([np.cos(np.radians(angle_deg)), np.sin(np.radians(angle_deg))])
    k = (np.arange(-14, 14) + 0.5) * CELL
    centres = np.stack(np.meshgrid(k, k, indexing="ij"), -1).reshape(-1, 2)

    def is_stiff(points):
        return points @ n > offset

    wall = find_wall(is_stiff, centres, is_stiff(centres), 7e-3, CELL)
    assert wall is not None
    np.testing.assert_allclose(wall.normal, n, atol=1e-3)
    assert wall.offset == pytest.approx(offset, abs=2e-5)


def test_find_wall_refuses_a_curved_boundary():
    k = (np.arange(-14, 14) + 0.5) * CELL
    centres = np.stack(np.meshgrid(k, k, indexing="ij"), -1).reshape(-1, 2)

    def is_stiff(points):  # a disc of 5 mm radius centred 4 mm away
        return np.hypot(points[:, 0] - 4e-3, points[:, 1]) < 5e-3

    assert find_wall(is_stiff, centres, is_stiff(centres), 7e-3, CELL) is None


def test_a_wall_uses_the_wall_table_a_buried_lump_the_columns_kernels_and_a_curved_top_the_local_model():
    surface = build_surface(_wall_object(1e-3), 0.0, 0.0, 0.03, TIP, 7e-3, CELL, 5e-3)
    assert surface.mixing == "wall" and len(surface.stacks) == 2
    lump = Inclusion(Material("lump", 1e6, 0.45), "sphere", (3e-3, 0.0, 0.03 - 3e-3), (2e-3,))
    obj = ObjectSpec("b", "box", (0.08, 0.08, 0.03), (0.0, 0.0), Material("m", 100e3, 0.45), inclusions=(lump,))
    assert build_surface(obj, 0.0, 0.0, 0.03, TIP, 7e-3, CELL, 5e-3).mixing == "buried"
    # a disc of another material reaching the top: its boundary is curved and the columns' tops differ
    disc = Inclusion(Material("disc", 1e6, 0.45), "sphere", (3e-3, 0.0, 0.03), (2e-3,))
    obj = ObjectSpec("b", "box", (0.08, 0.08, 0.03), (0.0, 0.0), Material("m", 100e3, 0.45), inclusions=(disc,))
    assert build_surface(obj, 0.0, 0.0, 0.03, TIP, 7e-3, CELL, 5e-3).mixing == "local"


def test_over_a_buried_change_a_cell_settles_through_the_shared_top_and_couples_through_the_depth():
    """Over a stiff layer 1 mm under the top (a wide buried box) a cell's own settlement is nearly the matrix's (the
    soft top it shares carries its load), while its coupling to cells 1-2 mm away, which runs deeper, is much
    smaller; a cell over the matrix far from the box is as over a plain block."""
    box = Inclusion(Material("lump", 2e6, 0.45), "box", (10e-3, 0.0, 0.03 - 1e-3 - 2.5e-3), (0.016, 0.03, 0.005))
    obj = ObjectSpec("b", "box", (0.08, 0.08, 0.03), (0.0, 0.0), Material("m", 115e3, 0.45), inclusions=(box,))
    plain = ObjectSpec("p", "box", (0.08, 0.08, 0.03), (0.0, 0.0), Material("m", 115e3, 0.45))
    s_lump = build_surface(obj, 0.0, 0.0, 0.03, TIP, 7e-3, CELL, 3e-3)
    s_plain = build_surface(plain, 0.0, 0.0, 0.03, TIP, 7e-3, CELL, 3e-3)
    assert s_lump.mixing == "buried"
    np.testing.assert_array_equal(s_lump.centres, s_plain.centres)

    def at(x, y):
        return int(np.argmin(np.hypot(s_lump.centres[:, 0] - x, s_lump.centres[:, 1] - y)))

    def ratio(i, j):
        return s_lump.compliance[i, j] / s_plain.compliance[i, j]

    over = at(5.25e-3, 0.25e-3)
    assert ratio(over, over) > 0.75
    assert ratio(over, at(5.25e-3, 1.25e-3)) < 0.4 and ratio(over, at(5.25e-3, 2.25e-3)) < 0.4
    away = at(-5.25e-3, 0.25e-3)
    assert ratio(away, away) == pytest.approx(1.0, abs=1e-3)


def test_a_soft_lump_under_a_stiff_top_blends_its_kernels_without_a_nan():
    """A stiff top over a soft box bends like a plate on a foundation: its kernel turns negative far out, where the
    blend of the columns' kernels has no log; the surface is built without a warning and is finite."""
    box = Inclusion(Material("lump", 57e3, 0.4), "box", (6e-3, 0.0, 0.04 - 1.33e-3 - 7.2e-3), (0.012, 0.03, 0.0144))
    obj = ObjectSpec("b", "box", (0.08, 0.08, 0.04), (0.0, 0.0), Material("m", 450e3, 0.4), inclusions=(box,))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        surface = build_surface(obj, 0.0, 0.0, 0.04, TIP, 7e-3, CELL, 5e-3)
    assert surface.mixing == "buried" and np.all(np.isfinite(surface.compliance))


def test_a_buried_lump_takes_its_force_from_the_points_law_and_its_image_leans_towards_the_lump():
    """Columns that differ only under a shared top (a stiff box 1 mm down, 2 mm beside the axis): the press's force
    at every sample is the point's contact law's, the pad's pressure is the surface solve's shape rescaled to it,
    and the stiff side carries more. A wall reaching the surface is not buried and keeps the surface's own force."""
    box = Inclusion(Material("lump", 2e6, 0.45), "box", (7e-3, 0.0, 0.03 - 1e-3 - 2.5e-3), (0.01, 0.01, 0.005))
    obj = ObjectSpec("b", "box", (0.08, 0.08, 0.03), (0.0, 0.0), Material("m", 115e3, 0.45), inclusions=(box,))
    assert build_surface(obj, 0.0, 0.0, 0.03, TIP, 7e-3, CELL, 5e-3).buried
    assert not build_surface(_wall_object(1e-3), 0.0, 0.0, 0.03, TIP, 7e-3, CELL, 5e-3).buried
    profile = press_profile(PressTarget(0.0, 0.0, depth=0.003, speed=0.01), 0.03, radius=R, timestep=0.002)
    trace = run_bem_press(Scene(objects=(obj,)), obj, profile)
    law = object_law(obj, 0.0, 0.0, 0.03, R, 1.25 * 0.003)
    assert trace.meta["force_from_law"]
    np.testing.assert_allclose(trace.force, law.force_at(trace.indentation), rtol=1e-9, atol=1e-12)
    deep = int(np.argmax(trace.indentation))
    assert asymmetry(trace.sensel_pressure[deep:deep + 1], "x")[0] > 0.1  # the FE's: +0.32 at 3 mm


def test_the_image_over_a_wall_leans_to_the_stiff_side_and_analytic_does_not():
    """The point of the rung: over a wall the stiffer side carries more (analytic averages around the axis)."""
    obj = _wall_object(0.0)
    a = np.sqrt(R * 3e-3)
    surface = build_surface(obj, 0.0, 0.0, 0.03, TIP, 1.2 * a + 2 * CELL, CELL, a)
    _, pressure = solve_ladder(surface, R, np.array([3e-3]))
    tilt = asymmetry(pressure.reshape(1, 4, 4))[0]
    assert 0.4 < tilt < 0.9  # the 3-D FE gives 0.61 at this contrast
    law = object_law(obj, 0.0, 0.0, 0.03, R, 3.2e-3)
    assert abs(asymmetry(law_sensel_pressure(law, np.array([3e-3]), sensel_bounds(TIP)))[0]) < 1e-9


@pytest.mark.parametrize("angle_deg", [45.0, 135.0])
def test_a_diagonal_wall_through_the_press_point_gives_a_mirror_symmetric_image(angle_deg):
    """A wall at 45 deg through the press point is its own mirror image across the pad's diagonal, so the image's
    asymmetries along x and y must agree up to the diagonal's sign (the 3-D FE: 0.35 | 0.35 at 20 | 115 kPa). The
    scene holds the wall as a staircase of 0.25 mm columns, so the located wall is a hair off 45 deg; cells on the
    line must keep their own column's side, not the side that hair puts them on (it gave 0.25 | 0.41)."""
    from palpate.sim.reference.fe3d import Wall as FEWall
    from palpate.sim.validity.image_cases import wall_columns

    wall = FEWall(Material("hard", 115e3, 0.45), np.radians(angle_deg), 0.0)
    obj = ObjectSpec("diagonal", "box", (0.08, 0.08, 0.03), (0.0, 0.0), Material("soft", 20e3, 0.45),
                     inclusions=tuple(wall_columns(wall, 0.04, 0.04, 0.03)))
    depths = np.array([0.5e-3, 1e-3, 3e-3])
    a = np.sqrt(R * depths[-1])
    surface = build_surface(obj, 0.0, 0.0, 0.03, TIP, 1.2 * a + 2 * CELL, CELL, a)
    assert surface.mixing == "wall"
    _, pressure = solve_ladder(surface, R, depths)
    image = pressure.reshape(len(depths), 4, 4)
    along_x, along_y = asymmetry(image, "x"), asymmetry(image, "y")
    sign = np.sign(np.cos(np.radians(angle_deg)) * np.sin(np.radians(angle_deg)))
    assert np.all(np.abs(along_x) > 0.25)
    np.testing.assert_allclose(along_x, sign * along_y, atol=0.01)


def test_wall_table_file_is_checked(tmp_path):
    table = load_wall_table()
    assert table.share.shape[2:] == (len(table.offsets), len(table.offsets), len(table.along))
    np.testing.assert_allclose(table.share, table.share.transpose(0, 1, 3, 2, 4), atol=1e-9)
    doc = table.to_dict({"how": "test"})
    # written packed; read back exactly; a list of the same numbers reads the same; a damaged value is refused
    written = tmp_path / "table.json"
    written.write_text(json.dumps(doc))
    np.testing.assert_array_equal(load_wall_table(written).share, table.share)
    listed = tmp_path / "listed.json"
    listed.write_text(json.dumps(dict(doc, share=table.share.tolist())))
    np.testing.assert_array_equal(load_wall_table(listed).share, table.share)
    damaged = table.share.tolist()
    damaged[0][0][0][0][0] = "x"
    for share, name in ((damaged, "bad.json"), (dict(doc["share"], base64=doc["share"]["base64"][:-4]), "cut.json")):
        bad = tmp_path / name
        bad.write_text(json.dumps(dict(doc, share=share)))
        with pytest.raises(ValidationError, match=name):
            load_wall_table(bad)
    with pytest.raises(ValidationError, match="not found"):
        load_wall_table(tmp_path / "missing.json")


def test_wall_rejects_bad_tables():
    with pytest.raises(ValidationError, match="contrasts"):
        WallTable(offsets=np.array([-1e-3, 0.0, 1e-3]), along=np.array([0.0]), poisson=np.array([0.3]),
                  contrast=np.array([0.5]), share=np.zeros((1, 1, 3, 3, 1)), thickness=0.03)
    wall = Wall(normal=np.array([1.0, 0.0]), offset=1e-3)
    np.testing.assert_allclose(wall.distance(np.array([[2e-3, 5.0]])), [1e-3])


def test_simulate_press_with_bem_runs_and_names_its_model():
    rec = simulate_press(115e3, 0.45, fidelity="bem", depth=0.003, seed=2)
    assert rec.meta["fidelity"] == "bem" and rec.meta["physics"]["mixing"] == "uniform"
    law = simulate_press(115e3, 0.45, fidelity="analytic", depth=0.003, seed=2)
    assert max(rec.truth.force) == pytest.approx(max(law.truth.force), rel=0.01)


def test_a_staircase_of_columns_is_sampled_once_per_kind_of_column_and_gives_every_cell_its_own_stack():
    """Cells are grouped by which inclusions' footprints cover them; each group's stack must be what sampling
    that very cell's column gives (a sphere's cells are sampled one by one: its chord depends on the cell)."""
    strips = tuple(Inclusion(Material("hard", 115e3, 0.45), "column", ((i + 0.5) * 1e-3, i * 0.5e-3, 0.0),
                             (1e-3, 40e-3)) for i in range(-6, 6))
    ball = Inclusion(Material("ball", 1e6, 0.45), "sphere", (-2e-3, -2e-3, 0.03 - 2.5e-3), (2e-3,))
    obj = ObjectSpec("stairs", "box", (0.08, 0.08, 0.03), (0.0, 0.0), Material("soft", 20e3, 0.45),
                     inclusions=strips + (ball,))
    k = (np.arange(-12, 12) + 0.5) * CELL
    centres = np.stack(np.meshgrid(k, k, indexing="ij"), -1).reshape(-1, 2)
    kinds = column_kinds(obj, centres + np.array([1e-3, 0.0]))
    assert len(np.unique(kinds)) < len(centres) / 4
    stack_of, stacks, on_object = column_stacks(obj, 1e-3, 0.0, 0.03, centres)
    assert on_object.all()
    for n in np.random.default_rng(0).choice(len(centres), 40, replace=False):
        _, own, _ = column_stacks(obj, 1e-3, 0.0, 0.03, centres[n:n + 1] + np.array([[1e-9, 0.0]]))
        assert stacks[stack_of[n]] == own[0]


def test_the_wall_table_is_read_once_per_file_version(tmp_path):
    path = tmp_path / "walls.json"
    table = load_wall_table()
    path.write_text(json.dumps(table.to_dict({"how": "test"})))
    first = load_wall_table(path)
    assert load_wall_table(path) is first
    assert not first.share.flags.writeable
    doc = table.to_dict({"how": "test"})
    doc["thickness"] = 0.02
    path.write_text(json.dumps(doc) + " ")  # a new version: another size and time
    assert load_wall_table(path).thickness == pytest.approx(0.02)


def test_the_wall_compliance_built_by_blocks_is_the_soft_stack_scaled_by_the_table_share():
    """The blocked, single-precision construction against the formula written out per pair in double precision."""
    obj = _wall_object(1.3e-3)
    a = np.sqrt(R * 3e-3)
    surface = build_surface(obj, 0.0, 0.0, 0.03, TIP, a + 2 * CELL, CELL, a)
    assert surface.mixing == "wall" and len(surface.centres) > 2 * ROWS
    table = load_wall_table()
    soft, hard = sorted(surface.stacks, key=lambda s: s.top_modulus)
    q = 1.0 / a
    contrast = stack_compliance(soft, q) / stack_compliance(hard, q)
    u = surface.centres[:, 0] - 1.3e-3
    near = NEAR_WALL * table.spacing
    u = np.where(u > 0, np.maximum(u, near), np.minimum(u, -near))
    along = np.abs(surface.centres[:, None, 1] - surface.centres[None, :, 1])
    cube = RegularGridInterpolator((np.log(table.contrast), table.offsets, table.offsets, table.along),
                                   table.share[1])  # nu 0.45 is a node of the table
    pts = np.stack(np.broadcast_arrays(np.log(contrast), u[:, None], u[None, :], np.minimum(along, table.along[-1])),
                   axis=-1)
    share = cube(pts.reshape(-1, 4)).reshape(along.shape)
    d = surface.centres[:, None, :] - surface.centres[None, :, :]
    own = influence(soft.scaled(), CELL, d[..., 0], d[..., 1]) / soft.top_modulus
    # the wall is located to a few micrometres (find_wall's tolerance), which moves the share by ~1e-4
    np.testing.assert_allclose(surface.compliance, own * contrast ** (share - 1.0), rtol=2e-3)


@pytest.mark.parametrize("poisson", [0.3, 0.45, 0.49])
def test_the_wall_compliance_is_positive_definite_for_walls_near_the_axis(poisson):
    """The wall model scales the soft stack's compliance pair by pair, which need not stay positive definite; the
    contact solve needs it to. A sweep of contrasts 2-22.5x, walls 0-2 mm either side of the axis, 2 and 4 mm deep."""
    worst = np.inf
    for soft, hard in ((20e3, 40e3), (50e3, 450e3), (10e3, 225e3)):
        for offset in (-2e-3, -0.75e-3, -0.25e-3, 0.0, 0.5e-3, 1.25e-3):
            obj = _wall_object(offset, soft, hard, poisson)
            for depth in (2e-3, 4e-3):
                a = np.sqrt(R * depth)
                c = build_surface(obj, 0.0, 0.0, 0.03, TIP, 1.05 * a + 2 * CELL, CELL, a).compliance.astype(float)
                eig = np.linalg.eigvalsh(0.5 * (c + c.T))
                worst = min(worst, eig[0] / eig[-1])
    assert worst > 0


def test_an_indefinite_compliance_is_refused_by_name():
    compliance = np.array([[1.0, 2.0], [2.0, 1.0]])
    with pytest.raises(ValidationError, match="not positive definite"):
        solve_contact(compliance, np.array([1.0, 1.0]))
