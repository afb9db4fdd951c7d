"""The `flex` fidelity's mesh correction: how much stiffer the trilinear flex block is than the elastic continuum.

A trilinear cell interpolates displacement over an edge comparable to the contact radius, so the block answers a
press with more force than the continuum does (1.3-1.9x with 5 mm cells), by a factor that depends on the contact
radius a over the cell edge, on the block's thickness (a thick block deforms over more coarse cells: at a = 1.1
cells the factor is 1.44 on 20 mm and 1.70 on 100 mm, nu 0.3) and on the Poisson ratio. The factor ripples by
+-8% in a / cell as the contact's edge crosses the rings of surface vertices (a press stands on a node column), so
it is tabulated densely in a / cell, not smoothed. It is measured on homogeneous blocks (CAL_HEIGHTS, none of the
validity table's thicknesses, wider than the window, bonded to the table) against the reference for the same block
(the layered contact law, which agrees with the FE reference within ~1%): kappa(a / cell, H, nu) = F_flex /
F_reference. A press divides its contact forces by kappa (times, over a stiff top layer, the plate's q,
:mod:`palpate.sim.flex.plate`) at its current contact radius sqrt(R d) (a soft skin's
mixed cells: where the block's contact was as wide, :meth:`palpate.sim.flex.mixing.MixingCorrection.contact_at`) and
its object's height. kappa is the mesh's alone (the reference of each block includes its own thickness), so a
thinner block, a layer or an edge keeps the stiffening its own elasticity gives it.

The window's pinned sides stiffen it too (a 20 mm block pressed 2-3 mm in the 30 mm window is ~20% stiffer than
in a window three times as wide), and a table measured in the default window holds that stiffening as well as the
mesh's. A window with free sides (a cylinder's whole disc, a small box) has no such stiffening, so there are two
kinds of table (key ``sides``): "pinned", measured in the default window, and "free", measured in a window twice
as wide (FREE_WINDOW_SCALE; wider changes kappa by under ~3% on a 20 mm block); a press uses kappa interpolated
between them by the fraction of its window's sides that are pinned.

models/flex_calibration.json holds one table per cell size (cell / tip radius) and kind of sides;
``benchmarks/flex_resolution.py --calibrate`` remeasures it (:func:`palpate.sim.flex.calibrate.measure_calibration`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.files import number_array
from palpate.core.world.resources import models_dir
from palpate.sim.validity.reference import read_document

#: The shipped table.
CALIBRATION_PATH = models_dir() / "flex_calibration.json"
#: Thicknesses of the calibration blocks, m (chosen between the validity table's 2/5/10/20/50/100 mm, so that every
#: row of the table reports on a thickness the correction was not measured on). The thinnest is under 2 mm because
#: a thin block's factor falls steeply with thickness where the contact is over half a cell (a / cell 0.57: 0.78 on
#: 3 mm, 0.62 on 2 mm, nu 0.49), so a 2 mm block must be interpolated, not given 3 mm's; 1.7 mm because its deepest
#: press (0.62 of it) then reaches that contact radius.
CAL_HEIGHTS = (0.0017, 0.003, 0.007, 0.014, 0.03, 0.07, 0.15)
#: Reference modulus of the calibration (the flex is E-invariant; this only fixes the units), Pa.
CAL_YOUNG = 2.0e5
FORMAT_VERSION = 4
#: The kinds of calibration table (see the module docstring).
SIDES = ("pinned", "free")
#: Width of the window a "free" table is measured in, in default windows.
FREE_WINDOW_SCALE = 2.0


@dataclass(frozen=True)
class MeshTable:
    """One calibration table: one cell size and kind of sides.

    Attributes:
        sides: "pinned" or "free" (SIDES).
        cell_over_radius: cell edge / tip radius it was measured with.
        poisson: (p,) Poisson ratios, increasing.
        thickness: (h,) block thicknesses, m, increasing, > 0.
        contact_over_cell: (c,) a / cell, increasing.
        measured_to: (p, h) the largest a / cell each block was pressed to (beyond it its row is held).
        factor: (p, h, c) kappa, > 0.
    """

    sides: str
    cell_over_radius: float
    poisson: np.ndarray
    thickness: np.ndarray
    contact_over_cell: np.ndarray
    measured_to: np.ndarray
    factor: np.ndarray


@dataclass(frozen=True)
class MeshCalibration:
    """A loaded calibration file: its tables sorted by cell_over_radius (the file's ``measured_with`` record of how
    it was measured is for people and is not kept)."""

    tables: tuple[MeshTable, ...]


def load_calibration(path: Path | str = CALIBRATION_PATH) -> MeshCalibration:
    """Read and validate a calibration file (bounded JSON, see :func:`palpate.core.files.read_json`).

    Raises:
        ValidationError: missing, too large, not JSON, wrong version or a bad key, naming the file and the key.
    """
    path = Path(path)
    raw = read_document(path, "flex calibration table", None, FORMAT_VERSION,
                        "regenerate it with `.venv/bin/python benchmarks/flex_resolution.py --calibrate`")
    return calibration_from(raw, str(path))


def calibration_from(raw: dict, source: str) -> MeshCalibration:
    """A decoded calibration document (a file's, or :func:`palpate.sim.flex.calibrate.measure_calibration`'s)
    validated; a ValidationError names ``source`` and the key."""
    tables = raw.get("tables")
    if not isinstance(tables, list) or not tables:
        raise ValidationError(f"{source}: key 'tables' must be a non-empty list")
    out = [_table(source, f"tables[{i}]", t) for i, t in enumerate(tables)]
    return MeshCalibration(tables=tuple(sorted(out, key=lambda t: t.cell_over_radius)))


def _table(source: str, key: str, t) -> MeshTable:
    """One table of a calibration document, validated."""
    if not isinstance(t, dict):
        raise ValidationError(f"{source}: {key} must be an object")

    def numbers(name: str, ndim: int) -> np.ndarray:
        return number_array(t.get(name), f"{source}: {key}.{name}", ndim)

    c_r = float(numbers("cell_over_radius", 0))
    nu, hs, ac = numbers("poisson", 1), numbers("thickness", 1), numbers("contact_over_cell", 1)
    fac, upto = numbers("factor", 3), numbers("measured_to", 2)
    if fac.shape != (len(nu), len(hs), len(ac)) or upto.shape != (len(nu), len(hs)):
        raise ValidationError(f"{source}: {key}.factor must be {len(nu)} x {len(hs)} x {len(ac)} and "
                              f"{key}.measured_to {len(nu)} x {len(hs)} (poisson x thickness x contact_over_cell)")
    if not (c_r > 0 and np.all(np.diff(nu) > 0) and np.all(np.diff(ac) > 0) and np.all(np.diff(hs) > 0)
            and hs[0] > 0 and np.all(fac > 0)):
        raise ValidationError(f"{source}: {key} needs cell_over_radius > 0, increasing poisson, thickness > 0 and "
                              "contact_over_cell, and factors > 0")
    if t.get("sides") not in SIDES:
        raise ValidationError(f"{source}: {key}.sides must be one of {list(SIDES)}, got {t.get('sides')!r}")
    return MeshTable(sides=t["sides"], cell_over_radius=c_r, poisson=nu, thickness=hs, contact_over_cell=ac,
                     measured_to=upto, factor=fac)


@dataclass(frozen=True)
class MeshFactor:
    """The mesh correction at one point of a press.

    Attributes:
        kappa: F_flex / F_continuum, the factor the contact forces are divided by.
        extrapolated: True if the cell size is over 5% from the table's, or the point lies outside what was
            measured (the table's end value is used).
    """

    kappa: float
    extrapolated: bool


def _weights(x: float, nodes: np.ndarray) -> np.ndarray:
    """Weights (n,) of linear interpolation at ``x`` on increasing ``nodes`` (n,), clamped at the ends (np.interp's
    rule), so that interpolating values v (n,) is weights @ v."""
    return np.array([np.interp(x, nodes, row) for row in np.eye(len(nodes))])


@dataclass(frozen=True)
class _SideCurve:
    contact_over_cell: np.ndarray
    factor: np.ndarray
    reach: float
    outside: bool


def _side_curve(t: MeshTable, poisson: float, cell_over_radius: float, thickness: float) -> _SideCurve:
    """One table reduced to kappa against a / cell at ``poisson`` and ``thickness`` (linear in log thickness and
    poisson, clamped at the table's ends; linear in a / cell is then one np.interp)."""
    nu, hs = t.poisson, t.thickness
    w_nu, w_h = _weights(poisson, nu), _weights(float(np.log(thickness)), np.log(hs))
    outside = (abs(t.cell_over_radius / cell_over_radius - 1.0) > 0.05 or not nu[0] <= poisson <= nu[-1]
               or not hs[0] * 0.95 <= thickness <= hs[-1] * 1.05)
    return _SideCurve(contact_over_cell=t.contact_over_cell, factor=np.einsum("p,h,phc->c", w_nu, w_h, t.factor),
                      reach=float(w_nu @ t.measured_to @ w_h), outside=bool(outside))


@dataclass(frozen=True)
class MeshCurve:
    """The mesh correction of one press (its cells, Poisson ratio, thickness and sides fixed) against a / cell.

    Attributes:
        sides: the kinds of table the press uses, each with its weight (the fraction of pinned sides, or 1 minus it).
        missing: a kind the press needs has no table.
    """

    sides: tuple[tuple[_SideCurve, float], ...]
    missing: bool

    def at(self, contact_over_cell: float) -> MeshFactor:
        """kappa at contact radius / cell ``contact_over_cell`` and whether it is extrapolated."""
        kappa = sum(w * float(np.interp(contact_over_cell, c.contact_over_cell, c.factor)) for c, w in self.sides)
        outside = any(c.outside or contact_over_cell > c.reach * 1.05 for c, w in self.sides if w > 0)
        return MeshFactor(float(kappa), bool(outside or self.missing))


def mesh_curve(poisson: float, cell_over_radius: float, calibration: MeshCalibration, thickness: float,
               pinned_fraction: float = 1.0) -> MeshCurve:
    """The mesh correction for cells of ``cell_over_radius``, ``poisson`` and block ``thickness`` (m) in a window with
    ``pinned_fraction`` (0 to 1) of its sides pinned, as a function of a / cell (:meth:`MeshCurve.at`).

    Uses, of each kind of sides, the table of the nearest cell size (linear in a / cell, log thickness and poisson,
    clamped at the table's ends), and interpolates linearly between the kinds by ``pinned_fraction``. Reduced once
    per press: a press reads it at every step.
    """
    if not 0.0 <= pinned_fraction <= 1.0:
        raise ValidationError(f"flex: pinned_fraction must be in [0, 1], got {pinned_fraction!r}")
    found = {}
    for sides in SIDES:
        tables = [tb for tb in calibration.tables if tb.sides == sides]
        if tables:
            t = min(tables, key=lambda tb: abs(np.log(tb.cell_over_radius / cell_over_radius)))
            found[sides] = _side_curve(t, poisson, cell_over_radius, thickness)
    weight = {"pinned": pinned_fraction, "free": 1.0 - pinned_fraction}
    missing = any(weight[k] > 0 and k not in found for k in SIDES)
    if len(found) < len(SIDES):
        return MeshCurve(sides=((next(iter(found.values())), 1.0),), missing=missing)
    return MeshCurve(sides=tuple((found[k], weight[k]) for k in SIDES), missing=False)


def mesh_factor(contact_over_cell: float, poisson: float, cell_over_radius: float, calibration: MeshCalibration,
                thickness: float, pinned_fraction: float = 1.0) -> MeshFactor:
    """kappa at contact radius / cell ``contact_over_cell``, ``poisson`` and block ``thickness`` (m) for cells of
    ``cell_over_radius`` in a window with ``pinned_fraction`` (0 to 1) of its sides pinned (:func:`mesh_curve`).

    Returns:
        The factor and whether it is extrapolated (also when a kind the press needs has no table).
    """
    return mesh_curve(poisson, cell_over_radius, calibration, thickness, pinned_fraction).at(contact_over_cell)
