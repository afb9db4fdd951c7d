"""The surface compliance beside a straight wall between two materials, measured once on the 3-D FE and tabulated.

A local-compliance rule (each pair of cells mixing their two materials' compliances) cannot hold a wall: the FE
shows the stiff side near the wall softened, the soft side stiffened, and pairs of cells on one side coupled more
or less strongly the farther apart they are, through the other material. So the FE's own surface compliance beside
a wall is the model. Written as the share lambda of the soft material in the coupling of two surface points,

    C_wall(i, j) = C_soft(i, j) * c^(lambda(u_i, u_j, v) - 1),

with c the stiff over the soft side's modulus, u each point's signed distance from the wall (+ on the stiff side),
v their distance along it and C_soft the soft material's own compliance (lambda = 1: soft, 0: stiff). lambda is the
ratio of the FE's nodal compliances with and without the wall on one mesh (so its discretisation cancels), over
u, u' in +-9 mm and v in 0..9 mm, per Poisson ratio and contrast, on a 30 mm block
(:mod:`.wall_measure`, models/bem_wall_table.json); between the tabulated values it is interpolated linearly (in
log contrast), and points within NEAR_WALL node spacings of the wall take the value there on their own side:
nearer, the table's steep, uneven values make C_wall indefinite for some walls. The clamp is the smallest, in
quarter spacings, that leaves every surface of a sweep positive definite (walls -3..+3 mm from the press point
every 0.25 mm and -1.5..+1.5 mm every 0.05 mm, contrasts 2-22.5x, nu 0.3-0.49, 1-4 mm deep, and rotated walls:
at 1.0 spacing 312 of 1800 surfaces are indefinite, at 1.1 120, from 1.2 none); tests/test_bem.py keeps a sweep
of them positive definite. Clamping farther (1.5) loads the stiff side's strip next to the wall too much: a
sensel that the wall crosses reads high.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.files import decimal_array, pack_decimals, per_file_version
from palpate.core.world.resources import models_dir
from palpate.sim.validity.reference import read_document

TABLE_PATH = models_dir() / "bem_wall_table.json"
FORMAT = "palpate-bem-wall"
VERSION = 1
#: Most numbers a wall table's lambda may hold (the shipped one holds 234 099).
MAX_SHARE = 4_000_000
#: Points nearer the wall than this many node spacings take the value there, on their own side.
NEAR_WALL = 1.25


@dataclass(frozen=True)
class WallTable:
    """lambda on a grid (see the module docstring).

    Attributes:
        offsets: signed distances from the wall, m, (U,) increasing, symmetric about 0 with a node on the wall.
        along: distances along the wall, m, (V,) from 0.
        poisson: (P,) increasing; contrast: (Q,) stiff over soft modulus, increasing, > 1.
        share: lambda, (P, Q, U, U, V), symmetric in its two offset axes.
        thickness: the FE block's thickness, m.
    """

    offsets: np.ndarray
    along: np.ndarray
    poisson: np.ndarray
    contrast: np.ndarray
    share: np.ndarray
    thickness: float

    def __post_init__(self) -> None:
        shape = (len(self.poisson), len(self.contrast), len(self.offsets), len(self.offsets), len(self.along))
        if self.share.shape != shape or not np.all(np.isfinite(self.share)):
            raise ValidationError(f"WallTable: share must be finite with shape {shape}, got {self.share.shape}")
        for name in ("offsets", "along", "poisson", "contrast"):
            a = getattr(self, name)
            if a.ndim != 1 or len(a) < 1 or np.any(np.diff(a) <= 0):
                raise ValidationError(f"WallTable: {name} must increase strictly")
        if np.any(self.contrast <= 1) or len(self.offsets) < 3:
            raise ValidationError("WallTable: contrasts must exceed 1 and offsets span the wall")

    @property
    def spacing(self) -> float:
        """The node spacing of the offsets, m."""
        return float(self.offsets[1] - self.offsets[0])

    def to_dict(self, measured_with: dict) -> dict:
        """The JSON document (lambda rounded to 1e-4)."""
        return {"format": FORMAT, "version": VERSION, "measured_with": measured_with,
                "thickness": self.thickness, "offsets": self.offsets.tolist(), "along": self.along.tolist(),
                "poisson": self.poisson.tolist(), "contrast": self.contrast.tolist(),
                "share": pack_decimals(self.share, 4)}


def load_wall_table(path: Path = TABLE_PATH) -> WallTable:
    """Read and check the wall table (models/bem_wall_table.json by default). Read once per file version
    (:func:`palpate.core.files.per_file_version`); its arrays are read-only."""
    return _wall_tables(path)


def _read_wall_table(path: Path) -> WallTable:
    doc = read_document(path, "the bem wall table", FORMAT, VERSION, "run benchmarks/bem_wall_table.py --write")
    try:
        table = WallTable(offsets=np.asarray(doc["offsets"], dtype=float), along=np.asarray(doc["along"], dtype=float),
                          poisson=np.asarray(doc["poisson"], dtype=float),
                          contrast=np.asarray(doc["contrast"], dtype=float),
                          share=decimal_array(doc["share"], f"{path}: share", 5, MAX_SHARE),
                          thickness=float(doc["thickness"]))
    except (KeyError, TypeError, ValueError) as exc:
        raise ValidationError(f"{path}: not a wall table ({exc})") from None
    for name in ("offsets", "along", "poisson", "contrast", "share"):
        getattr(table, name).setflags(write=False)  # one table serves every caller
    return table


_wall_tables = per_file_version(_read_wall_table)


def _bracket(grid: np.ndarray, value: float) -> tuple[int, int, float]:
    """Indices and weight of ``value`` between two nodes of ``grid`` (clamped to its ends)."""
    if len(grid) == 1 or value <= grid[0]:
        return 0, 0, 0.0
    if value >= grid[-1]:
        return len(grid) - 1, len(grid) - 1, 0.0
    k = int(np.searchsorted(grid, value)) - 1
    return k, k + 1, float((value - grid[k]) / (grid[k + 1] - grid[k]))


def _locate(grid: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Lower node index and weight of each x on ``grid`` (clamped to its ends)."""
    x = np.clip(x, grid[0], grid[-1])
    k = np.clip(np.searchsorted(grid, x) - 1, 0, len(grid) - 2)
    return k, (x - grid[k]) / (grid[k + 1] - grid[k])


