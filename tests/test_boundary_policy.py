"""The boundary policy: it presses where the fine map is unsure, off a cell's centre towards a wall hidden between
cell centres, and not again where a press already read the wall; the loop presses a policy's own point only inside
its cell."""

from __future__ import annotations

import numpy as np
import pytest
from test_fine_map import DEPTH, NOISE, _image

from palpate.core.boundary.moduli import material_moduli
from palpate.core.boundary.reading import read_boundary
from palpate.core.errors import ValidationError
from palpate.core.mapping.geometry import MapGeometry
from palpate.core.mapping.grids import Grid2D
from palpate.core.perception.memory import HapticMemory
from palpate.core.planning.boundary_seeking import BoundarySeeking
from palpate.core.planning.map_views import postprocess
from palpate.core.planning.policies import Target
from palpate.core.planning.registry import make_policy
from palpate.core.session.boundaries import shipped_templates
from palpate.core.session.explore import _press_point

SOFT, HARD = 20e3, 120e3
CELL = 0.015
WALL_X = 0.030  # half-way between the centres of cells 2 and 3: 7.5 mm from both, beyond a reading's reach


@pytest.fixture(scope="module")
def templates():
    return shipped_templates()


@pytest.fixture(scope="module")
def memory() -> HapticMemory:
    rng = np.random.default_rng(5)
    mus = np.array([[100.0, 1.0, 20.0, 0.5], [900.0, 3.0, 60.0, 1.5]])
    x = np.vstack([mu * (1 + 0.05 * rng.standard_normal((10, 4))) for mu in mus])
    return HapticMemory(["soft", "hard"]).fit(x, ["soft"] * 10 + ["hard"] * 10)


def _reading(templates, x0: float):
    """What a press at x0 reads beside the wall at WALL_X (harder side +x)."""
    near = abs(WALL_X - x0) < 0.007
    img = _image(templates, SOFT if near or x0 < WALL_X else HARD, WALL_X if near else None, x0, HARD / SOFT)
    return read_boundary(img, DEPTH, templates, NOISE)


def _pressed_map(templates, memory):
    """A 4 x 2 map of 15 mm cells, every cell pressed once at its centre and judged right (soft left of the wall,
    hard right of it), with the policy told each press's reading."""
    geometry = MapGeometry("grid2d", ("soft", "hard"), (0.0, 0.0), CELL, (4, 2))
    grid = Grid2D(["soft", "hard"], (4, 2), cell_size=CELL)
    refs = {name: [read_boundary(_image(templates, e, None, 0, 1), DEPTH, templates, NOISE)]
            for name, e in (("soft", SOFT), ("hard", HARD))}
    policy = BoundarySeeking(memory, geometry, material_moduli(refs))
    for ix in range(4):
        for iy in range(2):
            x0, y0 = (ix + 0.5) * CELL, (iy + 0.5) * CELL
            grid.update_cell(ix, iy, np.array([0.9, 0.1]) if x0 < WALL_X else np.array([0.1, 0.9]))
            policy.observe((x0, y0), _reading(templates, x0))
    return geometry, grid, policy


def test_it_presses_the_wall_between_two_cell_centres_then_not_there_again(templates, memory):
    geometry, grid, policy = _pressed_map(templates, memory)
    t = policy.next_target(grid)
    assert t.xy is not None and t.score is not None and t.score > 0
    x, y = t.xy
    # off its cell's centre towards the hidden wall, as far as the policy shifts a press (a quarter cell), in the
    # cell that holds the point
    assert int(x // CELL) == t.ix and int(y // CELL) == t.iy
    assert abs(x - (t.ix + 0.5) * CELL) <= CELL / 4 and abs(x - WALL_X) <= CELL / 4 + 1e-3
    # the press there reads the wall; the next point is elsewhere along it or away from it
    policy.observe((x, y), _reading(templates, x))
    nxt = policy.next_target(grid)
    assert np.hypot(nxt.xy[0] - x, nxt.xy[1] - y) > 3e-3


def test_it_expects_errors_beside_a_wall_drawn_far_from_every_press(templates, memory):
    # an 8 x 1 strip of 10 mm cells pressed at its two ends only, soft at 5 mm and hard at 75 mm: the map draws the
    # wall between them where nothing was felt, and a wall drawn there may lie anywhere near
    geometry = MapGeometry("grid2d", ("soft", "hard"), (0.0, 0.0), 0.01, (8, 1))
    grid = Grid2D(["soft", "hard"], (8, 1), cell_size=0.01)
    grid.update_cell(0, 0, np.array([0.9, 0.1]))
    grid.update_cell(7, 0, np.array([0.1, 0.9]))
    refs = {name: [read_boundary(_image(templates, e, None, 0, 1), DEPTH, templates, NOISE)]
            for name, e in (("soft", SOFT), ("hard", HARD))}
    errors = {}
    for spread in (0.0, 1.0):
        policy = BoundarySeeking(memory, geometry, material_moduli(refs), wall_spread=spread)
        for x0, e in ((0.005, SOFT), (0.075, HARD)):
            policy.observe((x0, 0.005), read_boundary(_image(templates, e, None, 0, 1), DEPTH, templates, NOISE))
        errors[spread], fine, pts = policy.point_scores(grid, postprocess(grid, 1, 1.0, False))
    x = pts[0, :, 0]
    wall = x[np.argmax(fine.labels()[0] == 1)]
    beside = np.abs(x - wall) < 0.005
    assert np.all(errors[1.0][:, beside] > errors[0.0][:, beside])
    # the press that would settle most is beside the drawn wall, not beside a press
    assert abs(x[np.argmax(errors[1.0][0])] - wall) < 0.01
    np.testing.assert_allclose(errors[1.0][:, x < 0.002], errors[0.0][:, x < 0.002], rtol=0.05)


def test_it_starts_with_info_gains_lattice_at_cell_centres(memory):
    geometry = MapGeometry("grid2d", ("soft", "hard"), (0.0, 0.0), CELL, (7, 7))
    grid = Grid2D(["soft", "hard"], (7, 7), cell_size=CELL)
    t = make_policy("boundary", memory=memory, geometry=geometry).next_target(grid)
    assert t.xy is None and (t.ix, t.iy) in {(ix, iy) for ix in (0, 3, 6) for iy in (0, 3, 6)}


def test_bad_settings_and_maps_are_refused(memory):
    voxel = MapGeometry("voxel", ("soft", "hard"), (0.0, 0.0), CELL, (3, 3, 2), z_top=0.04)
    with pytest.raises(ValidationError, match="voxel"):
        BoundarySeeking(memory, voxel)
    flat = MapGeometry("grid2d", ("soft", "hard"), (0.0, 0.0), CELL, (3, 3))
    with pytest.raises(ValidationError, match="crowding"):
        BoundarySeeking(memory, flat, crowding=float("nan"))
    with pytest.raises(ValidationError, match="geometry"):
        make_policy("boundary", memory=memory)


def test_the_loop_presses_a_point_only_inside_its_cell():
    geometry = MapGeometry("grid2d", ("soft", "hard"), (0.0, 0.0), CELL, (3, 3))
    centres = geometry.cell_centres()
    assert _press_point(Target(1, 1), centres, geometry, "p", "o") == pytest.approx((0.0225, 0.0225))
    assert _press_point(Target(1, 1, xy=(0.016, 0.029)), centres, geometry, "p", "o") == (0.016, 0.029)
    for xy in ((0.031, 0.02), (0.02, float("nan"))):
        with pytest.raises(ValidationError, match="outside its cell 2,2"):
            _press_point(Target(1, 1, xy=xy), centres, geometry, "p", "o")
