"""The `flex` fidelity's three calibration tables, read and validated once for a run and handed to each press.

A press reads the block's mesh correction (:mod:`palpate.sim.flex.calibration`), and over a stiff skin the plate's
(:mod:`palpate.sim.flex.plate`) or over a lump the lump's (:mod:`palpate.sim.flex.lump`); reading and validating the
three files takes ~4 ms (the plate table ~3 ms of it), which a run of many presses (a :class:`palpate.sim.source
.SimSource`) pays once by loading them here and passing them to :func:`palpate.sim.flex.press.run_flex_press`.
"""

from __future__ import annotations

from dataclasses import dataclass

from palpate.sim.flex.calibration import MeshCalibration, load_calibration
from palpate.sim.flex.lump import LumpTable, load_lump_calibration
from palpate.sim.flex.plate import PlateTable, load_plate_calibration


@dataclass(frozen=True)
class FlexTables:
    """The shipped calibration tables: the block's mesh correction, the plate's and the lump's."""

    mesh: MeshCalibration
    plate: PlateTable
    lump: LumpTable


def load_flex_tables() -> FlexTables:
    """Read and validate the three shipped tables (models/flex_calibration.json, flex_plate_calibration.json and
    flex_lump_calibration.json).

    Raises:
        ValidationError: a file is missing or invalid, naming it and how to regenerate it.
    """
    return FlexTables(mesh=load_calibration(), plate=load_plate_calibration(), lump=load_lump_calibration())
