"""Measuring the `flex` mesh correction (see :mod:`palpate.sim.flex.calibration` for what it holds and how it is
used): uncalibrated presses on a thick block, each compared with the reference for the same block."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from palpate.core.errors import SimulationDiverged, ValidationError
from palpate.core.session.sources import PressTarget
from palpate.core.world.scene import FingertipSpec, Inclusion, Layer, Material, ObjectSpec, Scene
from palpate.sim.contact.law import solve_contact_law
from palpate.sim.controller import press_profile
from palpate.sim.flex.calibration import (
    CAL_HEIGHTS,
    CAL_YOUNG,
    FORMAT_VERSION,
    FREE_WINDOW_SCALE,
    MeshCalibration,
    calibration_from,
    load_calibration,
    mesh_curve,
)
from palpate.sim.flex.grid import DEFAULT_RESOLUTION, DEFAULT_WINDOW
from palpate.sim.flex.lump import (
    HARD_LUMP_POISSON,
    LUMP_BULK_POISSON,
    LUMP_BULK_YOUNG,
    LUMP_CONTRASTS,
    LUMP_COVERS,
    LUMP_DEPTHS,
    LUMP_FORMAT,
    LUMP_FORMAT_VERSION,
    LUMP_HEIGHT,
    LUMP_RADII,
    SOFT_LUMP_POISSON,
    pocket_moduli,
)
from palpate.sim.flex.model import mixing_at
from palpate.sim.flex.plate import (
    BASE_POISSON,
    BASE_YOUNG,
    PLATE_BASE_POISSONS,
    PLATE_FORMAT,
    PLATE_FORMAT_VERSION,
    PLATE_HEIGHTS,
    PLATE_RATIOS,
    PLATE_SKIN_POISSONS,
    PLATE_SKINS,
    SKIN_POISSON,
)
from palpate.sim.flex.press import reference_press, run_flex_press
from palpate.sim.reference.fe import fe_press
from palpate.sim.reference.sample import AxisInclusion, AxisymmetricSample

#: Contact radius over cell edge at which the factor is tabulated (below the first the contact is one vertex): dense,
#: because the factor ripples as the contact's edge crosses the rings of surface vertices.
CONTACT_OVER_CELL = tuple(round(v, 3) for v in np.arange(0.2, 1.301, 0.025))
POISSONS = (0.0, 0.3, 0.45, 0.49)
#: Deepest calibration press, as a fraction of the block's thickness (the validity table presses to 0.6).
MAX_DEPTH_OVER_HEIGHT = 0.62


def deepest_press(resolution: float, radius: float, height: float) -> float:
    """A calibration press's depth, m: as deep as a / cell reaches CONTACT_OVER_CELL's end, within 0.7 tip radii
    and MAX_DEPTH_OVER_HEIGHT of the block's ``height``."""
    return min((CONTACT_OVER_CELL[-1] * resolution * 1.02) ** 2 / radius, 0.7 * radius, MAX_DEPTH_OVER_HEIGHT * height)


def loading_ratio(indentation: np.ndarray, force: np.ndarray, reference, depths: np.ndarray) -> np.ndarray:
    """F / F_reference at ``depths`` (m) along the loading branch of a press (force interpolated in depth)."""
    k = int(np.argmax(indentation))
    d, f = indentation[: k + 1], force[: k + 1]
    keep = np.concatenate([[True], np.diff(d) > 0])
    return np.interp(depths, d[keep], f[keep]) / reference.force_at(depths)


def measure_calibration(resolution: float, *, radius: float = 0.008, window: float = DEFAULT_WINDOW,
                        poissons=POISSONS, heights=CAL_HEIGHTS, path: Path | str | None = None,
                        progress=None) -> MeshCalibration:
    """Measure kappa on the calibration blocks for cells of ``resolution`` (m), both kinds of sides (a "pinned"
    table in ``window``, a "free" one in FREE_WINDOW_SCALE times it); write the file if ``path``; return the tables
    as :func:`palpate.sim.flex.calibration.load_calibration` reads them.

    Each (poisson, thickness) is one uncalibrated press, as deep as a / cell reaches the table's end or the
    thickness allows; beyond the deepest measured a / cell the row repeats its last value (and a press there is
    flagged extrapolated).
    """
    tables = [_measure_table(resolution, radius, w, sides, poissons, heights, progress)
              for sides, w in (("pinned", window), ("free", FREE_WINDOW_SCALE * window))]
    table = {
        "version": FORMAT_VERSION,
        "measured_with": {
            "young": CAL_YOUNG, "heights": list(heights), "radius": radius, "window": window,
            "free_window": FREE_WINDOW_SCALE * window,
            "reference": "layered contact law of the same bonded block (palpate.sim.contact.law)",
            "how": "benchmarks/flex_resolution.py --calibrate (palpate.sim.flex.calibrate.measure_calibration)",
        },
        "tables": tables,
    }
    if path is not None:
        Path(path).write_text(json.dumps(table) + "\n")
    return calibration_from(table, "measured flex calibration")


