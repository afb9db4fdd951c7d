"""The `flex` correction for lumps: what the window's surface vertices do over a pocket, measured on calibration lumps.

The lateral mixing correction (:func:`palpate.sim.flex.mixing.lateral_mixing_correction`) answers how the cells
round the press axis average a lump's moduli; it does not see the kinematics of the collision vertices over them.
Over a soft pocket as wide as two cells the contact's edge reaching the next ring of collision vertices, which are
interpolated from nodes on the pocket's rim and held by the bulk's cells, steps the force up by ~19% between 1.2 and
1.4 mm on the 8 mm tip (docs/results.md); the homogeneous blocks' kappa does not know that step. A
press over a lump multiplies kappa and the mixing correction by

    r(a / cell, e1, e2) = [F_flex(lump) / F_flex(block) / mixing] / [F_FE(lump) / F_FE(block)]

measured on calibration lumps (LUMP_COVERS x LUMP_RADII x LUMP_CONTRASTS: spheres on the press axis of a 30 mm block
of 100 kPa, nu 0.45, none a validity-table lump), each pressed once by flex uncorrected and by the FE reference,
against the same block without it on the same grid (so kappa cancels). A lump is placed in the table by what the
window holds under the press: e1 and e2, the mean Young's modulus over the bulk's of the four cells round the press
axis in the top cell layer and in the one under it (:func:`pocket_moduli`). r is interpolated linearly over the
calibration lumps' (log e1, log e2) (a Delaunay triangulation; its nearest lump outside their hull, flagged), with a
window holding no lump (e1 = e2 = 1) at r = 1 (it is the block kappa was measured on). The interpolation was chosen
before any held-out lump was evaluated, on the calibration lumps alone (r at 2 mm falls monotonically with e1 over
the soft ones, from +32% at e1 0.15 to +5% at 0.78; deep lumps with e1 = 1 differ by e2).

Every calibration lump is centred on the press axis (the four cells alike in each layer). Off the axis r was
measured against the 3-D FE reference beside box lumps (docs/results.md, off-axis lumps): neutral on
average but no rule: with a lump's edge at or beside the axis (a bulk cell beside a lump cell) it made 14 of 32 cases
worse (one depth by 9 points) and 18 better, 3 mm inside a lump's edge 8 of 16 worse. So a press reads
r ** (centring ** :data:`CENTRING_POWER`), ``centring`` (:func:`pocket_centring`) 1 over a centred pocket and 0
over a lump's edge: off the axis flex is as it was before r.

Applied to objects with inclusions and neither layers nor a haptic-material map (the table holds no such window: a
skin mixes into the top cells without a pocket). models/flex_lump_calibration.json holds the table for one cell
size and tip; ``benchmarks/flex_lump.py --calibrate`` remeasures it
(:func:`palpate.sim.flex.calibrate.measure_lump_calibration`); it does not depend on the block table (kappa cancels).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.files import number_array
from palpate.core.world.resources import models_dir
from palpate.core.world.scene import ObjectSpec
from palpate.sim.blas import one_blas_thread
from palpate.sim.flex.grid import FlexGrid
from palpate.sim.flex.mixing import cell_lookup
from palpate.sim.validity.reference import read_document

#: The shipped table.
LUMP_CALIBRATION_PATH = models_dir() / "flex_lump_calibration.json"
LUMP_FORMAT = "palpate-flex-lump-calibration"
LUMP_FORMAT_VERSION = 1
#: The calibration lumps: depth of the sphere's top under the surface (m), its radius (m) and its Young's modulus
#: over the bulk's; none is a validity-table lump (tops 1, 3, 6 mm, radius 5 mm, 20x and 0.1x).
LUMP_COVERS = (0.0007, 0.0015, 0.0022, 0.0045, 0.0075)
LUMP_RADII = (0.004, 0.006)
LUMP_CONTRASTS = (0.05, 0.2, 5.0, 40.0)
#: The calibration block: Young's modulus (Pa; flex and the reference are linear, only ratios matter), Poisson ratio,
#: height (m); a soft lump's Poisson ratio and a hard one's.
LUMP_BULK_YOUNG = 1.0e5
LUMP_BULK_POISSON = 0.45
LUMP_HEIGHT = 0.03
SOFT_LUMP_POISSON = 0.3
HARD_LUMP_POISSON = 0.4
#: Indentations of the calibration presses, m (a / cell 0.36-1.13 on the 8 mm tip with 5 mm cells; r is held
#: beyond both ends, flagged beyond the deep one).
LUMP_DEPTHS = tuple(float(v) for v in np.geomspace(4.0e-4, 4.0e-3, 28))
#: A press reads r ** (centring ** CENTRING_POWER) (:func:`pocket_centring`): r is measured on centred lumps only and
#: did not help partly centred ones (presses 3 mm inside a box lump's edge, docs/results.md), so it
#: fades steeply; 12 is the smallest power (of 1, 4, 6, 8, 12, 16) leaving no nu 0.45 case over 0.1% worse than
#: r = 1 in mean |error|.
CENTRING_POWER = 12


@dataclass(frozen=True)
class LumpTable:
    """A loaded lump calibration.

    Attributes:
        cell_over_radius: cell edge / tip radius it was measured with.
        contact_over_cell: (c,) a / cell = sqrt(R d) / cell, increasing.
        moduli: (n, 2) each calibration lump's e1, e2 (:func:`pocket_moduli`), > 0.
        factor: (n, c) r of each lump.
    """

    cell_over_radius: float
    contact_over_cell: np.ndarray
    moduli: np.ndarray
    factor: np.ndarray


def load_lump_calibration(path: Path | str = LUMP_CALIBRATION_PATH) -> LumpTable:
    """Read and validate a lump calibration file (bounded JSON, see :func:`palpate.core.files.read_json`).

    Raises:
        ValidationError: missing, too large, not JSON, another format or version, a bad or inconsistent key,
            naming the file and the key.
    """
    path = Path(path)
    raw = read_document(path, "flex lump calibration", LUMP_FORMAT, LUMP_FORMAT_VERSION,
                        "regenerate it with `.venv/bin/python benchmarks/flex_lump.py --calibrate`")
    arrays = {key: number_array(raw.get(key), f"{path}: {key}", ndim, max_size=100_000) for key, ndim in (
        ("cell_over_radius", 0), ("contact_over_cell", 1), ("moduli", 2), ("factor", 2))}
    n, c = len(arrays["moduli"]), len(arrays["contact_over_cell"])
    if arrays["moduli"].shape != (n, 2) or arrays["factor"].shape != (n, c) or n < 3 or c < 2:
        raise ValidationError(f"{path}: moduli must be (lumps, 2) and factor (lumps, contact_over_cell), >= 3 lumps")
    if not (np.all(np.diff(arrays["contact_over_cell"]) > 0) and arrays["cell_over_radius"] > 0
            and np.all(arrays["moduli"] > 0) and np.all(arrays["factor"] > 0)):
        raise ValidationError(f"{path}: needs increasing contact_over_cell, cell_over_radius > 0, moduli > 0 and "
                              "factors > 0")
    return LumpTable(cell_over_radius=float(arrays["cell_over_radius"]), **{k: arrays[k] for k in (
        "contact_over_cell", "moduli", "factor")})


def _pocket_cells(obj: ObjectSpec, grid: FlexGrid, young: np.ndarray, poisson: np.ndarray, x: float,
                  y: float) -> np.ndarray | None:
    """(2, 4) Young's moduli over the bulk's of the four cells round the press axis in the top two cell layers, or
    None where the lump correction does not apply (see :func:`pocket_moduli`)."""
    if not obj.inclusions or obj.layers or obj.material_map is not None or len(grid.z) < 3:
        return None
    lookup = cell_lookup(obj, grid, young, poisson, x, y)
    h = grid.finest / 2.0
    offsets = np.array([[-h, -h], [-h, h], [h, -h], [h, h]] * 2)
    top, first, second = float(grid.z[-1]), float(grid.z[-2]), float(grid.z[-3])
    depths = np.repeat([(top - first) / 2.0, (top - first) + (first - second) / 2.0], 4)
    cells = lookup(offsets, depths)[0].reshape(2, 4) / obj.material.young
    if not np.all(np.isfinite(cells) & (cells > 0)):
        raise ValidationError(f"flex: the cells under the press on {obj.name!r} have no positive modulus")
    return None if np.allclose(cells, 1.0, rtol=1e-9, atol=0.0) else cells


@dataclass(frozen=True)
class Pocket:
    """The lump under a press, as its window's cells see it.

    Attributes:
        moduli: (2,) e1, e2: the mean Young's modulus over the bulk's of the four cells round the press axis in the
            window's top cell layer and in the one under it.
        centring: 0-1, how centred on the press axis the pocket is (:func:`pocket_centring`).
    """

    moduli: np.ndarray
    centring: float


def pocket_at(obj: ObjectSpec, grid: FlexGrid, young: np.ndarray, poisson: np.ndarray, x: float,
              y: float) -> Pocket | None:
    """The pocket of a press at (x, y) (m), its eight cells looked up once; ``young`` and ``poisson`` per cell
    (:func:`palpate.sim.flex.mixing.cell_moduli`). None where the lump correction does not apply: no inclusion, a
    layer or a material map (the table holds no such window), or all eight cells bulk."""
    cells = _pocket_cells(obj, grid, young, poisson, x, y)
    if cells is None:
        return None
    d = np.abs(np.log(cells))
    return Pocket(moduli=cells.mean(axis=1),
                  centring=float(np.clip(d.min(axis=1).sum() / d.max(axis=1).sum(), 0.0, 1.0)))


def pocket_moduli(obj: ObjectSpec, grid: FlexGrid, young: np.ndarray, poisson: np.ndarray, x: float,
                  y: float) -> np.ndarray | None:
    """e1, e2 of a press at (x, y) (m): :attr:`Pocket.moduli` of :func:`pocket_at`, or None where the lump
    correction does not apply."""
    pocket = pocket_at(obj, grid, young, poisson, x, y)
    return None if pocket is None else pocket.moduli


def pocket_centring(obj: ObjectSpec, grid: FlexGrid, young: np.ndarray, poisson: np.ndarray, x: float,
                    y: float) -> float:
    """How centred on the press axis the pocket of :func:`pocket_moduli` is, 0-1: per layer the smallest over the
    largest |log modulus| of its four cells, summed over the two layers (1: the four cells alike in each layer, as
    every calibration lump's; 0: a bulk cell beside a lump cell, a lump's edge off the axis). 1 where there is no
    pocket. The press fades r with it (:func:`lump_curve`): off the axis r does not help (module docstring)."""
    pocket = pocket_at(obj, grid, young, poisson, x, y)
    return 1.0 if pocket is None else pocket.centring


@dataclass(frozen=True)
class LumpCurve:
    """r against a / cell for one press (its window and point fixed).

    Attributes:
        contact_over_cell: (c,) a / cell.
        factor: (c,) r.
        outside: e1, e2 lie outside the calibration lumps' hull (the nearest lump's row is used) or the cell size is
            over 5% from the table's.
    """

    contact_over_cell: np.ndarray
    factor: np.ndarray
    outside: bool

    def at(self, contact_over_cell: float) -> float:
        """r at contact radius / cell ``contact_over_cell`` (held at the table's ends)."""
        return float(np.interp(contact_over_cell, self.contact_over_cell, self.factor))

    def extrapolated(self, contact_over_cell: float) -> bool:
        """Whether r at ``contact_over_cell`` is read outside what was measured: beyond its deepest press (every
        press passes through the shallow end, where r is held as the lateral mixing correction is)."""
        return bool(self.outside or contact_over_cell > self.contact_over_cell[-1] * 1.05)


def lump_curve(table: LumpTable, moduli: np.ndarray, cell_over_radius: float, centring: float = 1.0) -> LumpCurve:
    """r for a press whose window holds ``moduli`` (e1, e2) with cells of ``cell_over_radius`` tip radii, reduced
    once per press to a curve in a / cell (see the module docstring for the interpolation), raised to ``centring`` **
    :data:`CENTRING_POWER` (``centring`` from :func:`pocket_centring`, 0-1: 0 gives r = 1)."""
    e = np.asarray(moduli, dtype=float)
    if (e.shape != (2,) or not np.all(np.isfinite(e) & (e > 0)) or not cell_over_radius > 0
            or not 0.0 <= centring <= 1.0):
        raise ValidationError(f"flex: a lump needs two positive cell moduli, cells > 0 and a centring in [0, 1], got "
                              f"{moduli!r}, {cell_over_radius!r}, {centring!r}")
    points = np.vstack([np.log(table.moduli), np.zeros((1, 2))])  # the window without a lump: the block, r = 1
    values = np.vstack([table.factor, np.ones((1, table.factor.shape[1]))])
    from scipy.interpolate import LinearNDInterpolator  # only flex presses over a lump: ~0.1 s to import

    with one_blas_thread():  # the triangulation's small LAPACK calls would leave OpenBLAS threads spinning (sim.blas)
        row = LinearNDInterpolator(points, values)(np.log(e)[None])[0]
    outside = bool(np.any(np.isnan(row)))
    if outside:
        row = values[int(np.argmin(np.linalg.norm(points - np.log(e)[None], axis=1)))]
    outside |= abs(table.cell_over_radius / cell_over_radius - 1.0) > 0.05
    fade = centring ** CENTRING_POWER
    return LumpCurve(contact_over_cell=table.contact_over_cell, factor=np.asarray(row, dtype=float) ** fade,
                     outside=outside)
