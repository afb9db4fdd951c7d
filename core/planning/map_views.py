"""Views of a map that every exploration policy plans on: column entropies, which columns are certain, distances,
the depth to press a voxel column to. Arrays are (ny, nx) over the columns a press chooses among.
"""

from __future__ import annotations

import math

import numpy as np

from palpate.core.mapping.probability import entropy_unchecked

#: A cell counts as "certain" when its entropy is at most this fraction of the largest possible (log_b M).
CERTAIN_FRACTION = 0.05


#: Same floor on entropies as the maps' post-processing: certain neighbours dominate without a division by zero.
H_MIN = 1e-12


def is_voxel(grid) -> bool:
    return len(grid.probabilities.shape) == 4


def plane_shape(grid) -> tuple[int, int]:
    """(nx, ny) of the columns a policy chooses among."""
    return tuple(int(v) for v in grid.shape[:2])  # type: ignore[return-value]


def h_max(grid) -> float:
    return math.log(len(grid.materials)) / math.log(grid.base)


def layers_reached(grid, max_depth: float | None) -> int:
    """Voxel layers a press to ``max_depth`` (m) reaches (all of them when None)."""
    nz = grid.shape[2]
    if max_depth is None:
        return nz
    return grid.layers_reached(max_depth)


def postprocess(grid, passes: int | None = 1, certainty: float = 1.0, lateral: bool = False):
    """The post-processed map the run reports: eq. 6.15 repeated ``passes`` times on a 2-D map, each pass keeping
    ``certainty`` of its estimate; a voxel map's own post-processing (``lateral``: also eq. 6.15 within layers)."""
    if is_voxel(grid):
        return grid.postprocessed(lateral=lateral, certainty=certainty)
    return grid.postprocessed(passes=passes, certainty=certainty)


def column_entropy(grid, post=None, max_depth: float | None = None) -> np.ndarray:
    """Entropy a press could act on per column, shape (ny, nx): the cell's entropy on a 2-D map, the sum over the
    reachable voxels of a column on a voxel map; of ``post`` (the post-processed map) when given."""
    m = grid if post is None else post
    h = entropy_unchecked(np.asarray(m.probabilities), m.base)
    if is_voxel(grid):
        return h[:, :, :layers_reached(grid, max_depth)].sum(axis=-1).T
    return h


def certain_columns(grid, post, max_depth) -> np.ndarray:
    """(ny, nx) mask of columns that are explored and certain in the post-processed map."""
    h = column_entropy(grid, post, max_depth)
    n = layers_reached(grid, max_depth) if is_voxel(grid) else 1
    explored = explored_plane(grid)
    return explored & (h <= CERTAIN_FRACTION * h_max(grid) * n)


def explored_plane(grid) -> np.ndarray:
    e = np.asarray(grid.explored)
    return e.any(axis=2).T if e.ndim == 3 else e


def distance_mm(shape_yx: tuple[int, int], cell_size: float, last) -> np.ndarray:
    """Distance of every cell centre from the last press's cell, mm, shape (ny, nx)."""
    ny, nx = shape_yx
    if last is None:
        return np.zeros((ny, nx))
    iy, ix = np.mgrid[0:ny, 0:nx]
    return np.hypot(ix - last[0], iy - last[1]) * cell_size * 1e3


def argmax_cell(score: np.ndarray, allowed: np.ndarray) -> tuple[int, int] | None:
    """(ix, iy) of the best allowed cell; ties go to the first in row order (deterministic)."""
    if not allowed.any():
        return None
    s = np.where(allowed, score, -np.inf)
    iy, ix = np.unravel_index(int(np.argmax(s)), s.shape)
    return int(ix), int(iy)


def target_depth(grid, post, ix: int, iy: int, max_depth: float | None) -> float | None:
    """Voxel maps: press down to the bottom of the deepest reachable voxel that is not certain yet (m), so a
    column whose deep part is known is not pressed deeper than needed; None on 2-D maps."""
    if not is_voxel(grid):
        return None
    k = layers_reached(grid, max_depth)
    h = entropy_unchecked(np.asarray(post.probabilities[ix, iy, :k]), post.base)
    uncertain = np.flatnonzero(h > CERTAIN_FRACTION * h_max(grid))
    layers = int(uncertain[-1]) + 1 if uncertain.size else k
    depth = layers * grid.cell_size
    return depth if max_depth is None else min(depth, max_depth)