def _measure_table(resolution: float, radius: float, window: float, sides: str, poissons, heights,
                   progress) -> dict:
    """One calibration table (see :func:`measure_calibration`), its presses in ``window`` (m)."""
    ac = np.array(CONTACT_OVER_CELL)
    factor, reach, cell = [], [], None
    for nu in poissons:
        rows, ups = [], []
        for h in heights:
            depth_max = deepest_press(resolution, radius, h)
            trace = reference_press(young=CAL_YOUNG, poisson=nu, height=h, radius=radius, resolution=resolution,
                                    window=window, width=4.0 * window, depth=depth_max, calibrate=False)
            cell = float(trace.meta["cell"])
            law = solve_contact_law(AxisymmetricSample(Material("m", CAL_YOUNG, nu), h), radius, 1.05 * depth_max)
            up = min(ac[-1], np.sqrt(radius * 0.98 * float(trace.indentation.max())) / cell)
            inside = np.minimum(ac, up)
            rows.append([round(float(v), 4) for v in loading_ratio(trace.indentation, trace.force, law,
                                                                   (inside * cell) ** 2 / radius)])
            ups.append(round(float(up), 4))
            if progress is not None:
                progress(sides, nu, h)
        factor.append(rows)
        reach.append(ups)
    return {"sides": sides, "cell_over_radius": round(cell / radius, 4), "cell": cell, "poisson": list(poissons),
            "thickness": list(heights), "contact_over_cell": list(CONTACT_OVER_CELL), "measured_to": reach,
            "factor": factor}


def plate_sample(skin: float, ratio: float, height: float, *, skin_poisson: float = SKIN_POISSON,
                 base_poisson: float = BASE_POISSON) -> AxisymmetricSample:
    """A stiff-over-soft stack: a ``skin`` m thick layer ``ratio`` times as stiff as its base, ``height`` m in all."""
    return AxisymmetricSample(Material("base", BASE_YOUNG, base_poisson), height,
                              layers=(Layer(Material("skin", BASE_YOUNG * ratio, skin_poisson), skin),))


@dataclass(frozen=True)
class PlateRatio:
    """One uncorrected flex press on a plate against its exact layered law.

    Attributes:
        contact_over_cell: (c,) a / cell = sqrt(R d) / cell of each depth read (held at the deepest reached).
        raw: (c,) F_flex (uncorrected) / F_law.
        block: (c,) the block's kappa the press reads there (the free table: the plate window's).
        reach: the deepest a / cell the press reached (capped at the grid's end).
        cell: the window's cell at the press point, m.
    """

    contact_over_cell: np.ndarray
    raw: np.ndarray
    block: np.ndarray
    reach: float
    cell: float


def plate_ratio(sample: AxisymmetricSample, *, radius: float = 0.008, resolution: float = DEFAULT_RESOLUTION,
                depth: float | None = None, calibration: MeshCalibration | None = None) -> PlateRatio:
    """Press ``sample`` (a layered stack) once by flex, uncorrected, at the centre of a box wider than the plate
    window, to ``depth`` (m; default :func:`deepest_press`), and compare it with the stack's exact layered contact
    law."""
    ac = np.array(CONTACT_OVER_CELL)
    h = sample.thickness
    if depth is None:
        depth = deepest_press(resolution, radius, h)
    bulk = sample.bulk
    trace = reference_press(young=bulk.young, poisson=bulk.poisson, height=h, radius=radius, resolution=resolution,
                            depth=depth, width=max(0.2, 4.0 * (h + 0.02)), layers=sample.layers, calibrate=False)
    cell = float(trace.meta["cell"])
    law = solve_contact_law(sample, radius, 1.05 * depth)
    up = min(ac[-1], np.sqrt(radius * 0.98 * float(trace.indentation.max())) / cell)
    inside = np.minimum(ac, up)
    raw = loading_ratio(trace.indentation, trace.force, law, (inside * cell) ** 2 / radius)
    top = sample.layers[0].material if sample.layers else bulk
    curve = mesh_curve(top.poisson, cell / radius, load_calibration() if calibration is None else calibration, h, 0.0)
    block = np.array([curve.at(float(a)).kappa for a in inside])
    return PlateRatio(contact_over_cell=ac, raw=raw, block=block, reach=float(up), cell=cell)