@dataclass(frozen=True)
class WallCoupling:
    """lambda between the points of one surface beside one wall, ready to be read a block of pairs at a time
    (made by :func:`wall_coupling`; single precision, as the table holds 4 digits).

    Attributes:
        first: (k * U * V,) the table interpolated at each of the k distinct offsets of the points.
        row: (n,) each point's distinct offset times U * V (where its slab of ``first`` starts).
        column: (n,) each point's offset node times V (the second offset's lower node, flattened).
        weight: (n,) each point's weight towards its next offset node.
        along_node: (m,) lower along-node of each distinct distance along the wall.
        along_weight: (m,) its weight towards the next node.
        nodes: (U, V), the table's offset and along node counts.
    """

    first: np.ndarray
    row: np.ndarray
    column: np.ndarray
    weight: np.ndarray
    along_node: np.ndarray
    along_weight: np.ndarray
    nodes: tuple[int, int]

    def share(self, pair: np.ndarray, rows: slice = slice(None)) -> np.ndarray:
        """lambda (k, n) for the points ``rows`` (k of them) against every point, ``pair`` (k, n) indexing each
        pair's distance along the wall."""
        n_u, n_v = self.nodes
        base = self.along_node.take(pair)
        base += self.column[None, :]
        base += self.row[rows, None]
        weight = self.along_weight.take(pair)
        low = self.first.take(base)
        step = self.first.take(base + 1)
        step -= low
        step *= weight
        low += step
        base += n_v
        high = self.first.take(base)
        step = self.first.take(base + 1)
        step -= high
        step *= weight
        high += step
        high -= low
        high *= self.weight[None, :]
        low += high
        return low


def wall_coupling(table: WallTable, poisson: float, contrast: float, u: np.ndarray,
                  along: np.ndarray) -> WallCoupling:
    """lambda between points at signed distances ``u`` (n,) from the wall (m, + stiff side) and the distinct
    distances ``along`` (m,) between them along it (m): the table interpolated linearly in Poisson ratio, log
    contrast and the three distances (clamped to the table).

    Raises:
        ValidationError: a contrast below 1 or a Poisson ratio outside the table.
    """
    if not contrast >= 1.0:
        raise ValidationError(f"wall_coupling: the contrast is stiff over soft, >= 1; got {contrast!r}")
    if not table.poisson[0] - 1e-9 <= poisson <= table.poisson[-1] + 1e-9:
        raise ValidationError(f"bem: a wall at Poisson ratio {poisson:g} is outside the wall table's "
                              f"{table.poisson[0]:g}-{table.poisson[-1]:g}")
    p0, p1, wp = _bracket(table.poisson, poisson)
    c0, c1, wc = _bracket(np.log(table.contrast), math.log(max(contrast, 1.0)))
    cube = sum(w1 * w2 * table.share[p, c] for p, w1 in ((p0, 1 - wp), (p1, wp))
               for c, w2 in ((c0, 1 - wc), (c1, wc)) if w1 * w2 > 0)
    # a point nearer the wall than NEAR_WALL node spacings takes the value there, on its own side
    near = NEAR_WALL * table.spacing
    u = np.where(u > 0, np.maximum(u, near), np.minimum(u, -near))
    # points on a lattice beside a straight wall share few offsets: interpolate the table once per offset
    distinct, slab = np.unique(u, return_inverse=True)
    slab = slab.reshape(-1)
    j0, b = _locate(table.offsets, distinct)
    cube = cube.astype(np.float32)
    first = (1 - b)[:, None, None].astype(np.float32) * cube[j0] + b[:, None, None].astype(np.float32) * cube[j0 + 1]
    n_u, n_v = cube.shape[1], cube.shape[2]
    k0, c = _locate(table.along, np.asarray(along, dtype=float).ravel())
    return WallCoupling(first=first.reshape(-1), row=(slab * (n_u * n_v)).astype(np.int32),
                        column=(j0 * n_v).astype(np.int32)[slab], weight=b.astype(np.float32)[slab],
                        along_node=np.minimum(k0, n_v - 2).astype(np.int32), along_weight=c.astype(np.float32),
                        nodes=(n_u, n_v))


