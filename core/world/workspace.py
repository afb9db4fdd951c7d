"""Where each object's map lies on the workspace, and what is truly under each of its cells.

The map geometry follows the object's footprint unless the scenario gives ``grid_origin_mm``/``grid_shape``; the
ground truth is the object's material mapped to the reference material it stands for (``like``).
"""

from __future__ import annotations

import numpy as np

from palpate.core.mapping.geometry import MapGeometry
from palpate.core.world.scenario import ObjectEntry, Scenario
from palpate.core.world.scene import material_index_at


def _footprint(entry: ObjectEntry) -> np.ndarray:
    spec = entry.spec
    return np.array(spec.size[:2] if spec.shape != "cylinder" else (2 * spec.size[0],) * 2, dtype=float)


def object_geometry(scenario: Scenario, entry: ObjectEntry) -> MapGeometry:
    """The empty map of one object: over its footprint in cells of ``exploration.cell_size`` (or as the scenario
    places it), 2-D or voxels down to ``exploration.voxel_depth`` below the top."""
    ex = scenario.exploration
    spec = entry.spec
    extent = _footprint(entry)
    if entry.grid_origin is not None:
        origin = entry.grid_origin
    else:
        origin = (spec.position[0] - extent[0] / 2.0, spec.position[1] - extent[1] / 2.0)
    if entry.grid_shape is not None:
        nx, ny = entry.grid_shape
    else:
        nx, ny = (max(1, int(round(extent[0] / ex.cell_size))), max(1, int(round(extent[1] / ex.cell_size))))
    shape: tuple[int, ...] = (int(nx), int(ny))
    z_top = None
    if ex.map == "voxel":
        z_top = spec.height
        shape = (*shape, max(1, int(round(ex.voxel_depth / ex.cell_size))))
    return MapGeometry(kind=ex.map, materials=tuple(scenario.references), origin=(float(origin[0]), float(origin[1])),
                       cell_size=ex.cell_size, shape=shape, entropy_base=ex.entropy_base, z_top=z_top)


def map_geometries(scenario: Scenario) -> dict[str, MapGeometry]:
    """Every object's map geometry, by object name (written into recordings so that replay rebuilds the maps)."""
    return {entry.spec.name: object_geometry(scenario, entry) for entry in scenario.objects}


def ground_truth_cells(entry: ObjectEntry, scenario: Scenario, centres_xy: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Reference-material index (or -1) at each point: the object's material mapped through ``like``."""
    spec = entry.spec
    names = [m.name for m in spec.materials()]
    idx = material_index_at(spec, np.column_stack([centres_xy, z]), names)
    refs = scenario.references
    like = scenario.truth_names()
    lut = np.array([refs.index(like[n]) if n in like else -1 for n in names] + [-1])
    return lut[idx]


def ground_truth_map(entry: ObjectEntry, scenario: Scenario, geometry: MapGeometry) -> np.ndarray:
    """Reference-material index (or -1) of every cell of an object's map: (ny, nx) for a 2-D map, the material
    half-way down the planned press (what a press there mostly feels); (nx, ny, nz) like the voxel grid, at each
    voxel's centre."""
    nx, ny = geometry.plane_shape
    top = entry.spec.height
    flat = geometry.cell_centres().reshape(-1, 2)
    if not geometry.voxel:
        return ground_truth_cells(entry, scenario, flat,
                                  np.full(nx * ny, top - scenario.exploration.depth / 2)).reshape(ny, nx)
    nz = geometry.shape[2]
    zc = top - (np.arange(nz) + 0.5) * geometry.cell_size
    pts = np.concatenate([np.column_stack([flat, np.full(nx * ny, z)]) for z in zc])
    truth = ground_truth_cells(entry, scenario, pts[:, :2], pts[:, 2]).reshape(nz, ny, nx)
    return np.transpose(truth, (2, 1, 0))


def contact_radius(scenario: Scenario) -> float:
    """Contact radius of the fingertip pressed to the exploration depth, m: sqrt(R d), the sphere's (Hertz)
    value on a thick block."""
    return float(np.sqrt(scenario.fingertip.radius * scenario.exploration.depth))


#: Rings and angles at which clear_of_walls samples the truth around a cell's centre (at a 6 mm radius the
#: outer ring's points are 1.6 mm apart, finer than a sensel).
_RING_FRACTIONS = np.array([0.25, 0.5, 0.75, 1.0])
_RING_ANGLES = np.linspace(0.0, 2.0 * np.pi, 24, endpoint=False)


def clear_of_walls(entry: ObjectEntry, scenario: Scenario, geometry: MapGeometry, radius: float) -> np.ndarray | None:
    """Which cells of a 2-D map a press can read without feeling a second material.

    Args:
        entry, scenario, geometry: the object, its scenario and its map.
        radius: distance around each cell's centre that must hold one reference material, m (e.g. the contact
            radius of a press at exploration depth).

    Returns:
        (ny, nx) booleans like :func:`ground_truth_map`: True where the truth is the same at every sampled point
        within ``radius`` of the centre, at the depth the truth is taken; None for voxel maps. Points off the
        object (truth -1) are not a second material: a free edge is the contact law's business, not a wall.
    """
    if geometry.voxel:
        return None
    if radius < 0 or not np.isfinite(radius):
        raise ValueError(f"clear_of_walls: radius must be finite and >= 0, got {radius!r} m")
    nx, ny = geometry.plane_shape
    centres = geometry.cell_centres().reshape(-1, 2)
    rings = radius * _RING_FRACTIONS[:, None]
    # the centre first, then the rings: one lookup for all
    offsets = np.vstack([np.zeros((1, 2)), np.column_stack([(rings * np.cos(_RING_ANGLES)).ravel(),
                                                             (rings * np.sin(_RING_ANGLES)).ravel()])])
    points = (centres[:, None, :] + offsets[None, :, :]).reshape(-1, 2)
    z = np.full(len(points), entry.spec.height - scenario.exploration.depth / 2)
    truth = ground_truth_cells(entry, scenario, points, z).reshape(len(centres), len(offsets))
    return ((truth == truth[:, :1]) | (truth < 0)).all(axis=1).reshape(ny, nx)