def _plate_ratio_within(sample: AxisymmetricSample, radius: float, resolution: float, calibration: MeshCalibration,
                        tries: int = 4) -> PlateRatio:
    """:func:`plate_ratio` to the default depth, or, where that press diverges (a thin skin 70x its base, after
    its deepest point: the tip sinks between the surface vertices), 15% shallower each time (its row is then held
    beyond the a / cell it reached, and a press there is flagged extrapolated)."""
    depth = None
    for _ in range(tries - 1):
        try:
            return plate_ratio(sample, radius=radius, resolution=resolution, depth=depth, calibration=calibration)
        except SimulationDiverged:
            depth = 0.85 * (deepest_press(resolution, radius, sample.thickness) if depth is None else depth)
    return plate_ratio(sample, radius=radius, resolution=resolution, depth=depth, calibration=calibration)


def measure_plate_calibration(*, radius: float = 0.008, resolution: float = DEFAULT_RESOLUTION,
                              path: Path | str | None = None, progress=None) -> dict:
    """Measure q = (F_flex / F_law) / kappa_block on the calibration plates (PLATE_SKIN_POISSONS x
    PLATE_BASE_POISSONS x PLATE_RATIOS x PLATE_SKINS x PLATE_HEIGHTS, :mod:`palpate.sim.flex.plate`), one uncorrected
    press each; write the file if ``path``. ``progress(skin_poisson, base_poisson, ratio, skin, height)`` after each."""
    calibration = load_calibration()
    cell = None

    def plate(nu_s, nu_b, ratio, skin, h):
        nonlocal cell
        sample = plate_sample(skin, ratio, h, skin_poisson=nu_s, base_poisson=nu_b)
        m = _plate_ratio_within(sample, radius, resolution, calibration)
        cell = m.cell
        if progress is not None:
            progress(nu_s, nu_b, ratio, skin, h)
        return [round(float(v), 4) for v in m.raw / m.block], round(m.reach, 4)

    rows = [[[[[plate(nu_s, nu_b, ratio, skin, h) for h in PLATE_HEIGHTS] for skin in PLATE_SKINS]
              for ratio in PLATE_RATIOS] for nu_b in PLATE_BASE_POISSONS] for nu_s in PLATE_SKIN_POISSONS]
    factor = [[[[[f for f, _ in hs] for hs in ss] for ss in ms] for ms in bs] for bs in rows]
    reach = [[[[[u for _, u in hs] for hs in ss] for ss in ms] for ms in bs] for bs in rows]
    table = {
        "format": PLATE_FORMAT, "version": PLATE_FORMAT_VERSION,
        "measured_with": {
            "radius": radius, "cell": cell,
            "reference": "layered contact law of the same stack (palpate.sim.contact.law)",
            "block_table": "models/flex_calibration.json, free sides (remeasure this table when it changes)",
            "how": "benchmarks/flex_plate.py --calibrate (palpate.sim.flex.calibrate.measure_plate_calibration)",
        },
        "cell_over_radius": round(cell / radius, 4), "contact_over_cell": list(CONTACT_OVER_CELL),
        "skin_poisson": list(PLATE_SKIN_POISSONS), "base_poisson": list(PLATE_BASE_POISSONS),
        "modulus_ratio": list(PLATE_RATIOS), "skin": list(PLATE_SKINS), "height": list(PLATE_HEIGHTS),
        "factor": factor, "measured_to": reach,
    }
    if path is not None:
        Path(path).write_text(json.dumps(table) + "\n")
    return table



def lump_sample(cover: float, radius: float, contrast: float) -> AxisymmetricSample:
    """A calibration lump: a sphere of ``radius`` m, its top ``cover`` m down, ``contrast`` times the bulk's
    Young's modulus, on the axis of the calibration block (:mod:`palpate.sim.flex.lump`)."""
    nu = SOFT_LUMP_POISSON if contrast < 1.0 else HARD_LUMP_POISSON
    return AxisymmetricSample(Material("bulk", LUMP_BULK_YOUNG, LUMP_BULK_POISSON), LUMP_HEIGHT,
                              inclusion=AxisInclusion(Material("lump", LUMP_BULK_YOUNG * contrast, nu), "sphere",
                                                      cover, radius))


