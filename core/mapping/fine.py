"""A fine material map (1 mm by default) under a 2-D cell map, sharpened by the presses' boundary readings
(:mod:`palpate.core.boundary`).

The cell map says which material each cell holds; a press's boundary reading says where, near the press, one
material gives way to a harder one. Each fine point's distribution mixes:

- its own cell's distribution, with a small weight (what is known without a reading);
- per press with a reading, weighted by closeness to the press (a Gaussian whose width follows the presses'
  spacing: far apart, early in an exploration or on coarse cells, a reading reaches further; along a wall it read,
  further still, as a wall goes on past the contact patch): when the press read a
  wall (probability p_boundary), the distribution of the nearest cell on the point's side whose centre is clear of
  the wall (a press there felt one material; cells astride a wall are judged on a mixture), each side in proportion
  to the probability that the point lies there given the reading's offset and angle spreads; when it read none
  (1 - p_boundary), the press's own cell's distribution;
- its nearest press's reading as above, with a small weight however far: where no press reaches and the
  cell map knows nothing (a uniform cell beyond eq. 6.15's neighbours), the nearest press decides the point.

The mixture is then sharpened by a temperature (the mixture alone is under-confident), and where the map draws a
wall far from every press, the wall's place is known only roughly: a point beside such a wall may lie on its other
side (see :func:`unseen_walls`). The cell map itself (the seed's grid and eq. 6.15) is unchanged; this layer is
computed from it.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from scipy.ndimage import distance_transform_edt
from scipy.spatial import cKDTree
from scipy.special import ndtr

from palpate.core import limits
from palpate.core.boundary.moduli import MaterialModuli
from palpate.core.boundary.reading import BoundaryReading
from palpate.core.errors import ValidationError
from palpate.core.mapping.geometry import MapGeometry

#: Side of a fine map's square point, m.
RESOLUTION = 1e-3
#: Weight of a point's own cell against the readings near it.
CELL_WEIGHT = 0.05
#: Least distance from a press over which its reading's weight falls by e, m (about the contact radius at depth).
REACH = 6e-3
#: Most such distance, m: where presses lie far apart.
REACH_MAX = 9e-3
#: Between the two, the readings reach this share of the presses' mean spacing (the root of the map's area over the
#: places pressed): a raster of 10 mm cells 6 mm, of 15 mm cells 9 mm, a third of a raster of 10 mm cells 9 mm. The
#: boundary policy plans with the same reach. Chosen on its exploration of tuning scenes 0-89
#: (benchmarks/exploration_fine.py) against 6 mm, 9 mm and reaches following the cell size or each press's nearest
#: press: as good as 9 mm there, which blurred the walls of heterogeneous.toml's 10 mm raster (median boundary error
#: 0 -> 1 mm, ECE near a wall 0.045 -> 0.108).
SPACING = 0.6
#: Temperature of the mixed distributions (below 1: sharper). A mixture of the cell map's and the readings'
#: distributions is under-confident (points it calls 0.75 are right 0.92 of the time). Chosen with WALL_SPREAD and
#: WALL_SPREAD_FROM on the boundary policy's and raster's maps of tuning scenes 0-23 after 0.1, 0.25, 0.5 and all of
#: raster's presses (benchmarks/exploration_fine.py --calibration): of the grid 0.6-0.75 x 1.0-1.6 x 5-7 mm, the
#: triple whose pooled ECE stays <= 0.05 over all points at every share and within 5 mm of a wall on the full maps,
#: with the lowest worst ECE within 5 mm of a wall on the sparse ones. With readings stretched along their walls
#: (ELONGATION) the mixture beside walls is less sharp: of 0.5-0.65 on the boundary policy's maps of tuning scenes 0-89,
#: the one with the lowest worst ECE on the sparse maps whose full maps stay within 0.04 near walls (0.65: 0.049). It
#: never changes a point's most probable material.
TEMPERATURE = 0.6
#: How far a wall the map draws may lie from where it is drawn, per metre that its points lie beyond
#: WALL_SPREAD_FROM from every press (midway between presses 30 mm apart, a wall is placed to within 9 mm).
WALL_SPREAD = 1.0
#: Distance from the nearest press within which the readings place walls themselves, m (about their reach).
WALL_SPREAD_FROM = 7e-3
#: Weight of a point's nearest press's reading, however far, against CELL_WEIGHT (see :func:`fine_map`): of 0.003-1,
#: the one with the most area right after a tenth of raster's presses (boundary policy, tuning scenes 0-17: median
#: 0.76 -> 0.86) among those that keep the area right after a full raster.
FAR_WEIGHT = 0.05
#: How far a reading that read a wall reaches along that wall, in reaches (across it, one reach): a wall goes on
#: past the contact patch, so beside it the press that felt it outweighs a farther press that felt one material.
#: Where the wall is curved the side's probability widens with the reading's angle spread (:func:`_reading_field`).
#: Chosen on the boundary policy's exploration of tuning scenes 0-89 (benchmarks/exploration_fine.py) among 1, 1.5,
#: 2 and 3.
ELONGATION = 1.5
#: Points farther than this many reaches from a press take nothing from its reading (its weight there is below
#: 1e-5, a 5000th of a point's own cell's; along a wall it read, the reach stretches only as far as the stretched
#: weight stays above that): a reading costs the same on any size of map. 3.5 against 5 (weight below 2.8e-11):
#: the same presses to 95% of the area right on every one of tuning scenes 0-89, a fifth less CPU in exploration.
CUTOFF = 3.5


@dataclass(frozen=True)
class FineMap:
    """Material probabilities on a fine raster over a 2-D map.

    Attributes:
        origin: (x0, y0) of the raster's corner, m (the cell map's).
        resolution: side of one point's square, m.
        probabilities: (ny, nx, M), per point a distribution over the cell map's materials.
        materials: their names.
    """

    origin: tuple[float, float]
    resolution: float
    probabilities: np.ndarray
    materials: tuple[str, ...]

    def centres(self) -> np.ndarray:
        """(ny, nx, 2) point centres, m."""
        ny, nx = self.probabilities.shape[:2]
        xs = self.origin[0] + (np.arange(nx) + 0.5) * self.resolution
        ys = self.origin[1] + (np.arange(ny) + 0.5) * self.resolution
        gx, gy = np.meshgrid(xs, ys)
        return np.stack([gx, gy], axis=-1)

    def labels(self) -> np.ndarray:
        """(ny, nx) index of each point's most probable material."""
        return np.argmax(self.probabilities, axis=-1)

    def cells_on_raster(self, cell_values: np.ndarray) -> np.ndarray:
        """A cell map's per-cell values, (ny_cells, nx_cells, ...), repeated onto this raster's points."""
        n = self.probabilities.shape[0] // cell_values.shape[0]
        return np.repeat(np.repeat(cell_values, n, axis=0), n, axis=1)


