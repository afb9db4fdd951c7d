"""The boundary policy: press where the fine material map (:mod:`palpate.core.mapping.fine`) is least sure, at
the point of the map where a press would settle most of it, not only at cell centres.

A press reads a wall within about a contact radius of its axis (:mod:`palpate.core.boundary`), so a wall half-way
between two pressed cell centres (up to half a cell from both) is out of reach of every cell-centred press; the fine
map can only guess it. This policy scores every point of the fine raster by the fine map's expected errors within a
reading's reach of it (a Gaussian of the fine map's reach, which follows the presses' spacing), discounted where
presses already landed, and adds :class:`~palpate.core.planning.info_gain.InfoGain`'s value of the point's cell
(what a press can reveal that no reading near a known wall will: a feature hidden between lattice presses). It
presses the best point within the inner part of its cell (``shift``): the cell map judges the cell by that press,
and a press far off the centre feels the neighbour's material as much as its own.

It starts with info_gain's even lattice; it needs the presses' boundary readings (``observe``), which the run gives
it on 2-D maps when the pad has templates; without them the fine map is the cell map spread on the raster and the
policy still works, as a smoothed info_gain.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.ndimage import gaussian_filter

from palpate.core.errors import ValidationError
from palpate.core.mapping.fine import (
    CUTOFF,
    FAR_WEIGHT,
    REACH,
    REACH_MAX,
    RESOLUTION,
    WALL_SPREAD,
    FineMap,
    fine_map,
    reading_reach,
    window_around,
)
from palpate.core.mapping.geometry import MapGeometry
from palpate.core.planning.info_gain import InfoGain
from palpate.core.planning.map_views import plane_shape, postprocess
from palpate.core.planning.policies import Target


@dataclass
class BoundarySeeking:
    """Press the point where the fine map's expected errors within reach, plus info_gain's value of its cell, are
    largest (module docstring).

    Args:
        memory: the trained haptic memory (info_gain's outcome model).
        geometry: the 2-D map's geometry.
        moduli: the reference materials' moduli as readings read them, or None (sides named by neighbour cells).
        travel_cost_per_mm: score units (cells) subtracted per mm from the last press.
        passes, certainty: of the post-processing computed when ``post`` is not given.
        seed: of info_gain's outcome draws.
        fine_weight: weight of the fine map's expected errors (in cells of area) against info_gain's value.
        crowding: distance over which an earlier press discounts a point (m): a second press where one landed reads
            what the first one read.
        shift: how far off its cell's centre a press may go, as a share of the half-width, [0, 1] (0 = centres
            only, as info_gain).
        spread_stride: info_gain's first lattice (every ``spread_stride``-th cell).
        far_weight: the fine map's weight of a point's nearest reading however far (0: plan on the readings in
            reach only; the default, the reported map's, took tuning scenes 0-17 to 95% of the area right in 0.25 of
            raster's presses against 0.26 with 0).
        resolution: the fine map's (m); reach: the fine map's least reach, m (its reach follows the presses'
            spacing, :func:`palpate.core.mapping.fine.reading_reach`; a press settles the errors within it).
        wall_spread: how roughly the fine map places a wall it draws far from every press
            (:func:`palpate.core.mapping.fine.unseen_walls`; 0: as drawn). The reported map's: the planner then
            presses beside such walls (tuning scenes 0-89: fewer presses to 95% of the area right than with 0 on 41,
            more on 21).
    """

    memory: object
    geometry: MapGeometry
    moduli: object | None = None
    travel_cost_per_mm: float = 0.0
    passes: int | None = 1
    certainty: float = 1.0
    seed: int = 0
    fine_weight: float = 1.0
    crowding: float = 3e-3
    shift: float = 0.5
    spread_stride: int = 3
    far_weight: float = FAR_WEIGHT
    resolution: float = RESOLUTION
    reach: float = REACH
    wall_spread: float = WALL_SPREAD
    _info: InfoGain = field(init=False, repr=False)
    _readings: list = field(default_factory=list, init=False, repr=False)
    _pressed: list = field(default_factory=list, init=False, repr=False)

    def __post_init__(self) -> None:
        if self.geometry.voxel:
            raise ValidationError("the boundary policy plans on a fine 2-D map; a voxel map needs another policy")
        for key in ("fine_weight", "crowding", "travel_cost_per_mm", "far_weight", "wall_spread"):
            v = getattr(self, key)
            if not (np.isfinite(v) and v >= 0):
                raise ValidationError(f"boundary policy: {key} must be a finite number >= 0, got {v!r}")
        if not 0 <= self.shift <= 1:
            raise ValidationError(f"boundary policy: shift must be in [0, 1], got {self.shift!r}")
        self._info = InfoGain(self.memory, passes=self.passes, certainty=self.certainty, seed=self.seed,
                              spread_stride=int(self.spread_stride))

    def observe(self, location: tuple[float, float], reading) -> None:
        """Take in a press: its measured (x, y), m, and its boundary reading in the world frame (None if none)."""
        xy = (float(location[0]), float(location[1]))
        self._pressed.append(xy)
        if reading is not None:
            self._readings.append((xy, reading))

    def expected_errors(self, fine) -> np.ndarray:
        """Per fine point, the chance its most probable material is wrong, (NY, NX)."""
        return 1.0 - fine.probabilities.max(axis=-1)

    def point_scores(self, grid, post) -> tuple[np.ndarray, FineMap, np.ndarray]:
        """(errors, fine, centres): the fine map's expected errors a press at each point of the fine raster would
        settle (cells of area, weighted by ``fine_weight``, discounted by crowding), shape (NY, NX); the fine map;
        its points' (x, y), m, (NY, NX, 2)."""
        # one reach, the fine map's, for the map and for the errors a press there settles
        reach = reading_reach(self.geometry, self._readings, self.reach, max(self.reach, REACH_MAX))
        # the unsharpened mixture, as the planner's weights were chosen on it (the temperature is for reports)
        fine = fine_map(self.geometry, post.probabilities, self._readings, resolution=self.resolution,
                        reach=reach, reach_max=reach, moduli=self.moduli, temperature=1.0, far_weight=self.far_weight,
                        wall_spread=self.wall_spread)
        wrong = self.expected_errors(fine)
        res = fine.resolution
        n = int(round(self.geometry.cell_size / res))
        # sum of wrong(p) exp(-|p - q|^2 / reach^2) over the points p, in cells of area
        sigma = reach / (res * math.sqrt(2))
        errors = gaussian_filter(wrong, sigma, mode="constant", truncate=3.0) * (math.pi * (reach / res) ** 2
                                                                              / n**2)
        pts = fine.centres()
        if self._pressed and self.crowding > 0:
            crowd = np.zeros(wrong.shape)
            for xy in self._pressed:
                window = window_around(wrong.shape, self.geometry.origin, res, xy, CUTOFF * self.crowding)
                if window is not None:
                    crowd[window] += np.exp(-np.sum((pts[window] - np.array(xy)) ** 2, axis=-1) / self.crowding**2)
            errors = errors / (1.0 + crowd)
        return self.fine_weight * errors, fine, pts

    def next_target(self, grid, post=None, last=None) -> Target | None:
        """The next lattice cell's centre, then the best point by info_gain's value of its cell plus the fine errors
        a press there would settle, within ``shift`` of its cell's centre; its ``score`` is that sum (cells). Never
        None (the run's budget and stop rules end the exploration)."""
        post = postprocess(grid, self.passes, self.certainty, False) if post is None else post
        seed_cell = self._info.lattice_cell(grid, last)
        if seed_cell is not None:
            return Target(seed_cell[0], seed_cell[1])
        errors, fine, pts = self.point_scores(grid, post)
        value, _, allowed = self._info.value_terms(grid, post)
        n = errors.shape[0] // plane_shape(grid)[1]
        score = errors + fine.cells_on_raster(np.where(allowed, value, 0.0))
        if self.travel_cost_per_mm > 0 and self._pressed:
            score = score - self.travel_cost_per_mm * 1e3 * np.linalg.norm(pts - np.array(self._pressed[-1]), axis=-1)
        # a press stays within ``shift`` of its cell's half-width from the centre: the cell map judges the cell by
        # it, and a press far off the centre feels the neighbour's material as much as its own
        k = np.arange(n) + 0.5 - n / 2
        inner = np.abs(k) <= max(self.shift * n / 2, 0.5) + 1e-9
        score = np.where(np.tile(inner, score.shape[0] // n)[:, None] & np.tile(inner, score.shape[1] // n)[None, :],
                         score, -np.inf)
        j, i = np.unravel_index(int(np.argmax(score)), score.shape)
        ix, iy = int(i // n), int(j // n)
        if self.shift == 0:
            return Target(ix, iy, None, float(score[j, i]))
        x, y = (float(v) for v in pts[j, i])
        return Target(ix, iy, None, float(score[j, i]), (x, y))
