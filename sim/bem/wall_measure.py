"""Measure the wall table (:mod:`.wall`) on the 3-D FE (:mod:`palpate.sim.reference.fe3d_solve`): a 30 mm box
block bonded to a rigid base, split by a vertical wall at x = 0 into a soft half (x < 0) and a stiff half, and the
same block of the soft material alone, on one mesh.

Each block's top surface compliance within +-``extent`` is condensed from its stiffness (the nested-dissection LU's
trailing block); lambda = log(c C_wall / C_soft) / log c for each pair of a node on the line y = 0 and a node of
the window. The mesh is uniform at spacing ``h`` over the window (the wall on a grid line) and grows away from it.
"""

from __future__ import annotations

import math

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.world.scene import Material
from palpate.sim.reference.fe3d import BoxBlock, TensorGrid, Wall
from palpate.sim.reference.fe3d_solve import _stiffness, condensed_compliance, dissection_rank, grid_indices
from palpate.sim.reference.mesh import graded_line

THICKNESS, HALF = 0.03, 0.04


def surface_response(block: BoxBlock, extent: float, h: float, growth: float = 1.3) -> dict:
    """Settlement (m per N) of each top node within +-``extent`` (m) under a unit force at each top node on y = 0
    within it: {'x', 'y' (responding nodes, m), 'x_source' (m), 'compliance' (n_resp, n_src), 'dofs'}."""
    line = graded_line(block.half_x, h, extent, growth)
    x = np.unique(np.concatenate([-line[::-1], line]))
    grid = TensorGrid(x=x, y=x.copy(), depth=graded_line(block.thickness, h, extent / 3.0, growth))
    basis, stiffness = _stiffness(block, grid)
    locs = basis.doflocs
    heights, (ix, iy, iz) = grid_indices(block, grid, locs, h)
    uz = basis.get_dofs().all("u^3")
    free = np.flatnonzero(iz != 0)
    top = uz[iz[uz] == len(heights) - 1]
    top = top[(np.abs(locs[0, top]) <= extent + 1e-9) & (np.abs(locs[1, top]) <= extent + 1e-9)]
    rank = dissection_rank((len(grid.x), len(grid.y), len(heights)))[(ix * len(grid.y) + iy) * len(heights) + iz]
    compliance = condensed_compliance(stiffness, free, top, rank)
    src = np.flatnonzero(np.isclose(locs[1, top], 0.0))
    return {"x": locs[0, top], "y": locs[1, top], "x_source": locs[0, top[src]], "compliance": compliance[:, src],
            "dofs": int(basis.N)}


def wall_block(poisson: float, contrast: float) -> BoxBlock:
    """The measuring block: 100 kPa on x < 0, ``contrast`` times stiffer beyond (1: the soft block alone)."""
    soft = Material("soft", 1e5, poisson)
    if contrast == 1.0:
        return BoxBlock(soft, THICKNESS, HALF, HALF)
    return BoxBlock(soft, THICKNESS, HALF, HALF, wall=Wall(Material("stiff", 1e5 * contrast, poisson), 0.0, 0.0))


def measure_share(poisson: float, contrast: float, *, extent: float = 9e-3, h: float = 1e-3,
                  soft: dict | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict]:
    """lambda on the grid (offsets (U,), along (V,), share (U, U, V)) for one Poisson ratio and contrast; ``soft``
    passes the soft block's response when already solved (it depends on the Poisson ratio only). Returns the soft
    response too."""
    if not (contrast > 1 and 0 <= poisson < 0.5):
        raise ValidationError(f"measure_share: need contrast > 1 and 0 <= poisson < 0.5, got {contrast}, {poisson}")
    wall = surface_response(wall_block(poisson, contrast), extent, h)
    if soft is None:
        soft = surface_response(wall_block(poisson, 1.0), extent, h)
    # far apart on a nearly incompressible block the settlement can change sign (the surface heaves); there both
    # are a tiny share of the near ones and the factor is floored (lambda >= -1)
    ratio = contrast * wall["compliance"] / soft["compliance"]
    share = np.log(np.where(ratio > 1.0 / contrast, ratio, 1.0 / contrast)) / math.log(contrast)
    n = int(round(extent / h))
    offsets = np.arange(-n, n + 1) * h
    along = np.arange(n + 1) * h
    cube = np.full((len(offsets), len(offsets), len(along)), np.nan)
    ix = np.rint(wall["x"] / h).astype(int) + n
    iy = np.rint(np.abs(wall["y"]) / h).astype(int)
    js = np.rint(wall["x_source"] / h).astype(int) + n
    for k in range(len(ix)):
        cube[ix[k], js, iy[k]] = share[k]
    if np.isnan(cube).any():
        raise ValidationError("measure_share: the mesh's nodes do not cover the table's grid; a bug in the mesh")
    return offsets, along, 0.5 * (cube + cube.transpose(1, 0, 2)), soft
