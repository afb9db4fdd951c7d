"""The `flex` fidelity's window: which part of the object is meshed, and where its nodes stand.

- A box (or a cylinder too wide for the window): at most ``window`` wide around the press point (snapped to a 1 mm
  grid so nearby presses share a model), the object's full height, cells of about ``resolution``; where the window
  cuts through the object its sides are pinned; free object faces within it stay free.
- Over a stiff layer (a plate, which spreads its load far wider than a block), the box's window is
  PLATE_WINDOW_SCALE times as wide, fine at the press and coarser out, with the free calibration table (times the
  plate's q under a stiff top layer, :mod:`palpate.sim.flex.plate`): the
  default window's pinned sides stiffened stiff skins by +25 to +40% at 4 mm.
- A cylinder whose disc fits the window (radius up to window / sqrt(2)): the whole disc, a tensor grid mapped onto
  it (:func:`disc_map`), so its curved side is free where it really is. A square inscribed in the disc with
  pinned sides instead clamps the side and, on a disc narrower than the tip's contact, lets the contact run off
  the mesh (the press diverged on edge_6mm and edge_10mm).
- Node planes on stiff layers: the bottom of each layer stiffer than what lies under it is a node plane (the
  nearest node moved onto it within SNAP_PLANE cells, else a plane inserted), a layer thinner than a cell gets
  LAYER_CELLS cells through it, and its cells are marked ``bending``: a stiff skin carries load by bending, which
  a cell mixing it with its base cannot, and which a thin trilinear cell cannot either without the incompatible
  modes :func:`palpate.sim.flex.element.bending_ee` gives it. Other cells holding two materials (a soft skin, a
  lump) get their mix (:func:`palpate.sim.flex.mixing.cell_moduli`), which the press corrects by the continuum's
  answer to it (:mod:`palpate.sim.flex.mixing`). Node planes on a lump's top, bottom and sides
  were tried and dropped: on lump_hard_3mm and lump_soft_3mm they left as many rows beyond 10% (one) for two more
  layers of cells.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.world.scene import ObjectSpec
from palpate.sim.flex.element import UNIT_CORNERS

#: Default cell edge of the elastic grid (under the press, if graded), m.
DEFAULT_RESOLUTION = 0.005
#: Ratio of neighbouring cell edges beyond the fine region of a graded grid (flex_grid(core=...)).
GROWTH = 1.5
#: Default lateral size of the simulated window around the press point, m.
DEFAULT_WINDOW = 0.03
#: Press points are snapped to this grid to choose the window, m (nearby presses share a model).
SNAP = 0.001
#: Fewest cells through the thickness (a thin block bends and squeezes over its thickness, not over a cell).
MIN_LAYERS = 2
#: An interface within this many cells of a node moves that node onto it (no sliver cell); farther, a plane is added.
SNAP_PLANE = 0.25
#: Cells through a stiff layer thinner than a cell.
LAYER_CELLS = 2
#: A window over a stiff layer (a plate) is this many default windows wide, graded laterally: cells of the
#: resolution within PLATE_CORE_CELLS cells of the press, then growing by PLATE_GROWTH per cell out to its sides.
#: A plate spreads its load far wider than a block, so the default window's pinned sides stiffen it (+30% on
#: skin_stiff_2mm at 4 mm). 60 mm (one 20 mm cell each side of the fine core, 6 x 6 cells) since the plate table
#: is measured on this window with the base's Poisson ratio as an axis: half the cost of the 90 mm window (8 x 8)
#: at the same error; a graded base or outer cells of 25 mm or more diverged on thin calibration plates
#: (docs/results.md).
PLATE_WINDOW_SCALE = 2.0
PLATE_CORE_CELLS = 2
PLATE_GROWTH = 2.0


@dataclass(frozen=True)
class FlexGrid:
    """The simulated window of the object: a tensor grid of nodes, fine at the press point and coarser away.

    Attributes:
        x, y, z: node coordinates along each axis, m, world frame, increasing (z from the table, 0, to the top).
            With ``disc_radius`` > 0, x and y span the square [centre - r, centre + r] that is mapped onto the disc.
        pinned: which side faces are pinned, order (x-, x+, y-, y+) (the bottom is always pinned).
        disc_radius: radius of the disc the x-y square is mapped onto (a cylinder's whole disc), m; 0: no mapping.
        bending: (nz,) which layers of cells lie in a stiff layer thinner than a cell (their cells must bend).
        far_sides: the pinned sides are as far from the press as in the "free" calibration table's window or
            farther (a plate's wide window), so the mesh correction is that table's.
    """

    x: np.ndarray
    y: np.ndarray
    z: np.ndarray
    pinned: tuple[bool, bool, bool, bool]
    disc_radius: float = 0.0
    bending: np.ndarray | None = None
    far_sides: bool = False

    def bending_cells(self) -> np.ndarray:
        """(n,) which cells (MuJoCo's order) lie in a stiff layer thinner than a cell."""
        layers = np.zeros(self.cells[2], dtype=bool) if self.bending is None else np.asarray(self.bending, dtype=bool)
        return np.tile(layers, self.cells[0] * self.cells[1])

    @property
    def lower(self) -> np.ndarray:
        """(x, y, z) lower corner of the (unmapped) grid, m."""
        return np.array([self.x[0], self.y[0], self.z[0]])

    @property
    def size(self) -> np.ndarray:
        """(sx, sy, sz) extents of the (unmapped) grid, m."""
        return np.array([self.x[-1] - self.x[0], self.y[-1] - self.y[0], self.z[-1] - self.z[0]])

    @property
    def cells(self) -> tuple[int, int, int]:
        """(nx, ny, nz) trilinear cells per axis."""
        return (len(self.x) - 1, len(self.y) - 1, len(self.z) - 1)

    @property
    def finest(self) -> float:
        """The smallest lateral cell edge (the cells under the press; a disc's centre cells), m."""
        return float(min(np.diff(self.x).min(), np.diff(self.y).min()))

    def nodes(self) -> np.ndarray:
        """(N, 3) node positions in MuJoCo's node order (k fastest, i slowest), m (mapped onto the disc, if any)."""
        i, j, k = np.meshgrid(self.x, self.y, self.z, indexing="ij")
        pts = np.stack([i.ravel(), j.ravel(), k.ravel()], axis=1)
        if self.disc_radius > 0:
            centre = (self.lower[:2] + self.size[:2] / 2.0)
            pts[:, :2] = centre + self.disc_radius * disc_map((pts[:, :2] - centre) / self.disc_radius)
        return pts

    def cell_corners(self) -> np.ndarray:
        """(n, 8, 3) corners of each cell, cells in MuJoCo's order (z fastest, then y, then x), corners in its node
        order, m."""
        nx, ny, nz = self.cells
        nodes = self.nodes().reshape(nx + 1, ny + 1, nz + 1, 3)
        i, j, k = np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij")
        off = UNIT_CORNERS.astype(int)
        return nodes[i.ravel()[:, None] + off[:, 0], j.ravel()[:, None] + off[:, 1], k.ravel()[:, None] + off[:, 2]]

    def cell_centres(self) -> np.ndarray:
        """(n, 3) cell centres (the mean of the corners) in MuJoCo's cell order, m."""
        return self.cell_corners().mean(axis=1)

    def pinned_nodes(self) -> np.ndarray:
        """Indices of the pinned grid nodes (MuJoCo's node order: k fastest, i slowest)."""
        nx, ny, nz = (c + 1 for c in self.cells)
        i, j, k = np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij")
        pin = k == 0
        for flag, face in zip(self.pinned, (i == 0, i == nx - 1, j == 0, j == ny - 1), strict=True):
            if flag:
                pin |= face
        return np.nonzero(pin.ravel())[0]

    def key(self) -> tuple:
        """A hashable identity (for model caches)."""
        return (tuple(tuple(np.round(a, 9)) for a in (self.x, self.y, self.z))
                + (self.pinned, self.disc_radius, tuple(self.bending_cells()[: self.cells[2]]), self.far_sides))


def disc_map(uv: np.ndarray) -> np.ndarray:
    """The concentric map of the square [-1, 1]^2 onto the unit disc, (n, 2) -> (n, 2): each square ring of nodes
    onto the circle of its half-width (the axes' nodes stay where they are), so the rings of cells are annuli.
    Chosen over the elliptical map (smooth, the identity at the centre) on edge_10mm: within 10% of the reference
    where the elliptical one was 12-14% soft at 2-3 mm."""
    ring = np.max(np.abs(uv), axis=1)
    norm = np.linalg.norm(uv, axis=1)
    return uv * np.where(norm > 0, ring / np.where(norm > 0, norm, 1.0), 0.0)[:, None]


def graded_nodes(lo: float, hi: float, focus: float, fine: float, core: float, growth: float) -> np.ndarray:
    """Node coordinates on [lo, hi] (m): steps of ``fine`` within ``core`` of ``focus`` (a node), then steps growing
    by ``growth`` each to the ends (the last ones stretched or shrunk so the ends are nodes). ``focus`` may be an
    end (a one-sided grading, e.g. down from the top)."""
    out = [np.array([focus])]
    for side, length in ((-1.0, focus - lo), (1.0, hi - focus)):
        if length <= 1e-12:
            continue
        n_core = int(max(1, round(min(core, length) / fine)))
        steps = [min(core, length) / n_core] * n_core
        rest = length - sum(steps)
        if rest > 1e-12:
            grown, h = [], steps[-1]
            while sum(grown) < rest:
                h *= growth
                grown.append(h)
            if len(grown) > 1 and sum(grown) - rest > 0.5 * grown[-1]:
                grown.pop()  # the last step would be mostly overshoot: stretch the others instead
            steps += list(np.asarray(grown) * rest / sum(grown))
        out.append(focus + side * np.cumsum(steps))
    nodes = np.sort(np.concatenate(out))
    nodes[0], nodes[-1] = lo, hi
    return nodes


def with_planes(nodes: np.ndarray, planes, snap: float) -> np.ndarray:
    """``nodes`` (m, increasing) with a node on each of ``planes`` strictly inside them: the nearest node moved
    onto a plane within ``snap`` m of it (unless it is an end or already on another plane), else the plane
    inserted."""
    out = np.array(nodes, dtype=float)
    held = {round(float(out[0]), 9), round(float(out[-1]), 9)}
    for p in sorted({round(float(v), 9) for v in planes}):
        if not out[0] < p < out[-1]:
            continue
        i = int(np.argmin(np.abs(out - p)))
        if abs(out[i] - p) < 1e-9:
            held.add(p)
            continue
        if abs(out[i] - p) <= snap and round(float(out[i]), 9) not in held:
            out[i] = p
        else:
            out = np.sort(np.append(out, p))
        held.add(p)
    return out


def _split_thin(nodes: np.ndarray, bands, cell: float, per_band: int) -> np.ndarray:
    """``nodes`` with ``per_band`` cells through each (bottom, top) band thinner than ``cell`` whose ends are nodes."""
    out = list(nodes)
    for lo, hi in bands:
        if hi - lo < cell and np.any(np.isclose(nodes, lo)) and np.any(np.isclose(nodes, hi)):
            out += list(np.linspace(lo, hi, per_band + 1)[1:-1])
    return np.sort(np.array(out))


def _thin_layers(nodes: np.ndarray, bands, cell: float) -> np.ndarray:
    """(len(nodes) - 1,) which node intervals lie inside a (bottom, top) band thinner than ``cell`` (m)."""
    mid = (nodes[1:] + nodes[:-1]) / 2.0
    out = np.zeros(len(mid), dtype=bool)
    for lo, hi in bands:
        if hi - lo < cell:
            out |= (mid > lo) & (mid < hi)
    return out


def _stiff_layers(obj: ObjectSpec) -> list[tuple[float, float]]:
    """(bottom, top), m, of each layer of ``obj`` stiffer than what lies under it: a stiff skin bends, which needs
    cells of its own, while a soft one is squeezed, which the series mix of a cell holding it and its base gives
    exactly (a soft skin's own thin cells, under a tip wider than them, measured softer than the continuum on the
    validity table's soft skins: -25% at 1 and 4 mm on skin_soft_2mm, against -5% and -13% mixed)."""
    out = []
    top = obj.height
    below = ([layer.material for layer in obj.layers] + [obj.material])[1:]
    for layer, under in zip(obj.layers, below, strict=True):
        if layer.material.young > under.young:
            out.append((top - layer.thickness, top))
        top -= layer.thickness
    return out


def flex_grid(obj: ObjectSpec, x: float, y: float, resolution: float = DEFAULT_RESOLUTION,
              window: float = DEFAULT_WINDOW, core: float | None = None, growth: float = GROWTH,
              plate: bool = True) -> FlexGrid:
    """The window of ``obj`` for a press at (x, y) (m, snapped to SNAP; see the module docstring), meshed with
    cells of ``resolution`` m within ``core`` m of the press (laterally and down from the top) growing by ``growth``
    per cell beyond (a node column stands under the press). ``core`` None (the default): a uniform grid, except
    over a stiff layer with ``plate`` (a box, or a cylinder wider than the window): laterally PLATE_WINDOW_SCALE
    times ``window`` wide, graded by PLATE_CORE_CELLS and PLATE_GROWTH, its mesh correction the free table's.

    A graded grid resolves the contact better for its node count, but the discrete integrator solves M + K
    iteratively each step and its cost grows with the node count and the grading's ill-conditioning: 1.5 mm cells
    graded to the 30 mm window (14 x 14 x 10 cells) run several times slower than the uniform 5 mm default, which
    is why the default stays uniform."""
    uniform = core is None
    core = max(window, obj.height, resolution) if core is None else core
    for name, v in (("resolution", resolution), ("window", window), ("core", core)):
        if not (np.isfinite(v) and v > 0):
            raise ValidationError(f"flex: {name} must be a length > 0 m, got {v!r}")
    if not (np.isfinite(growth) and growth >= 1.0):
        raise ValidationError(f"flex: growth must be a cell-to-cell ratio >= 1, got {growth!r}")
    if obj.shape not in ("box", "cylinder"):
        raise ValidationError(f"object {obj.name!r}: the flex fidelity supports shapes 'box' and 'cylinder', "
                              f"not {obj.shape!r}; use fidelity 'rigid' or 'analytic' for meshes")
    bands = _stiff_layers(obj)
    zs = with_planes(graded_nodes(0.0, obj.height, obj.height, resolution, core, growth),
                     [bottom for bottom, _ in bands], SNAP_PLANE * resolution)
    zs = _split_thin(zs, bands, resolution, LAYER_CELLS)
    if len(zs) - 1 < MIN_LAYERS:
        zs = np.linspace(0.0, obj.height, MIN_LAYERS + 1)
    bending = _thin_layers(zs, bands, resolution)
    cx, cy = obj.position
    if obj.shape == "cylinder" and obj.size[0] <= window / np.sqrt(2.0):
        r = float(obj.size[0])
        n = 2 * int(np.ceil(r / resolution - 1e-9))
        return FlexGrid(x=np.linspace(cx - r, cx + r, n + 1), y=np.linspace(cy - r, cy + r, n + 1), z=zs,
                        pinned=(False, False, False, False), disc_radius=r, bending=bending)
    lateral_core, lateral_growth, far = core, growth, False
    if plate and bands and uniform:
        window, lateral_core, lateral_growth = PLATE_WINDOW_SCALE * window, PLATE_CORE_CELLS * resolution, PLATE_GROWTH
        far = True
    if obj.shape == "box":
        half = np.array(obj.size[:2], dtype=float) / 2.0
        edges_free = True
    else:  # a cylinder wider than the window: the square inscribed in it, cut by the window
        half = np.full(2, obj.size[0] / np.sqrt(2.0))
        edges_free = False
    lo_obj = np.array([cx, cy]) - half
    hi_obj = np.array([cx, cy]) + half
    w = np.minimum(window / 2.0, half)
    snapped = np.round(np.array([x, y], dtype=float) / SNAP) * SNAP
    centre = np.clip(snapped, lo_obj + w, hi_obj - w)
    lo, hi = centre - w, centre + w
    focus = np.clip(snapped, lo, hi)
    eps = 1e-9
    pinned = (
        bool(lo[0] > lo_obj[0] + eps or not edges_free), bool(hi[0] < hi_obj[0] - eps or not edges_free),
        bool(lo[1] > lo_obj[1] + eps or not edges_free), bool(hi[1] < hi_obj[1] - eps or not edges_free),
    )
    xs, ys = (graded_nodes(lo[a], hi[a], focus[a], resolution, lateral_core, lateral_growth) for a in range(2))
    return FlexGrid(x=xs, y=ys, z=zs, pinned=pinned, bending=bending, far_sides=far)
