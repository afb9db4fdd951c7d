"""Measuring the `flex` mesh correction (see :mod:`palpate.sim.flex_calibration` for what it holds and how it is
used): uncalibrated presses on a thick block, each compared with the reference for the same block."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from palpate.core.world.scene import Material
from palpate.sim.contact.law import solve_contact_law
from palpate.sim.flex import reference_press
from palpate.sim.flex_calibration import CAL_HEIGHTS, CAL_YOUNG, FORMAT_VERSION, FREE_WINDOW_SCALE
from palpate.sim.flex_grid import DEFAULT_WINDOW
from palpate.sim.reference.sample import AxisymmetricSample

#: Contact radius over cell edge at which the factor is tabulated (below the first the contact is one vertex): dense,
#: because the factor ripples as the contact's edge crosses the rings of surface vertices.
CONTACT_OVER_CELL = tuple(round(v, 3) for v in np.arange(0.2, 1.301, 0.025))
POISSONS = (0.0, 0.3, 0.45, 0.49)
#: Deepest calibration press, as a fraction of the block's thickness (the validity table presses to 0.6).
MAX_DEPTH_OVER_HEIGHT = 0.62


def loading_ratio(indentation: np.ndarray, force: np.ndarray, reference, depths: np.ndarray) -> np.ndarray:
    """F / F_reference at ``depths`` (m) along the loading branch of a press (force interpolated in depth)."""
    k = int(np.argmax(indentation))
    d, f = indentation[: k + 1], force[: k + 1]
    keep = np.concatenate([[True], np.diff(d) > 0])
    return np.interp(depths, d[keep], f[keep]) / reference.force_at(depths)


def measure_calibration(resolution: float, *, radius: float = 0.008, window: float = DEFAULT_WINDOW,
                        poissons=POISSONS, heights=CAL_HEIGHTS, path: Path | str | None = None,
                        progress=None) -> dict:
    """Measure kappa on the calibration blocks for cells of ``resolution`` (m), both kinds of sides (a "pinned"
    table in ``window``, a "free" one in FREE_WINDOW_SCALE times it); write the file if ``path``.

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
            "how": "benchmarks/flex_resolution.py --calibrate (palpate.sim.flex_calibrate.measure_calibration)",
        },
        "tables": tables,
    }
    if path is not None:
        Path(path).write_text(json.dumps(table) + "\n")
    return table


def _measure_table(resolution: float, radius: float, window: float, sides: str, poissons, heights,
                   progress) -> dict:
    """One calibration table (see :func:`measure_calibration`), its presses in ``window`` (m)."""
    ac = np.array(CONTACT_OVER_CELL)
    factor, reach, cell = [], [], None
    for nu in poissons:
        rows, ups = [], []
        for h in heights:
            depth_max = min((ac[-1] * resolution * 1.02) ** 2 / radius, 0.7 * radius, MAX_DEPTH_OVER_HEIGHT * h)
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
