"""Measuring the `flex` mesh correction (see :mod:`palpate.sim.flex_calibration` for what it holds and how it is
used): uncalibrated presses on a thick block, each compared with the reference for the same block."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from palpate.core.world.scene import Material
from palpate.sim.contact.law import solve_contact_law
from palpate.sim.flex import reference_press
from palpate.sim.flex_calibration import CAL_HEIGHT, CAL_YOUNG, FORMAT_VERSION
from palpate.sim.flex_model import DEFAULT_WINDOW
from palpate.sim.reference.sample import AxisymmetricSample

#: Contact radius over cell edge at which the factor is tabulated (below the first the contact is one vertex).
CONTACT_OVER_CELL = (0.25, 0.4, 0.55, 0.7, 0.85, 1.0, 1.2)
#: The factor ripples by several % as the contact edge crosses surface vertices; a quadratic in a / cell fitted to
#: the whole loading branch keeps the trend and leaves the ripple (the flex's own error) in place.
FIT_ORDER = 2
POISSONS = (0.0, 0.3, 0.45, 0.49)


def loading_ratio(indentation: np.ndarray, force: np.ndarray, reference, depths: np.ndarray) -> np.ndarray:
    """F / F_reference at ``depths`` (m) along the loading branch of a press (force interpolated in depth)."""
    k = int(np.argmax(indentation))
    d, f = indentation[: k + 1], force[: k + 1]
    keep = np.concatenate([[True], np.diff(d) > 0])
    return np.interp(depths, d[keep], f[keep]) / reference.force_at(depths)


def measure_calibration(resolution: float, *, radius: float = 0.008, window: float = DEFAULT_WINDOW,
                        poissons=POISSONS, path: Path | str | None = None) -> dict:
    """Measure kappa on the calibration block for cells of ``resolution`` (m); write the file if ``path``."""
    rows, cell = [], None
    ac = np.array(CONTACT_OVER_CELL)
    for nu in poissons:
        depth_max = min((ac[-1] * resolution * 1.05) ** 2 / radius, 0.7 * radius)
        trace = reference_press(young=CAL_YOUNG, poisson=nu, height=CAL_HEIGHT, radius=radius, resolution=resolution,
                                window=window, width=4.0 * window, depth=depth_max, calibrate=False)
        cell = float(trace.meta["cell"])
        law = solve_contact_law(AxisymmetricSample(Material("m", CAL_YOUNG, nu), CAL_HEIGHT), radius,
                                1.05 * depth_max)
        dense = np.linspace(ac[0], ac[-1], 60)
        ratio = loading_ratio(trace.indentation, trace.force, law, (dense * cell) ** 2 / radius)
        fit = np.polynomial.Polynomial.fit(dense, ratio, FIT_ORDER)
        rows.append([round(float(v), 4) for v in fit(ac)])
    table = {
        "version": FORMAT_VERSION,
        "measured_with": {
            "young": CAL_YOUNG, "height": CAL_HEIGHT, "radius": radius, "window": window,
            "reference": "layered contact law of the same bonded block (palpate.sim.contact.law)",
            "how": "benchmarks/flex_resolution.py --calibrate (palpate.sim.flex_calibrate.measure_calibration)",
        },
        "tables": [{"cell_over_radius": round(cell / radius, 4), "cell": cell, "poisson": list(poissons),
                    "contact_over_cell": list(CONTACT_OVER_CELL), "factor": rows}],
    }
    if path is not None:
        Path(path).write_text(json.dumps(table, indent=1) + "\n")
    return table
