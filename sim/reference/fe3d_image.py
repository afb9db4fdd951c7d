"""The taxel image of the 3-D FE reference: the sensel pad's mean pressures from the top surface's nodal contact
forces (:func:`palpate.sim.reference.fe3d_solve.contact_field`).

Frames: the pad's x, y are the FE's x, y, the press (tip) axis at the origin, so a sensel footprint of
:func:`palpate.sim.fingertip.sensel_bounds` (row 0 at +y, column 0 at -x, the vertical projection onto the pad
plane) is a rectangle of the block's top. Each node's force is spread uniformly over its tributary rectangle (the
dual cell of the tensor grid: from half way to the previous grid line to half way to the next), and that rectangle
is intersected exactly with each footprint; a sensel's mean pressure is the force on its footprint over the sensel
area.
"""

from __future__ import annotations

import numpy as np

from palpate.core.world.scene import FingertipSpec
from palpate.sim.fingertip import sensel_bounds, sensel_quadrature
from palpate.sim.reference.fe3d import BoxBlock
from palpate.sim.reference.fe3d_solve import SurfaceContact, contact_field
from palpate.sim.validity.image import PressImage


def tributary_edges(nodes: np.ndarray) -> np.ndarray:
    """Edges (m, (n + 1,)) of the dual cells of increasing grid lines ``nodes`` (m): midpoints between nodes, the
    end cells as wide on their outer side as on their inner."""
    nodes = np.asarray(nodes, dtype=float)
    mid = 0.5 * (nodes[1:] + nodes[:-1])
    return np.concatenate([[nodes[0] - (mid[0] - nodes[0])], mid, [nodes[-1] + (nodes[-1] - mid[-1])]])


def _overlap(edges: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """(cells, intervals) length of each cell [edges[i], edges[i+1]] inside each interval [lo, hi], m."""
    return np.clip(np.minimum(edges[1:, None], hi[None, :]) - np.maximum(edges[:-1, None], lo[None, :]), 0.0, None)


def sensel_forces(field: SurfaceContact, tip: FingertipSpec) -> np.ndarray:
    """Force (N) on each sensel footprint, (n, rows, cols): each node's force spread over its tributary
    rectangle, intersected exactly with the footprints (see the module docstring)."""
    bounds = sensel_bounds(tip)
    ex, ey = tributary_edges(field.x), tributary_edges(field.y)
    ox = _overlap(ex, bounds[0, :, 0], bounds[0, :, 1]) / np.diff(ex)[:, None]  # (nx, cols) share of each cell
    oy = _overlap(ey, bounds[:, 0, 2], bounds[:, 0, 3]) / np.diff(ey)[:, None]  # (ny, rows)
    return np.einsum("yr,nyx,xc->nrc", oy, field.force, ox)


def field_image(field: SurfaceContact, tip: FingertipSpec) -> PressImage:
    """The pad's image of a nodal field: total force (N) and mean pressure (Pa) per sensel at each depth."""
    return PressImage(depth=field.depth, force=field.force.sum(axis=(1, 2)),
                      pressure=sensel_forces(field, tip) / tip.sensel_area)


def fe3d_image(block: BoxBlock, tip: FingertipSpec, depths, *, h: float = 0.001, growth: float = 1.3,
               half: bool | None = None, depth_growth: float | None = None,
               depth_uniform: float = 0.25) -> tuple[PressImage, SurfaceContact]:
    """The 3-D FE's image of a press of ``tip`` (its sphere and its pad) ``depths`` (m) into the centre of
    ``block``'s top: the pad's x, y are the FE's x, y with the press axis at the origin. Returns the image and
    the nodal field it comes from (the mesh and ``half``: see
    :func:`palpate.sim.reference.fe3d_solve.contact_field`)."""
    field = contact_field(block, tip.radius, depths, h=h, growth=growth, half=half, depth_growth=depth_growth,
                          depth_uniform=depth_uniform)
    return field_image(field, tip), field


def radial_image(depth, force, r, pressure, tip: FingertipSpec, order: int = 16) -> PressImage:
    """The pad's image of an axisymmetric pressure (the axisymmetric FE's ``r`` m, ``pressure`` Pa (n, m), zero
    beyond its last radius) centred on the press axis: each sensel's mean by a tensor Gauss rule of ``order``
    points a side (to check the 3-D image against :mod:`.fe` on a plain block)."""
    points, weights = sensel_quadrature(tip, order)
    radius = np.hypot(points[..., 0], points[..., 1])
    p = np.stack([(np.interp(radius, r, row, right=0.0) * weights).sum(axis=-1) for row in np.asarray(pressure)])
    return PressImage(depth=np.asarray(depth), force=np.asarray(force), pressure=p)