@dataclass(frozen=True)
class Wall:
    """A straight boundary between two materials near a press point.

    Attributes:
        normal: unit (2,) from the soft side to the stiff side.
        offset: signed distance of the wall from the press point along ``normal``, m.
    """

    normal: np.ndarray
    offset: float

    def distance(self, points: np.ndarray) -> np.ndarray:
        """Signed distance of points (n, 2) (m, relative to the press point) from the wall, + on the stiff side."""
        return points @ self.normal - self.offset


def _crossings(is_stiff, starts: np.ndarray, direction: np.ndarray, length: float, tol: float,
               samples: int = 65) -> np.ndarray | None:
    """Where along each line starts[k] + t direction, t in [-length, length], ``is_stiff`` turns true, to ``tol``
    m; None if on any line it does not change exactly once. Every line is sampled in one call per level, each level
    ``samples - 1`` times finer than the last (two levels for a few-millimetre reach), so the material lookup runs
    a handful of times rather than once per bisection step."""
    n_lines = len(starts)
    lo = np.full(n_lines, -length)
    hi = np.full(n_lines, length)
    first = True
    while True:
        t = lo[:, None] + (hi - lo)[:, None] * np.linspace(0.0, 1.0, samples)[None, :]
        points = starts[:, None, :] + t[:, :, None] * direction[None, None, :]
        side = np.asarray(is_stiff(points.reshape(-1, 2)), dtype=bool).reshape(n_lines, samples)
        change = side[:, 1:] != side[:, :-1]
        if first and (np.any(change.sum(axis=1) != 1) or side[:, 0].any() or not side[:, -1].all()):
            return None
        first = False
        k = np.argmax(change, axis=1)
        rows = np.arange(n_lines)
        lo, hi = t[rows, k], t[rows, k + 1]
        if np.all(hi - lo <= tol):
            return 0.5 * (lo + hi)


def find_wall(is_stiff, centres: np.ndarray, stiff: np.ndarray, reach: float, cell: float,
              tol: float = 1e-5) -> Wall | None:
    """The straight wall that splits the square cells (centres (n, 2) m, side ``cell`` m) into their ``stiff``
    (bool) and other ones, located to ``tol`` m by ever finer sampling of ``is_stiff(points (k, 2)) -> bool (k,)``;
    None where no straight line does (a curved or broken boundary, or more than one)."""
    if stiff.all() or not stiff.any():
        return None
    design = np.column_stack([np.ones(len(centres)), centres])
    coef, *_ = np.linalg.lstsq(design, stiff.astype(float), rcond=None)
    if not np.hypot(*coef[1:]) > 0:
        return None
    normal = coef[1:] / np.hypot(*coef[1:])
    tangent = np.array([-normal[1], normal[0]])
    # two crossings half a reach either side of the press point give the wall's direction
    starts = np.array([-0.5 * reach, 0.5 * reach])[:, None] * tangent[None, :]
    t = _crossings(is_stiff, starts, normal, reach, tol)
    if t is None:
        return None
    points = starts + t[:, None] * normal[None, :]
    along = points[1] - points[0]
    tangent = along / np.hypot(*along)
    normal = np.array([tangent[1], -tangent[0]])
    if normal @ (coef[1:]) < 0:
        normal = -normal
    wall = Wall(normal=normal, offset=float(points[0] @ normal))
    # every cell on its side, but for those the wall cuts
    wrong = (wall.distance(centres) > 0) != stiff
    cut = np.abs(wall.distance(centres)) < cell / np.sqrt(2.0)
    if np.count_nonzero(wrong & ~cut) > 0:
        return None
    return wall
