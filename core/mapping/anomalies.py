"""Spots harder or softer than the map says: where a buried lump lies though no press named its material.

A lump a few millimetres under the surface stiffens (or softens) the presses over it by tens of percent, yet the
memory still names the material on top, so the map shows nothing there. Each press's boundary reading also gives
the modulus of the one material that best explains its image (``log_plain``, in the reading's own units); the
reference materials' training presses give each material's mean and spread of it
(:class:`palpate.core.boundary.moduli.MaterialModuli`). A press whose modulus lies ``z`` spreads or more from that
of the material the map names at its cell is anomalous, unless a wall at the surface explains it: its image then
reads as a wall (``p_plain`` below :data:`P_PLAIN_MIN`) and the map names another material within one cell. On the
map's rim, and within a press's contact radius of the map's edge, only harder presses count (an object's free edge
within reach reads softer). Nearby anomalous presses of one sign (harder or softer) make one spot.

A deeper harder lump moves each press over it by only one or two spreads, but it moves all of them. So a press is
also anomalous when it and its neighbours agree: its z, less the median z of the presses of its material
(exploration presses read a little apart from the training presses every material's spread comes from), is at least
:data:`POOL_PRESS_Z` and the sum of those centred z over the presses within :data:`LINK_CELLS` of it that name the
same material, divided by the square root of their number, is at least :data:`POOL_Z_MIN` (only presses judged as
above, away from walls and the map's edge, take part). Only harder leans pool: pooling softer ones as well added as
many spots on no lump as lumps on tuning scenes (:data:`POOL_Z_MIN`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from palpate.core.boundary.lump_depth import LumpEvidence, read_lump_depth
from palpate.core.boundary.moduli import MaterialModuli
from palpate.core.boundary.reading import BoundaryReading
from palpate.core.errors import ValidationError
from palpate.core.mapping.geometry import MapGeometry

#: Spreads of the named material's read modulus beyond which a press is anomalous. Chosen on tuning scenes (lumps
#: 0-23 of benchmarks/lump_scenes.py, shape families 0-17; raster, physics presses) as the smallest half value with
#: at most one spot on no lump per ten scenes: 3 finds 20 of 46 lumps with 2 such spots in 42 scenes (2.5: 23 with
#: 12; 3.5: 18 with 1).
Z_MIN = 3.0
#: A press whose image reads as one material at least this likely is judged on its modulus alone.
P_PLAIN_MIN = 0.2
#: Anomalous presses within this many cells of each other make one spot.
LINK_CELLS = 1.5
#: Pooled evidence (the module docstring) at which a press and its neighbours make a harder spot together. Chosen on
#: tuning scenes 0-23 of voxel_lumps.py, fine_map_lumps.py and fine_map_families.py (72 scenes, 84 lumps; raster,
#: physics presses) as the most lumps for no more spots on no lump than single presses make: lumps spotted / stray
#: spots 34 / 9 without pooling, 35 / 9 at 3 and 3.5, 38 / 9 at 2.5; pooling softer leans too at 2.5: 41 / 12.
POOL_Z_MIN = 2.5
#: The least centred z of a press that pooled evidence may make anomalous (its own reading must lean that way).
POOL_PRESS_Z = 1.0
#: Fewest presses of a material whose median centres its z (fewer: not centred).
POOL_CENTRE_MIN = 5


@dataclass(frozen=True)
class StiffnessAnomaly:
    """A spot whose presses read harder or softer than the material the map names there.

    Attributes:
        sign: "harder" or "softer".
        material: the material the map names under the spot's strongest press.
        presses: how many presses it holds.
        centroid_m: (x, y) of its presses weighted by |z|, m.
        z: its strongest press's distance from the named material's mean log modulus, in that material's spreads
            (signed: > 0 harder).
        press: the index of its strongest press in the readings it was found in.
        locations: (x, y) of each of its presses, m.
    """

    sign: str
    material: str
    presses: int
    centroid_m: tuple[float, float]
    z: float
    press: int = -1
    locations: tuple[tuple[float, float], ...] = ()

    def to_dict(self) -> dict:
        """JSON-ready form (summary.json)."""
        return {"sign": self.sign, "material": self.material, "presses": self.presses,
                "centroid_m": list(self.centroid_m), "z": self.z,
                "press_locations_m": [list(xy) for xy in self.locations]}


def press_z(geometry: MapGeometry, probabilities: np.ndarray, readings, moduli: MaterialModuli) -> np.ndarray:
    """Per reading, its read modulus against the material the map names at its cell, in that material's spreads
    (NaN where the map names a material the moduli do not know)."""
    return _named_z(geometry, np.argmax(np.asarray(probabilities, dtype=float), axis=-1), readings, moduli)[2]


def _named_z(geometry: MapGeometry, labels: np.ndarray, readings, moduli: MaterialModuli):
    """(ix, iy, z): each reading's cell and :func:`press_z`, with ``labels`` the map's most probable material per
    cell (ny, nx)."""
    xy = np.array([loc[:2] for loc, _ in readings], dtype=float).reshape(-1, 2)
    ix, iy = geometry.cells_at(xy)
    known = np.array([moduli.materials.index(m) if m in moduli.materials else -1 for m in geometry.materials])
    k = known[labels[iy, ix]]
    log_plain = np.array([r.log_plain for _, r in readings], dtype=float)
    z = np.full(len(readings), np.nan)
    z[k >= 0] = (log_plain[k >= 0] - moduli.log_mean[k[k >= 0]]) / moduli.log_sd[k[k >= 0]]
    return ix, iy, z


def stiffness_anomalies(geometry: MapGeometry, probabilities: np.ndarray,
                        readings: list[tuple[tuple[float, float], BoundaryReading]], moduli: MaterialModuli, *,
                        z_min: float = Z_MIN, p_plain_min: float = P_PLAIN_MIN,
                        link_cells: float = LINK_CELLS, edge_reach: float = 0.0,
                        pool_z_min: float = POOL_Z_MIN) -> list[StiffnessAnomaly]:
    """The spots of a 2-D map (``probabilities`` (ny, nx, M), e.g. post-processed) where presses read harder or
    softer than it says (see the module docstring), strongest first.

    Args:
        geometry: the map's geometry (2-D).
        probabilities: its distributions.
        readings: per press, its measured (x, y) location, m, and its boundary reading.
        moduli: the reference materials' read moduli.
        z_min, p_plain_min, link_cells, pool_z_min: see :data:`Z_MIN`, :data:`P_PLAIN_MIN`, :data:`LINK_CELLS`,
            :data:`POOL_Z_MIN` (inf: no pooled evidence).
        edge_reach: m; a softer press this close to the map's edge is taken for the object's free edge, as one in a
            rim cell is (the contact radius at the press's depth: a deep press feels an edge two cells away).

    Raises:
        ValidationError: a voxel map, probabilities of another shape or not finite, or settings that are not
            positive (edge_reach: not finite or negative).
    """
    if geometry.voxel:
        raise ValidationError("stiffness_anomalies: 2-D maps only")
    nx, ny = geometry.plane_shape
    probs = np.asarray(probabilities, dtype=float)
    if probs.shape != (ny, nx, len(geometry.materials)) or not np.all(np.isfinite(probs)):
        raise ValidationError(f"stiffness_anomalies: probabilities must be finite, ({ny}, {nx}, "
                              f"{len(geometry.materials)}), got {probs.shape}")
    if not (z_min > 0 and 0 <= p_plain_min <= 1 and link_cells > 0 and 0 <= edge_reach < np.inf
            and pool_z_min > 0):
        raise ValidationError("stiffness_anomalies: z_min, link_cells and pool_z_min must be > 0, p_plain_min in "
                              f"[0, 1], edge_reach a finite distance >= 0 m (got {edge_reach!r})")
    if not readings:
        return []
    labels = np.argmax(probs, axis=-1)
    cx, cy, z = _named_z(geometry, labels, readings, moduli)
    (x0, y0), span = geometry.origin, np.array([nx, ny]) * geometry.cell_size
    at = np.array([loc[:2] for loc, _ in readings], dtype=float).reshape(-1, 2)
    edge = np.minimum(np.minimum(at[:, 0] - x0, x0 + span[0] - at[:, 0]),
                      np.minimum(at[:, 1] - y0, y0 + span[1] - at[:, 1]))
    # the object's free edge may lie within reach of the map's rim: it reads softer there
    inner = (cx > 0) & (cx < nx - 1) & (cy > 0) & (cy < ny - 1) & (edge >= edge_reach)
    # a wall at the surface reads as a wall and shows in the map; a lump under one material does neither
    clear = np.array([r.p_plain >= p_plain_min or bool(np.all(
        labels[max(iy - 1, 0):iy + 2, max(ix - 1, 0):ix + 2] == labels[iy, ix]))
        for (_, r), ix, iy in zip(readings, cx, cy, strict=True)], dtype=bool) & np.isfinite(z)
    single = clear & (np.abs(z) >= z_min) & (inner | (z > 0))  # clear holds only finite z
    keep = np.flatnonzero(single | _pooled(at, labels[cy, cx], z, clear & inner, link_cells * geometry.cell_size,
                                           pool_z_min))
    if not len(keep):
        return []
    xy = at[keep]
    zk = z[keep]
    # neighbours by a tree, not a dense matrix: a long run may hold thousands of anomalous presses
    pairs = cKDTree(xy).query_pairs(link_cells * geometry.cell_size, output_type="ndarray")
    pairs = pairs[np.sign(zk[pairs[:, 0]]) == np.sign(zk[pairs[:, 1]])]
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(keep), len(keep)))
    _, spot = connected_components(graph, directed=False)
    out = []
    for s in np.unique(spot):
        members = np.flatnonzero(spot == s)
        w = np.abs(zk[members])
        strongest = members[int(np.argmax(w))]
        press = int(keep[strongest])
        centre = (w @ xy[members]) / w.sum()
        out.append(StiffnessAnomaly("harder" if zk[strongest] > 0 else "softer",
                                    geometry.materials[int(labels[cy[press], cx[press]])], len(members),
                                    (float(centre[0]), float(centre[1])), float(zk[strongest]), press,
                                    tuple((float(x), float(y)) for x, y in xy[members])))
    return sorted(out, key=lambda a: -abs(a.z))


def _pooled(xy: np.ndarray, named: np.ndarray, z: np.ndarray, eligible: np.ndarray, radius: float,
             pool_z_min: float) -> np.ndarray:
    """Mask of the presses that pooled evidence makes anomalous (the module docstring): ``xy`` (n, 2) m, ``named``
    the material index the map names at each, ``z`` their z, ``eligible`` those that take part."""
    out = np.zeros(len(z), dtype=bool)
    if not np.isfinite(pool_z_min) or eligible.sum() < 2:
        return out
    centred = np.zeros(len(z))
    for m in np.unique(named[eligible]):
        of = eligible & (named == m)
        centred[of] = z[of] - (np.median(z[of]) if of.sum() >= POOL_CENTRE_MIN else 0.0)
    idx = np.flatnonzero(eligible)
    pairs = idx[cKDTree(xy[idx]).query_pairs(radius, output_type="ndarray")].reshape(-1, 2)
    pairs = pairs[named[pairs[:, 0]] == named[pairs[:, 1]]]
    # each press pools itself and every same-material neighbour within the radius (pairs are listed once)
    total = centred + np.bincount(pairs[:, 0], centred[pairs[:, 1]], len(z)) \
        + np.bincount(pairs[:, 1], centred[pairs[:, 0]], len(z))
    count = 1.0 + np.bincount(pairs.ravel(), minlength=len(z))
    out[idx] = (centred[idx] >= POOL_PRESS_Z) & (total[idx] / np.sqrt(count[idx]) >= pool_z_min) & (z[idx] > 0)
    return out


def anomaly_report(geometry: MapGeometry, probabilities: np.ndarray,
                   readings: list[tuple[tuple[float, float], BoundaryReading]],
                   moduli: MaterialModuli | None, edge_reach: float = 0.0,
                   lumps: LumpEvidence | None = None) -> list[dict] | None:
    """summary.json's ``stiffness_anomalies`` of a 2-D map (None without the reference materials' moduli); with
    ``lumps`` (its curves one per reading), each spot's ``lump``: the lump its strongest press reads (its material,
    top depth and shape; :func:`~palpate.core.boundary.lump_depth.read_lump_depth`), or None."""
    if moduli is None:
        return None
    if lumps is not None and len(lumps.curves) != len(readings):
        raise ValidationError(f"anomaly_report: {len(lumps.curves)} press curves for {len(readings)} readings")
    out = []
    for a in stiffness_anomalies(geometry, probabilities, readings, moduli, edge_reach=edge_reach):
        row = a.to_dict()
        if lumps is not None:
            lump = read_lump_depth(lumps.curves[a.press], a.material, lumps, moduli, a.sign)
            row["lump"] = None if lump is None else lump.to_dict()
        out.append(row)
    return out