def lump_object(sample: AxisymmetricSample) -> ObjectSpec:
    """A box wide enough that no side is in the window, with ``sample``'s sphere (if any) on the axis at (0, 0)."""
    inclusions = ()
    if sample.inclusion is not None:
        inc = sample.inclusion
        centre = (0.0, 0.0, sample.thickness - inc.depth - inc.radius)
        inclusions = (Inclusion(inc.material, "sphere", centre, (inc.radius,)),)
    width = max(0.2, 4.0 * (sample.thickness + 0.02))
    return ObjectSpec("lump", "box", (width, width, sample.thickness), (0.0, 0.0), sample.bulk,
                      inclusions=inclusions)


@dataclass(frozen=True)
class LumpPress:
    """One uncorrected flex press of a lump sample: the force (N) at LUMP_DEPTHS on the loading branch, the lateral
    mixing correction there, and e1, e2 of the window under the press (None without a lump)."""

    force: np.ndarray
    mixing: np.ndarray
    moduli: np.ndarray | None


def lump_press(sample: AxisymmetricSample, *, radius: float = 0.008,
               resolution: float = DEFAULT_RESOLUTION) -> LumpPress:
    """Press ``sample`` once by flex, uncorrected, at its centre to just past LUMP_DEPTHS' deepest."""
    obj = lump_object(sample)
    depths = np.array(LUMP_DEPTHS)
    target = PressTarget(0.0, 0.0, depth=1.03 * depths[-1], speed=0.01)
    profile = press_profile(target, obj.height, radius=radius, timestep=0.002)
    models: dict = {}
    trace = run_flex_press(Scene((obj,), fingertip=FingertipSpec(radius=radius)), obj, target, profile,
                           resolution=resolution, calibrate=False, models=models)
    fm = next(iter(models.values()))[0]
    k = int(np.argmax(trace.indentation))
    d, f = trace.indentation[: k + 1], trace.force[: k + 1]
    keep = np.concatenate([[True], np.diff(d) > 0])
    force = np.interp(depths, d[keep], f[keep])
    mixing = mixing_at(fm, obj, 0.0, 0.0, radius)
    mix = np.ones_like(depths) if mixing is None else np.array([mixing.at(float(v)) for v in depths])
    return LumpPress(force=force, mixing=mix,
                     moduli=pocket_moduli(obj, fm.grid, fm.cell_young, fm.cell_poisson, 0.0, 0.0))


def measure_lump_calibration(*, radius: float = 0.008, resolution: float = DEFAULT_RESOLUTION,
                             path: Path | str | None = None, progress=None) -> dict:
    """Measure r = [F_flex(lump) / F_flex(block) / mixing] / [F_FE(lump) / F_FE(block)] on the calibration lumps
    (LUMP_COVERS x LUMP_RADII x LUMP_CONTRASTS, :mod:`palpate.sim.flex.lump`), one uncorrected flex press and one FE
    reference each; write the file if ``path``. ``progress(cover, radius, contrast)`` after each."""
    depths = np.array(LUMP_DEPTHS)
    block = lump_sample(LUMP_COVERS[0], LUMP_RADII[0], 1.0)
    block = AxisymmetricSample(block.bulk, block.thickness)
    flex_block = lump_press(block, radius=radius, resolution=resolution).force
    fe_block = fe_press(block, radius, depths).force
    moduli, factor = [], []
    for cover in LUMP_COVERS:
        for size in LUMP_RADII:
            for contrast in LUMP_CONTRASTS:
                sample = lump_sample(cover, size, contrast)
                m = lump_press(sample, radius=radius, resolution=resolution)
                r = m.force / flex_block / m.mixing / (fe_press(sample, radius, depths).force / fe_block)
                if m.moduli is None or not np.all(np.isfinite(r) & (r > 0)):
                    raise ValidationError(f"flex lump calibration: {sample.describe()} gave no finite ratio")
                moduli.append([round(float(v), 6) for v in m.moduli])
                factor.append([round(float(v), 4) for v in r])
                if progress is not None:
                    progress(cover, size, contrast)
    table = {
        "format": LUMP_FORMAT, "version": LUMP_FORMAT_VERSION,
        "measured_with": {
            "radius": radius, "cell": resolution,
            "reference": "FE reference (palpate.sim.reference.fe, refinement 1) of each lump and of the block",
            "how": "benchmarks/flex_lump.py --calibrate (palpate.sim.flex.calibrate.measure_lump_calibration)",
            "lumps": "covers x radii x contrasts, row-major", "covers": list(LUMP_COVERS),
            "radii": list(LUMP_RADII), "contrasts": list(LUMP_CONTRASTS),
        },
        "cell_over_radius": round(resolution / radius, 4),
        "contact_over_cell": [round(float(v), 5) for v in np.sqrt(radius * depths) / resolution],
        "moduli": moduli, "factor": factor,
    }
    if path is not None:
        Path(path).write_text(json.dumps(table) + "\n")
    return table