def points_per_cell(geometry: MapGeometry, resolution: float = RESOLUTION) -> int:
    """Fine points along a cell's side for ``resolution`` (m): the nearest whole number, lowered as far as needed
    to keep the raster within the limit ``map_cells`` (a map over metres of cells would otherwise take gigabytes
    after its last press); at least 1."""
    nx, ny = geometry.plane_shape
    n = max(1, int(round(geometry.cell_size / resolution)))
    return max(1, min(n, math.isqrt(int(limits.limit("map_cells") // (nx * ny)))))


def _clear_cell(geometry: MapGeometry, probs: np.ndarray, astride: np.ndarray, foot: np.ndarray, step: np.ndarray,
                clear: float) -> np.ndarray:
    """The distribution of the first cell along ``step`` (a unit vector) from the wall's foot whose centre lies at
    least ``clear`` from the wall and whose own press did not read a wall within ``clear`` (a press there felt one
    material); the nearest cell clear of this wall if none is."""
    nx, ny = geometry.plane_shape
    first = None
    for k in range(1, 4 * max(nx, ny)):
        ix, iy = geometry.cells_at(foot + step * (k * geometry.cell_size / 4))
        centre = np.array(geometry.origin) + (np.array([ix, iy]) + 0.5) * geometry.cell_size
        if abs(float((centre - foot) @ step)) < clear:
            continue
        first = probs[iy, ix] if first is None else first
        if astride[iy, ix] < 0.5:
            return probs[iy, ix]
    return first if first is not None else probs[geometry.cells_at(foot)[::-1]]


def _astride(geometry: MapGeometry, readings, clear: float) -> np.ndarray:
    """Per cell, the probability that its (last) press read a wall within ``clear`` of its axis (0 when none
    read)."""
    nx, ny = geometry.plane_shape
    out = np.zeros((ny, nx))
    for (x0, y0), r in readings:
        ix, iy = geometry.cells_at(np.array([x0, y0]))
        out[iy, ix] = float(r.posterior[:, np.abs(r.offsets) < clear].sum())
    return out


def window_around(shape: tuple[int, int], origin: tuple[float, float], res: float, xy: tuple[float, float],
                  radius: float | None) -> tuple[slice, slice] | None:
    """The (rows, columns) of a raster of ``shape`` whose points lie within ``radius`` (m) of ``xy`` along both
    axes (all of them when None); None when none do."""
    if radius is None:
        return slice(None), slice(None)
    ny, nx = shape
    x0, x1 = (int(np.floor((xy[0] - radius - origin[0]) / res)), int(np.ceil((xy[0] + radius - origin[0]) / res)) + 1)
    y0, y1 = (int(np.floor((xy[1] - radius - origin[1]) / res)), int(np.ceil((xy[1] + radius - origin[1]) / res)) + 1)
    x0, x1, y0, y1 = max(x0, 0), min(x1, nx), max(y0, 0), min(y1, ny)
    if x0 >= x1 or y0 >= y1:
        return None
    return slice(y0, y1), slice(x0, x1)


def fine_map(geometry: MapGeometry, probabilities: np.ndarray, readings: list[tuple[tuple[float, float],
             BoundaryReading]], *, resolution: float = RESOLUTION, reach: float = REACH,
             cell_weight: float = CELL_WEIGHT, clear: float = REACH, moduli: MaterialModuli | None = None,
             cutoff: float | None = CUTOFF, temperature: float = TEMPERATURE,
             far_weight: float = FAR_WEIGHT, reach_max: float = REACH_MAX, spacing: float = SPACING,
             wall_spread: float = WALL_SPREAD, wall_spread_from: float = WALL_SPREAD_FROM,
             elongation: float = ELONGATION) -> FineMap:
    """The fine map of a 2-D cell map (see the module docstring).

    Args:
        geometry: the cell map's geometry (2-D only).
        probabilities: the cell map's distributions, (ny, nx, M) (e.g. the post-processed map's).
        readings: per press, its measured (x, y) location, m, and its boundary reading in the world's frame.
        resolution: fine point side, m (coarsened, to a whole number of points a cell side, where the raster would
            hold more points than the limit ``map_cells``: see :func:`points_per_cell`); cell_weight: see above;
            clear: distance from a wall at which a cell's centre counts as clear of it, m (about the contact radius).
        moduli: the reference materials' moduli as the reading reads them (:mod:`palpate.core.boundary.moduli`):
            when given, each side of a read wall is the material its read modulus matches, not a neighbour cell's.
        reach, reach_max, spacing: the distance scale of the readings' weights, m: ``spacing`` times the presses'
            mean spacing (:func:`reading_reach`), clipped to [reach, reach_max]; reach_max = reach: that one scale.
        cutoff: a reading reaches points within this many ``reach`` (along a read wall, up to ``elongation`` times that)
            of its press (None: every point).
        elongation: a reading's reach along the wall it read over its reach across it, >= 1 (1: the same every
            way); it applies in proportion to the reading's probability of a wall.
        far_weight: weight of each point's nearest reading, however far (0: none; a point out of every reading's
            reach then keeps its cell's distribution).
        temperature: each point's distribution is raised to 1 / temperature and renormalised (1: the mixture as it
            is; below 1 sharper); the most probable material stays.
        wall_spread, wall_spread_from: see :func:`unseen_walls` (m per m, m); wall_spread 0: the sharpened mixture
            as it is.

    Raises:
        ValidationError: a voxel geometry, probabilities of another shape, or a resolution that is not a positive
            fraction of the cell size.
    """
    if geometry.voxel:
        raise ValidationError("fine_map: 2-D maps only")
    nx, ny = geometry.plane_shape
    probs = np.asarray(probabilities, dtype=float)
    if probs.shape[:2] != (ny, nx) or probs.ndim != 3:
        raise ValidationError(f"fine_map: probabilities must be ({ny}, {nx}, M), got {probs.shape}")
    if not (0 < resolution <= geometry.cell_size and reach > 0 and cell_weight > 0 and 0 < temperature < np.inf
            and 0 <= far_weight < np.inf and reach <= reach_max < np.inf and 0 <= spacing < np.inf
            and 0 <= wall_spread < np.inf and 0 <= wall_spread_from < np.inf and 1 <= elongation < np.inf):
        raise ValidationError("fine_map: resolution must be in (0, cell size], reach, cell_weight and temperature "
                              "> 0 and finite, far_weight, spacing, wall_spread and wall_spread_from >= 0 and finite, "
                              "reach_max in [reach, inf), elongation in [1, inf)")
    n = points_per_cell(geometry, resolution)
    out = FineMap(geometry.origin, geometry.cell_size / n, np.zeros((ny * n, nx * n, probs.shape[2])),
                  geometry.materials)
    pts = out.centres()
    ix, iy = geometry.cells_at(pts)
    acc = cell_weight * probs[iy, ix]
    weight = np.full(pts.shape[:2], cell_weight)
    # which cells' presses straddle a wall: only needed when neighbour cells name the sides
    astride = _astride(geometry, readings, clear) if moduli is None else None
    res = out.resolution
    reach = reading_reach(geometry, readings, reach, reach_max, spacing)
    fields = []  # per reading on the map: (location, the reading's field at points relative to it)
    for (x0, y0), r in readings:
        window = window_around(pts.shape[:2], geometry.origin, res, (x0, y0), _radius(r, reach, cutoff, elongation))
        if window is None:
            continue
        own = probs[geometry.cells_at(np.array([x0, y0]))[::-1]]
        if moduli is not None:
            matched = own * moduli.probabilities(r.log_plain, geometry.materials)
            own = matched / matched.sum() if matched.sum() > 0 else own
            hard = moduli.probabilities(r.log_hard, geometry.materials)
            soft = moduli.probabilities(r.log_soft, geometry.materials)
        else:
            foot = np.array([x0, y0]) + r.foot
            hard = _clear_cell(geometry, probs, astride, foot, r.normal, clear)
            soft = _clear_cell(geometry, probs, astride, foot, -r.normal, clear)
        field = functools.partial(_reading_field, r, own, hard, soft, res)
        rel = pts[window] - np.array([x0, y0])
        w = _weights(r, rel, reach, elongation)
        acc[window] += w[..., None] * field(rel)
        weight[window] += w
        fields.append(((x0, y0), field))
    if far_weight > 0 and fields:
        # each point also hears its nearest press, however far: where no press reaches and the cell map knows
        # nothing (a uniform cell), that decides the point as the press says, with little confidence
        flat = pts.reshape(-1, 2)
        _, nearest = cKDTree(np.array([xy for xy, _ in fields])).query(flat)
        far = np.empty((len(flat), probs.shape[2]))
        # one pass: the points sorted by their nearest reading, each reading's run evaluated at once
        order = np.argsort(nearest, kind="stable")
        runs, starts = np.unique(nearest[order], return_index=True)
        for k, at in zip(runs, np.split(order, starts[1:]), strict=True):
            far[at] = fields[k][1](flat[at] - np.array(fields[k][0]))
        acc += far_weight * far.reshape(acc.shape)
        weight += far_weight
    mixed = acc / weight[..., None]
    if temperature != 1.0:
        # scaled by each point's largest first: no underflow to 0/0 however sharp
        mixed = np.power(mixed / mixed.max(axis=-1, keepdims=True), 1.0 / temperature)
        mixed /= mixed.sum(axis=-1, keepdims=True)
    if wall_spread > 0 and readings:
        mixed = unseen_walls(mixed, pts, np.array([xy for xy, _ in readings], dtype=float), res, wall_spread,
                             wall_spread_from)
    return FineMap(out.origin, out.resolution, mixed, out.materials)


def unseen_walls(probabilities: np.ndarray, points: np.ndarray, presses: np.ndarray, resolution: float,
                 spread: float = WALL_SPREAD, spread_from: float = WALL_SPREAD_FROM) -> np.ndarray:
    """A fine map's distributions with the uncertainty of walls drawn far from every press.

    Near a press (within ``spread_from``) its reading places a wall; farther out the map draws walls where cells
    change material, and such a wall may lie anywhere within about the distance to the nearest press. A point at
    distance b from the map's nearest drawn wall and d from the nearest press lies on the wall's other side with
    probability Phi(-b / sigma), sigma = ``spread`` * max(0, d - ``spread_from``); its two most probable materials
    swap with that probability (a point beside a drawn wall far from every press is nearly undecided between its
    sides; none changes its most probable material). Points within ``spread_from`` of a press keep their
    distribution.

    Args:
        probabilities: (ny, nx, M) distributions on a raster of square points ``resolution`` m a side.
        points: (ny, nx, 2) the points' centres, m.
        presses: (K, 2) press locations, m (K >= 1).
        spread: m of a wall's place per m of distance beyond ``spread_from``; spread_from: m.

    Returns:
        The new (ny, nx, M) distributions (the input is not changed).
    """
    p = np.asarray(probabilities, dtype=float)
    if p.shape[-1] < 2:
        return p.copy()
    drawn = edges(np.argmax(p, axis=-1), both_sides=True)
    if not drawn.any():  # one material everywhere: no wall to misplace
        return p.copy()
    d, _ = cKDTree(np.asarray(presses, dtype=float)).query(points.reshape(-1, 2))
    sigma = spread * np.maximum(0.0, d.reshape(p.shape[:2]) - spread_from)
    # distance from a point's centre to the drawn wall: to the centre of the nearest point beside it, plus half a point
    b = distance_transform_edt(~drawn) * resolution + 0.5 * resolution
    swap = np.where(sigma > 0, ndtr(-b / np.where(sigma > 0, sigma, 1.0)), 0.0)[..., None]
    order = np.argsort(p, axis=-1)
    top, second = order[..., -1:], order[..., -2:-1]
    p_top, p_second = np.take_along_axis(p, top, -1), np.take_along_axis(p, second, -1)
    out = p.copy()
    np.put_along_axis(out, top, (1 - swap) * p_top + swap * p_second, -1)
    np.put_along_axis(out, second, (1 - swap) * p_second + swap * p_top, -1)
    return out


def reading_reach(geometry: MapGeometry, readings, reach: float = REACH, reach_max: float = REACH_MAX,
                  spacing: float = SPACING) -> float:
    """The distance scale of the readings' weights on a fine map, m: ``spacing`` times the presses' mean spacing,
    the root of the map's area over the number of places pressed (presses rounded to the same millimetre are one
    place), clipped to [reach, reach_max]; reach_max with no reading."""
    if not readings:
        return float(reach_max)
    places = len(np.unique(np.round(np.array([xy for xy, _ in readings], dtype=float) / 1e-3), axis=0))
    nx, ny = geometry.plane_shape
    return float(np.clip(spacing * geometry.cell_size * math.sqrt(nx * ny / places), reach, reach_max))


def _radius(r: BoundaryReading, reach: float, cutoff: float | None, elongation: float) -> float | None:
    """How far a reading reaches, m: ``cutoff`` reaches, and along a read wall as far as its stretched weight stays
    above exp(-cutoff^2) (so a reading that read no wall costs no more than an unstretched one); None: everywhere."""
    if cutoff is None:
        return None
    p_wall = 1.0 - r.p_plain
    if elongation == 1.0 or p_wall <= 0.0:
        return cutoff * reach
    # p_wall exp(-(d / (elongation reach))^2) = exp(-cutoff^2) at d = elongation reach sqrt(cutoff^2 + ln p_wall)
    return reach * max(cutoff, elongation * math.sqrt(max(0.0, cutoff**2 + math.log(p_wall))))


def _weights(r: BoundaryReading, rel: np.ndarray, reach: float, elongation: float) -> np.ndarray:
    """A reading's weight at points ``rel`` (..., 2) m from its press: a Gaussian of width ``reach``, stretched
    ``elongation`` times along the wall it read as far as it read one (1 - p_plain)."""
    w = np.exp(-np.sum(rel**2, axis=-1) / reach**2)
    if elongation == 1.0:
        return w
    across = rel @ r.normal
    along = rel @ r.tangent
    p_wall = 1.0 - r.p_plain
    return (1.0 - p_wall) * w + p_wall * np.exp(-(across**2 + (along / elongation) ** 2) / reach**2)


def _reading_field(r: BoundaryReading, own: np.ndarray, hard: np.ndarray, soft: np.ndarray, res: float,
                   rel: np.ndarray) -> np.ndarray:
    """A reading's distribution at points ``rel`` (..., 2) m from its press: each side of a read wall in proportion
    to the probability that the point lies there, the press's own material where no wall was read."""
    n_vec = r.normal
    s = rel @ n_vec - r.offset
    along = np.abs(rel @ r.tangent)
    spread = np.sqrt(r.offset_sd**2 + (r.angle_sd * along) ** 2 + (0.25 * res) ** 2)
    q = ndtr(s / spread)[..., None]
    p_wall = 1.0 - r.p_plain
    return p_wall * (q * hard + (1 - q) * soft) + (1 - p_wall) * own


def edges(labels: np.ndarray, both_sides: bool = False) -> np.ndarray:
    """Points of a label raster whose label differs from the point before them along x or y (``both_sides``: or
    from the point after them, so both sides of every boundary are marked)."""
    e = np.zeros(labels.shape, dtype=bool)
    e[:, 1:] |= labels[:, 1:] != labels[:, :-1]
    e[1:, :] |= labels[1:, :] != labels[:-1, :]
    if both_sides:
        e[:, :-1] |= labels[:, :-1] != labels[:, 1:]
        e[:-1, :] |= labels[:-1, :] != labels[1:, :]
    return e


def boundary_error(labels: np.ndarray, truth: np.ndarray, mask: np.ndarray, resolution: float) -> tuple[float, float]:
    """How far a labelled raster's boundaries lie from the true ones: the median and 90th percentile, over the true
    boundary points inside ``mask``, of the distance to the nearest boundary point of ``labels``, m (infinite when
    ``labels`` has no boundary; NaN when the truth has none in ``mask``)."""
    mine, true = edges(labels), edges(truth) & mask
    if not true.any():
        return float("nan"), float("nan")
    if not mine.any():
        return float("inf"), float("inf")
    dist = distance_transform_edt(~mine) * resolution
    return float(np.median(dist[true])), float(np.percentile(dist[true], 90))
