"""The surface under a press as boundary elements: square cells around the press point, the layer stack under each
cell, their compliance matrix, and which share of each cell lies on each sensel.

Each cell has the stack of layers found along its own vertical line. How two cells' settlements couple depends on
what lies around them (``Surface.mixing``):

- ``uniform``: one stack under every cell: the stack's exact compliance (:mod:`.kernel`);
- ``wall``: two stacks split by a straight line: the soft stack's compliance times the wall table's factor, measured
  on the 3-D FE (:mod:`.wall`), with the contrast of the two stacks' compliances at the contact's scale;
- ``buried``: columns that differ only under a top layer they share (a lump under the surface): each pair of cells
  couples through a geometric blend of the columns' own exact kernels at the pair's distance, weighted by how much
  of each column lies around the two cells (smoothed over BURIED_SMOOTHING) times BURIED_SHARE. The kernels carry
  what a single ratio cannot: near cells couple through the shared top (alike over lump and matrix), far ones
  through the depth where the lump is;
- ``local``: anything else (a curved boundary at the surface, three materials): the press point's stack's
  compliance times a power mean of the two cells' relative compliances, each averaged over a short length
  (a local-compliance model, as in rough-contact solvers with influence matrices; measured, not exact).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import lru_cache

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.world.scene import FingertipSpec, ObjectSpec
from palpate.sim.bem.kernel import Stack, influence
from palpate.sim.bem.wall import WallTable, find_wall, load_wall_table, wall_coupling
from palpate.sim.contact.layered import surface_kernel
from palpate.sim.contact.stack import object_breaks, object_lookup
from palpate.sim.fingertip import sensel_bounds

#: Vertical sampling of each cell's column, m: fine near the surface, where a press feels most.
FINE_STEP, FINE_DEPTH, COARSE_STEP = 0.25e-3, 10e-3, 1e-3
#: How two cells' compliances mix (power mean) and over what length (m) each column's is averaged.
MIX_POWER, MIX_SMOOTHING = -1.0, 1.0e-3
#: Where the columns differ only under a top layer they share (a buried lump): the length (m) over which each
#: column's share around a cell is smoothed, and the share of the buried column's kernel a pair wholly over it
#: takes (below 1: a lump of finite width is softer than a layer of its column everywhere). Both chosen on the FE
#: reference's tuning lumps (docs/results.md).
BURIED_SMOOTHING = 2.0e-3
BURIED_SHARE = 0.8
#: Rows of the compliance matrix built at a time.
ROWS = 32


@dataclass(frozen=True)
class Surface:
    """The cells a press can touch and what lies under them.

    Attributes:
        cell: cell side, m.
        centres: (n, 2) cell centres relative to the press point, m.
        stack_of: (n,) index into ``stacks`` of each cell's column.
        stacks: the distinct column stacks (top first, on the rigid table).
        compliance: (n, n) settlement per unit pressure, m/Pa, single precision (the contact solve's gathers and
            factorisations cost half as much; the wall table and kernels hold fewer digits anyway).
        overlap: (rows * cols, n) share of each sensel's footprint covered by each cell (rows sum to 1 where the
            cells cover the sensel).
        mixing: how the stacks' compliances were combined: "uniform", "wall", "buried" or "local" (module docstring).
        buried: the columns differ only under a top layer they all share (a buried lump, not a wall at the surface):
            the surface's force over a finite buried change is not held (too stiff), so a press takes its force from
            the point's contact law and only the image's shape from the surface
            (:func:`palpate.sim.bem.press.law_scaled`).
    """

    cell: float
    centres: np.ndarray
    stack_of: np.ndarray
    stacks: tuple[Stack, ...]
    compliance: np.ndarray
    overlap: np.ndarray
    mixing: str
    buried: bool = False


def _depth_edges(thickness: float, breaks: list[float]) -> np.ndarray:
    fine = np.arange(0.0, min(FINE_DEPTH, thickness), FINE_STEP)
    coarse = np.arange(min(FINE_DEPTH, thickness), thickness, COARSE_STEP)
    edges = np.unique(np.concatenate([fine, coarse, [thickness], [b for b in breaks if 0 < b < thickness]]))
    # drop slivers a break leaves beside a sampling edge
    keep = np.concatenate([[True], np.diff(edges) > 1e-6])
    return edges[keep]


def column_stacks(obj: ObjectSpec, x: float, y: float, surface_z: float,
                  centres: np.ndarray) -> tuple[np.ndarray, tuple[Stack, ...], np.ndarray]:
    """The layer stack under each cell centre ((n, 2) m from the press point (x, y)): (stack index per cell, the
    distinct stacks, whether the cell lies on the object)."""
    if not obj.inclusions and obj.material_map is None:
        # layers only: every column is the press point's (sampled once)
        _, stacks, _ = _sampled_stacks(obj, x, y, surface_z, np.zeros((1, 2)))
        on_object = obj.contains_xy(centres + np.array([x, y]))
        return np.zeros(len(centres), dtype=int), stacks, on_object
    return _sampled_stacks(obj, x, y, surface_z, centres)


def column_kinds(obj: ObjectSpec, xy: np.ndarray) -> np.ndarray:
    """A label per world point (n, 2) m such that two points with one label have the same column of materials:
    the same footprint membership of every inclusion and the object, and the same map category. A point over a
    sphere gets a label of its own (the sphere's chord under it depends on where it lies)."""
    covers = [obj.contains_xy(xy)]
    unique = np.zeros(len(xy), dtype=bool)
    for inc in obj.inclusions:
        d = xy - np.asarray(inc.center[:2], dtype=float)
        if inc.shape == "sphere":
            inside = np.einsum("ij,ij->i", d, d) <= inc.size[0] ** 2
            unique |= inside
        else:
            inside = np.all(np.abs(d) <= np.asarray(inc.size[:2], dtype=float) / 2.0, axis=1)
        covers.append(inside)
    codes = np.where(unique, np.arange(len(xy)), -1)[:, None]
    if obj.material_map is not None:
        names = obj.material_map.material_names_at(xy)  # type: ignore[attr-defined]
        _, category = np.unique(np.array(["" if n is None else n for n in names]), return_inverse=True)
        codes = np.column_stack([codes, category.reshape(-1)])
    # one byte string per point: sorting those is far cheaper than a row-wise unique over many inclusions
    rows = np.ascontiguousarray(np.concatenate(
        [np.packbits(np.column_stack(covers), axis=1), codes.astype(np.int64).view(np.uint8)], axis=1))
    return np.unique(rows.view(np.dtype((np.void, rows.shape[1]))).ravel(), return_inverse=True)[1].reshape(-1)


def _sampled_stacks(obj: ObjectSpec, x: float, y: float, surface_z: float,
                    centres: np.ndarray) -> tuple[np.ndarray, tuple[Stack, ...], np.ndarray]:
    lookup = object_lookup(obj, x, y, surface_z)
    edges = _depth_edges(surface_z, object_breaks(obj, surface_z))
    mid = 0.5 * (edges[1:] + edges[:-1])
    # each distinct kind of column is sampled once: a staircase of many inclusions costs its kinds, not its cells
    _, rep, kind = np.unique(column_kinds(obj, centres + np.array([x, y])), return_index=True, return_inverse=True)
    n, m = len(rep), len(mid)
    young, poisson, inside = lookup(np.repeat(centres[rep], m, axis=0), np.tile(mid, n))
    young, poisson, inside = young.reshape(n, m), poisson.reshape(n, m), inside.reshape(n, m)
    on_object = inside.all(axis=1)[kind]
    key = np.ascontiguousarray(np.concatenate([young, poisson], axis=1))
    # rows as byte strings: sorting those is far cheaper than np.unique(axis=0)'s lexicographic sort of floats
    _, first, stack_of = np.unique(key.view(np.dtype((np.void, key.shape[1] * key.itemsize))).ravel(),
                                   return_index=True, return_inverse=True)
    stack_of = stack_of.reshape(-1)[kind]
    stacks = []
    for row in first:
        e, nu = young[row], poisson[row]
        change = np.flatnonzero((np.diff(e) != 0) | (np.diff(nu) != 0)) + 1
        starts = np.concatenate([[0], change])
        ends = np.concatenate([change, [m]])
        stacks.append(Stack(tuple(float(edges[b] - edges[a]) for a, b in zip(starts, ends, strict=True)),
                            tuple(float(e[a]) for a in starts), tuple(float(nu[a]) for a in starts)))
    return stack_of.reshape(-1), tuple(stacks), on_object


@lru_cache(maxsize=32)
def _lattice(stack: Stack, cell: float, span: int) -> np.ndarray:
    """Coefficients (per unit top E*) for every lattice offset (i, j) cells, i, j in [-span, span]."""
    k = np.arange(-span, span + 1) * cell
    dx, dy = np.meshgrid(k, k, indexing="ij")
    return influence(stack, cell, dx, dy)


def _kernel_table(stack: Stack, cell: float, span: int) -> np.ndarray:
    """The stack's own compliance (m/Pa) for every lattice offset -2 span..2 span cells, flattened."""
    return _lattice(stack.scaled(), float(cell), 2 * span).ravel() / stack.top_modulus


def sensel_overlap(tip: FingertipSpec, centres: np.ndarray, cell: float) -> np.ndarray:
    """(rows * cols, n) share of each sensel footprint covered by each square cell (centres (n, 2) m, side m)."""
    b = sensel_bounds(tip).reshape(-1, 4)
    h = cell / 2.0
    wx = np.minimum(b[:, 1:2], centres[None, :, 0] + h) - np.maximum(b[:, 0:1], centres[None, :, 0] - h)
    wy = np.minimum(b[:, 3:4], centres[None, :, 1] + h) - np.maximum(b[:, 2:3], centres[None, :, 1] - h)
    area = (b[:, 1] - b[:, 0]) * (b[:, 3] - b[:, 2])
    return np.maximum(wx, 0.0) * np.maximum(wy, 0.0) / area[:, None]


def stack_compliance(stack: Stack, wavenumber: float) -> float:
    """The stack's surface compliance at one wavenumber q (1/m) times q: 2 H(q) / E*_top, 1/Pa."""
    h = surface_kernel(np.array([wavenumber]), np.array(stack.thickness), np.array(stack.young),
                       np.array(stack.poisson))
    return float(2.0 * h[0] / stack.top_modulus)


def power_mean(a: np.ndarray, b: np.ndarray, power: float) -> np.ndarray:
    """((a^p + b^p) / 2)^(1/p) of positive arrays; p = 0 the geometric mean, p = -inf the smaller."""
    if power == 0:
        return np.sqrt(a * b)
    if np.isinf(power):
        return np.minimum(a, b) if power < 0 else np.maximum(a, b)
    return (0.5 * (a**power + b**power)) ** (1.0 / power)


def lattice_ij(centres: np.ndarray, cell: float) -> np.ndarray:
    """(row, column) (n, 2) of cell centres (n, 2) m on the lattice of side ``cell`` m whose cells' corners meet at
    the press point."""
    return np.rint(centres / cell - 0.5).astype(int)


def _lattice_index(centres: np.ndarray, cell: float, span: int) -> np.ndarray:
    """Flat lattice index (row times (4 span + 1) plus column) of cell centres (n, 2) m, as :func:`_compliance`
    reads them."""
    ij = lattice_ij(centres, cell)
    return ij[:, 0] * (4 * span + 1) + ij[:, 1]


def _compliance(stack: Stack, cell: float, span: int, flat_ij: np.ndarray, factor=None) -> np.ndarray:
    """(n, n) m/Pa: the stack's own compliance between the cells at flat lattice indices ``flat_ij`` (n,) (row
    times (4 span + 1) plus column), each row block times ``factor(rows, pair)`` when given (pair: each pair's
    flat index into the lattice of offsets -2 span..2 span squared). A block of rows at a time, so that no
    temporary is (n, n): those would cost fresh pages and cache misses on every press."""
    width = 4 * span + 1
    table = _kernel_table(stack, cell, span)
    n = len(flat_ij)
    out = np.empty((n, n), dtype=np.float32)
    for start in range(0, n, ROWS):
        rows = slice(start, min(start + ROWS, n))
        pair = flat_ij[rows, None] - flat_ij[None, :]
        pair += 2 * span * (width + 1)
        block = table.take(pair)
        if factor is not None:
            block *= factor(rows, pair)
        out[rows] = block
    return out


def _buried_factor(stacks, used, ref: int, stack_of: np.ndarray, on_object: np.ndarray, keep: np.ndarray,
                   shape: tuple[int, int], cell: float, span: int):
    """``factor(rows, pair)`` of a buried change (module docstring): exp of the sum over the other columns s of
    BURIED_SHARE x the pair's mean smoothed share of s x log(kernel_s / kernel_ref) at the pair's offset."""
    from scipy.ndimage import gaussian_filter

    ref_table = _kernel_table(stacks[ref], cell, span)
    terms = []
    for s in used:
        if s == ref:
            continue
        table = _kernel_table(stacks[s], cell, span)
        share = gaussian_filter(np.where(on_object & (stack_of == s), 1.0, 0.0).reshape(shape), BURIED_SMOOTHING / cell,
                                mode="constant").ravel()[keep]
        # a stiff top over a soft layer bends like a plate on a foundation: its kernel changes sign far out, where
        # a blend of logs means nothing; there the reference column's kernel stands (log ratio 0)
        ratio = np.divide(table, ref_table, out=np.ones_like(table), where=(table > 0) & (ref_table > 0))
        terms.append(((0.5 * BURIED_SHARE * share).astype(np.float32), np.log(ratio).astype(np.float32)))

    def factor(rows: slice, pair: np.ndarray) -> np.ndarray:
        out = np.zeros(pair.shape, dtype=np.float32)
        for half_share, log_ratio in terms:
            out += (half_share[rows, None] + half_share[None, :]) * log_ratio.take(pair)
        return np.exp(out, out=out)

    return factor


def build_surface(obj: ObjectSpec, x: float, y: float, surface_z: float, tip: FingertipSpec, reach: float,
                  cell: float, contact_radius: float, walls: WallTable | None = None) -> Surface:
    """The cells within ``reach`` (m) of the press point (x, y) on the object's top at ``surface_z`` (m), their
    stacks and compliance, and their overlap with the pad's sensels (see the module docstring).

    ``contact_radius`` (m) is the scale at which two columns' compliances are compared; ``walls`` the wall table
    (read from models/ when a wall is met and none is given).

    Raises:
        ValidationError: no material under the press point, or a wall outside the wall table.
    """
    if not (cell > 0 and reach > cell):
        raise ValidationError(f"bem: need a cell (m) smaller than the reach (m), got {cell!r}, {reach!r}")
    span = int(math.ceil(reach / cell))
    margin = int(math.ceil(3.0 * MIX_SMOOTHING / cell))
    k = (np.arange(-span - margin, span + margin) + 0.5) * cell
    gx, gy = np.meshgrid(k, k, indexing="ij")
    lattice = np.column_stack([gx.ravel(), gy.ravel()])
    stack_of, stacks, on_object = column_stacks(obj, x, y, surface_z, lattice)
    centre = int(np.argmin(np.hypot(lattice[:, 0], lattice[:, 1])))
    if not on_object[centre]:
        raise ValidationError("bem: no material under the press point")
    q = 1.0 / contact_radius
    compliance_at = np.array([stack_compliance(st, q) for st in stacks])
    keep = on_object & (np.hypot(lattice[:, 0], lattice[:, 1]) <= reach)
    # off the object nothing can be pressed (the compliance beside a free edge is not modelled: `auto` keeps
    # this rung away from edges within reach)
    centres, own = lattice[keep], stack_of[keep]
    used, own = np.unique(own, return_inverse=True)
    flat_ij = _lattice_index(centres, cell, span)
    mixing = "uniform"
    base, factor = stacks[used[0]], None
    top = {(stacks[i].young[0], stacks[i].poisson[0]) for i in used}
    buried = len(used) > 1 and len(top) == 1
    if buried:
        mixing = "buried"
        ref = stack_of[centre]
        base = stacks[ref]
        factor = _buried_factor(stacks, used, ref, stack_of, on_object, keep, gx.shape, cell, span)
    elif len(used) > 1:
        wall = None
        if len(used) == 2:
            soft, stiff = sorted(used, key=lambda s: -compliance_at[s])

            def is_stiff(points: np.ndarray) -> np.ndarray:
                idx, found, inside = column_stacks(obj, x, y, surface_z, points)
                return inside & np.array([f == stacks[stiff] for f in found])[idx]

            wall = find_wall(is_stiff, centres, used[own] == stiff, reach, cell)
        if wall is not None:
            mixing = "wall"
            walls = load_wall_table() if walls is None else walls
            # a cell the wall cuts keeps the side of its own column: a located wall a hair off (the staircase of
            # a rotated wall) would otherwise put cells on the line on either side at random (45 deg: x and y
            # asymmetries 0.25 | 0.41 against the FE's 0.35 | 0.35)
            u = wall.distance(centres)
            u = np.where(used[own] == stiff, np.abs(u), -np.abs(u))
            tangent = np.array([-wall.normal[1], wall.normal[0]])
            steps = np.arange(-2 * span, 2 * span + 1) * cell
            along = np.abs(steps[:, None] * tangent[0] + steps[None, :] * tangent[1]).ravel()
            nu = 0.5 * (stacks[soft].poisson[0] + stacks[stiff].poisson[0])
            contrast = compliance_at[soft] / compliance_at[stiff]
            base = stacks[soft]
            coupling = wall_coupling(walls, nu, contrast, u, along)

            def factor(rows: slice, pair: np.ndarray) -> np.ndarray:
                share = coupling.share(pair, rows)
                share -= 1.0
                share *= math.log(contrast)
                return np.exp(share, out=share)
        else:
            mixing = "local"
            ref = stack_of[centre]
            field = np.where(on_object, compliance_at[stack_of] / compliance_at[ref], 0.0).reshape(gx.shape)
            from scipy.ndimage import gaussian_filter

            sigma = MIX_SMOOTHING / cell
            weight = gaussian_filter(on_object.reshape(gx.shape).astype(float), sigma, mode="constant")
            field = gaussian_filter(field, sigma, mode="constant") / np.maximum(weight, 1e-12)
            field = field.ravel()[keep]
            base = stacks[ref]

            def factor(rows: slice, pair: np.ndarray) -> np.ndarray:
                return power_mean(field[rows, None], field[None, :], MIX_POWER)
    compliance = _compliance(base, cell, span, flat_ij, factor)
    return Surface(cell=float(cell), centres=centres, stack_of=own, stacks=tuple(stacks[i] for i in used),
                   compliance=compliance, overlap=sensel_overlap(tip, centres, cell), mixing=mixing, buried=buried)


def uniform_surface(surface: Surface, stack: Stack, reach: float) -> Surface:
    """``surface``'s cells over ``stack`` everywhere (the one it was built with ``reach``, m): the like-against-like
    reference of a surface with several stacks (a ratio of the two solves cancels the cells' own error)."""
    span = int(math.ceil(reach / surface.cell))
    flat_ij = _lattice_index(surface.centres, surface.cell, span)
    return replace(surface, stack_of=np.zeros(len(flat_ij), dtype=int), stacks=(stack,),
                   compliance=_compliance(stack, surface.cell, span, flat_ij), mixing="uniform", buried=False)
