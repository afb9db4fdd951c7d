"""Planning at scale: the accuracy gains of a 2-D map kept between choices and rescored only where a press can have
changed them.

A cell's gain (:func:`~palpate.core.planning.expected_accuracy.expected_accuracy_gain`) depends only on the measured
map within ``max(2, reach + 1)`` cells of it (its eq. 6.15 neighbours' numerators, their belief votes) and on the
post-processed map within one cell, plus the material frequencies the belief starts from. So after a press only a
window around what changed is rescored: the window is computed on a crop that holds everything its cells depend on,
which gives bit-for-bit the values of scoring the whole map (the kernels sum each cell's terms in the same order
whatever the array's extent). The frequencies are the one global input: they are kept from the last full scoring and
refreshed, with a full rescoring, once any of them has drifted by more than ``freq_tolerance``; both paths use the
same kept frequencies, so the choices are those of scoring every cell.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from palpate.core.planning.expected_accuracy import expected_accuracy_gain, material_frequencies


@dataclass(frozen=True)
class _Plane:
    """The part of a map the gain reads (a crop of a Grid2D, or one in full)."""

    probabilities: np.ndarray
    explored: np.ndarray
    base: float
    p_min: float


class GainCache:
    """Accuracy gains of one 2-D map, kept and rescored where the map changed (module docstring).

    Args:
        table: the memory's predicted press outcomes (see :func:`palpate.core.planning.outcomes.outcome_table`).
        reach, correlation_cells, temperature, surprise: the belief's (see
            :func:`~palpate.core.planning.expected_accuracy.label_belief`).
        freq_tolerance: largest drift of a material's frequency before a full rescoring.
        max_window: a change whose window covers more than this share of the map is rescored in full.
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
        self._p = self._explored = self._post = None
        self._key = None
        self.rescored_cells = 0  # cells rescored by the last call (how much work it did)

    def _gain_of(self, p, explored, post_p, base, p_min) -> np.ndarray:
        return expected_accuracy_gain(_Plane(p, explored, base, p_min), _Plane(post_p, explored, base, p_min),
                                      self.table, reach=self.reach, correlation_cells=self.correlation_cells,
                                      temperature=self.temperature, surprise=self.surprise, freq=self.freq)

    def fits(self, grid) -> bool:
        """Whether this cache was made for a map of ``grid``'s shape and materials."""
        return self._key is None or self._key == (np.shape(grid.probabilities), tuple(grid.materials))

    def _fresh_freq(self, p: np.ndarray, explored: np.ndarray) -> np.ndarray:
        return material_frequencies(np.argmax(p, axis=-1), explored, p.shape[-1])

    def full(self, grid, post) -> np.ndarray:
        """Score every cell (refreshing the kept frequencies) and keep the result; returns the gains (ny, nx)."""
        p = np.array(grid.probabilities, dtype=float)
        explored = np.array(grid.explored, dtype=bool)
        post_p = np.array(post.probabilities, dtype=float)
        self.freq = self._fresh_freq(p, explored)
        self.gain = self._gain_of(p, explored, post_p, grid.base, grid.p_min)
        self._p, self._explored, self._post = p, explored, post_p
        self._key = (p.shape, tuple(grid.materials))
        self.rescored_cells = explored.size
        return self.gain.copy()

    def update(self, grid, post, local: bool = True) -> np.ndarray:
        """The gains after whatever changed since the last call, rescoring only around the changes (every cell,
        with the same kept frequencies, when not ``local``: the full computation the local one must equal)."""
        if self.gain is None or not self.fits(grid):
            return self.full(grid, post)
        p = np.asarray(grid.probabilities)
        explored = np.asarray(grid.explored)
        post_p = np.asarray(post.probabilities)
        if np.max(np.abs(self._fresh_freq(p, explored) - self.freq)) > self.freq_tolerance:
            return self.full(grid, post)
        if not local:
            self.gain = self._gain_of(p, explored, post_p, grid.base, grid.p_min)
            self._p, self._explored, self._post = p.copy(), explored.copy(), post_p.copy()
            self.rescored_cells = explored.size
            return self.gain.copy()
        changed = (explored != self._explored) | np.any(p != self._p, axis=-1) | np.any(post_p != self._post, axis=-1)
        rows = np.flatnonzero(changed.any(axis=1))
        self.rescored_cells = 0
        if rows.size == 0:
            return self.gain.copy()
        cols = np.flatnonzero(changed.any(axis=0))
        ny, nx = changed.shape
        r = self.radius
        # cells whose gain can change, and the crop holding everything they depend on
        y0, y1 = max(0, rows[0] - r), min(ny, rows[-1] + r + 1)
        x0, x1 = max(0, cols[0] - r), min(nx, cols[-1] + r + 1)
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
        self.rescored_cells = (y1 - y0) * (x1 - x0)
        return self.gain.copy()
