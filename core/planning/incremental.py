"""Planning at scale: the accuracy gains of a 2-D map kept between choices and rescored only where a press can have
changed them.

A cell's gain (:func:`~palpate.core.planning.expected_accuracy.expected_accuracy_gain`) depends only on the measured
map within ``max(2, reach + 1)`` cells of it (its eq. 6.15 neighbours' numerators, their belief votes) and on the
post-processed map within one cell, plus the material frequencies the belief starts from. So after a press only a
window around what changed is rescored: the window is computed on a crop that holds everything its cells depend on,
which gives bit-for-bit the values of scoring the whole map (the kernels sum each cell's terms in the same order
whatever the array's extent). The frequencies are the one global input: they are kept from the last full scoring and
refreshed, with a full rescoring, once any of them has drifted by more than ``freq_tolerance``; the full computation
(``local=False``) uses the same kept frequencies, so the choices are those of scoring every cell.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from palpate.core.planning.expected_accuracy import expected_accuracy_gain


@dataclass(frozen=True)
class _Plane:
    """The part of a map the gain reads (a crop of a Grid2D, or one in full)."""

    probabilities: np.ndarray
    explored: np.ndarray
    base: float
    p_min: float


def _changed_cells(new: np.ndarray, old: np.ndarray) -> np.ndarray:
    """Flat indices of the cells (rows of the trailing materials axis) where two (..., M) arrays differ."""
    m = new.shape[-1]
    return np.unique(np.flatnonzero(new.reshape(-1) != old.reshape(-1)) // m)


class GainCache:
    """Accuracy gains of one 2-D map, kept and rescored where the map changed (module docstring).

    Args:
        table: the memory's predicted press outcomes (see :func:`palpate.core.planning.outcomes.outcome_table`).
        reach, correlation_cells, temperature, surprise: the belief's (see
            :func:`~palpate.core.planning.expected_accuracy.label_belief`).
        freq_tolerance: largest drift of a material's frequency before a full rescoring.
        max_window: a change whose window covers more than this share of the map is rescored in full.

    After :meth:`update`: ``gain`` (ny, nx), and ``window``, the (rows, columns) slices rescored, None when every
    cell was (terms that depend on the map as locally as the gain can be refreshed in the same window).
    """

    def __init__(self, table, *, reach: int, correlation_cells: float, temperature: float, surprise: float,
                 freq_tolerance: float = 0.02, max_window: float = 0.25):
        self.table = table
        self.reach = int(reach)
        self.correlation_cells = float(correlation_cells)
        self.temperature = float(temperature)
        self.surprise = float(surprise)
        self.freq_tolerance = float(freq_tolerance)
        self.max_window = float(max_window)
        self.radius = max(2, self.reach + 1)
        self.freq: np.ndarray | None = None
        self.gain: np.ndarray | None = None
        self.window: tuple[slice, slice] | None = None
        self._p = self._explored = self._post = self._labels = self._counts = None
        self._key = None
        self.rescored_cells = 0  # cells rescored by the last call (how much work it did)

    def _gain_of(self, p, explored, post_p, base, p_min) -> np.ndarray:
        return expected_accuracy_gain(_Plane(p, explored, base, p_min), _Plane(post_p, explored, base, p_min),
                                      self.table, reach=self.reach, correlation_cells=self.correlation_cells,
                                      temperature=self.temperature, surprise=self.surprise, freq=self.freq)

    def fits(self, grid) -> bool:
        """Whether this cache was made for a map of ``grid``'s shape and materials."""
        return self._key is None or self._key == (np.shape(grid.probabilities), tuple(grid.materials))

    def _frequencies(self) -> np.ndarray:
        """Laplace-smoothed share of each material among the explored cells' labels (as
        :func:`~palpate.core.planning.expected_accuracy.material_frequencies`), from the kept counts."""
        return (self._counts + 1.0) / (self._counts.sum() + self._counts.size)

    def full(self, grid, post) -> np.ndarray:
        """Score every cell (refreshing the kept frequencies) and keep the result; returns the gains (ny, nx)."""
        p = np.array(grid.probabilities, dtype=float)
        explored = np.array(grid.explored, dtype=bool)
        post_p = np.array(post.probabilities, dtype=float)
        self._labels = np.argmax(p, axis=-1)
        self._counts = np.bincount(self._labels[explored], minlength=p.shape[-1]).astype(float)
        self.freq = self._frequencies()
        self.gain = self._gain_of(p, explored, post_p, grid.base, grid.p_min)
        self._p, self._explored, self._post = p, explored, post_p
        self._key = (p.shape, tuple(grid.materials))
        self.window = None
        self.rescored_cells = explored.size
        return self.gain

    def update(self, grid, post, local: bool = True) -> np.ndarray:
        """The gains after whatever changed since the last call, rescoring only around the changes (every cell,
        with the same kept frequencies, when not ``local``: the full computation the local one must equal).
        Returns the kept array itself (read it, do not write it)."""
        if self.gain is None or not self.fits(grid):
            return self.full(grid, post)
        p = np.asarray(grid.probabilities)
        explored = np.asarray(grid.explored)
        post_p = np.asarray(post.probabilities)
        ny, nx = explored.shape
        moved = np.union1d(_changed_cells(p, self._p), np.flatnonzero(explored.reshape(-1) !=
                                                                      self._explored.reshape(-1)))
        # the kept label counts follow the cells that changed
        if moved.size:
            iy, ix = np.divmod(moved, nx)
            m = p.shape[-1]
            old = self._labels[iy, ix]
            new = np.argmax(p[iy, ix], axis=-1)
            self._counts -= np.bincount(old[self._explored[iy, ix]], minlength=m)
            self._counts += np.bincount(new[explored[iy, ix]], minlength=m)
            self._labels[iy, ix] = new
        if np.max(np.abs(self._frequencies() - self.freq)) > self.freq_tolerance:
            return self.full(grid, post)
        if not local:
            self.gain = self._gain_of(p, explored, post_p, grid.base, grid.p_min)
            self._p, self._explored, self._post = p.copy(), explored.copy(), post_p.copy()
            self.window = None
            self.rescored_cells = explored.size
            return self.gain
        cells = np.union1d(moved, _changed_cells(post_p, self._post))
        self.rescored_cells = 0
        self.window = (slice(0, 0), slice(0, 0))
        if cells.size == 0:
            return self.gain
        rows, cols = np.divmod(cells, nx)
        r = self.radius
        # cells whose gain can change, and the crop holding everything they depend on
        y0, y1 = max(0, int(rows.min()) - r), min(ny, int(rows.max()) + r + 1)
        x0, x1 = max(0, int(cols.min()) - r), min(nx, int(cols.max()) + r + 1)
        if (y1 - y0) * (x1 - x0) > self.max_window * ny * nx:
            return self.full(grid, post)
        cy0, cy1 = max(0, y0 - r), min(ny, y1 + r)
        cx0, cx1 = max(0, x0 - r), min(nx, x1 + r)
        crop = (slice(cy0, cy1), slice(cx0, cx1))
        g = self._gain_of(p[crop], explored[crop], post_p[crop], grid.base, grid.p_min)
        self.gain[y0:y1, x0:x1] = g[y0 - cy0:y1 - cy0, x0 - cx0:x1 - cx0]
        self._p[crop] = p[crop]
        self._explored[crop] = explored[crop]
        self._post[crop] = post_p[crop]
        self.window = (slice(y0, y1), slice(x0, x1))
        self.rescored_cells = (y1 - y0) * (x1 - x0)
        return self.gain
