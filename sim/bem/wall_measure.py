"""Measure the wall table (:mod:`.wall`) on the 3-D FE: a box block bonded to a rigid base, split by a vertical wall
at x = 0 into a soft half (x < 0) and a stiff half, and the same block of the soft material alone, on one mesh.

Each block's stiffness (:mod:`palpate.sim.reference.fe3d`'s trilinear bricks with selective reduced integration) is
factorised once; unit downward forces at the top nodes on the line y = 0 within +-``extent`` give the settlement of
every top node within +-``extent``; lambda = log(c C_wall / C_soft) / log c at each (u_i, u_j, v) pair. The mesh is
uniform at spacing ``h`` over the window (the wall on a grid line) and grows away from it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from palpate.core.errors import ValidationError
from palpate.sim.reference.fe3d import TensorGrid, _stiffness
from palpate.sim.reference.mesh import graded_line


@dataclass(frozen=True)
class WallBlock:
    """A block split at x = 0: Young moduli left (x < 0) and right, one Poisson ratio, sizes in m (the interface the
    FE stiffness assembly reads)."""

    young_left: float
    young_right: float
    poisson: float
    thickness: float = 0.03
    half_x: float = 0.04
    half_y: float = 0.04
    lump: None = None

    def materials_at(self, x: np.ndarray, y: np.ndarray, depth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(Young Pa, Poisson) at points (m)."""
        x = np.asarray(x, dtype=float)
        return np.where(x > 0, self.young_right, self.young_left), np.full(x.shape, self.poisson)


def surface_response(block: WallBlock, extent: float, h: float, growth: float = 1.3) -> dict:
    """Settlement (m per N) of each top node within +-``extent`` (m) under a unit force at each top node on y = 0
    within it: {'x', 'y' (responding nodes, m), 'x_source' (m), 'compliance' (n_resp, n_src), 'dofs'}."""
    from scipy.sparse.linalg import splu

    line = graded_line(block.half_x, h, extent, growth)
    x = np.unique(np.concatenate([-line[::-1], line]))
    grid = TensorGrid(x=x, y=x.copy(), depth=graded_line(block.thickness, h, extent / 3.0, growth))
    basis, stiffness = _stiffness(block, grid)
    locs = basis.doflocs
    uz = basis.get_dofs().all("u^3")
    free = np.flatnonzero(~np.isclose(locs[2], 0.0))
    at = -np.ones(basis.N, dtype=int)
    at[free] = np.arange(len(free))
    top = uz[np.isclose(locs[2, uz], block.thickness)]
    inside = (np.abs(locs[0, top]) <= extent + 1e-9) & (np.abs(locs[1, top]) <= extent + 1e-9)
    resp = top[inside]
    src = resp[np.isclose(locs[1, resp], 0.0)]
    lu = splu(stiffness[free][:, free].tocsc(), permc_spec="MMD_AT_PLUS_A")
    loads = np.zeros((len(free), len(src)))
    loads[at[src], np.arange(len(src))] = -1.0
    return {"x": locs[0, resp], "y": locs[1, resp], "x_source": locs[0, src],
            "compliance": -lu.solve(loads)[at[resp]], "dofs": int(basis.N)}


def measure_share(poisson: float, contrast: float, *, extent: float = 9e-3, h: float = 1e-3,
                  soft: dict | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict]:
    """lambda on the grid (offsets (U,), along (V,), share (U, U, V)) for one Poisson ratio and contrast; ``soft``
    passes the soft block's response when already solved (it depends on the Poisson ratio only). Returns the soft
    response too."""
    if not (contrast > 1 and 0 <= poisson < 0.5):
        raise ValidationError(f"measure_share: need contrast > 1 and 0 <= poisson < 0.5, got {contrast}, {poisson}")
    young = 1e5
    wall = surface_response(WallBlock(young, young * contrast, poisson), extent, h)
    if soft is None:
        soft = surface_response(WallBlock(young, young, poisson), extent, h)
    share = np.log(contrast * wall["compliance"] / soft["compliance"]) / math.log(contrast)
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
