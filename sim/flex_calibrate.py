"""Measuring the `flex` calibration table (see :mod:`palpate.sim.flex_calibration` for what it holds and how it is
used): reference presses on a thick block, each compared with Hertz."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from palpate.core.errors import ValidationError
from palpate.sim.flex import reference_press
from palpate.sim.flex_calibration import CAL_HEIGHT, CAL_POISSON, CAL_RANGE, CAL_YOUNG, FORMAT_VERSION
from palpate.sim.hertz import effective_modulus_rigid, hertz_force


def hertz_ratio(indentation: np.ndarray, force: np.ndarray, young: float, poisson: float, radius: float,
                depth_range: tuple[float, float] = CAL_RANGE) -> float:
    """Least-squares ratio c of force = c * Hertz(d) over the indentations inside ``depth_range`` (m)."""
    d = np.asarray(indentation, dtype=float)
    sel = (d >= depth_range[0]) & (d <= depth_range[1])
    if sel.sum() < 3:
        raise ValidationError(f"hertz_ratio: fewer than 3 samples with indentation in {depth_range} m")
    h = hertz_force(effective_modulus_rigid(young, poisson), radius, d[sel])
    return float(np.dot(h, np.asarray(force)[sel]) / np.dot(h, h))


def measure_calibration(cells_over_radius: list[float], *, radius: float = 0.008, timestep: float = 0.005,
                        path: Path | str | None = None) -> dict:
    """Measure the factor at each cell/radius (see module docstring) and optionally write the table to ``path``.

    Returns:
        the JSON-ready table (also written when ``path`` is given).
    """
    points = []
    for c in cells_over_radius:
        trace = reference_press(young=CAL_YOUNG, poisson=CAL_POISSON, height=CAL_HEIGHT, radius=radius,
                                resolution=c * radius, timestep=timestep, depth=CAL_RANGE[1] * 1.5,
                                calibrate=False)
        press = trace.t <= trace.meta["press_end"]
        factor = hertz_ratio(trace.indentation[press], trace.force[press], CAL_YOUNG, CAL_POISSON, radius)
        # the grid rounds to an even cell count, so key the table by the cell actually used
        cell = float(np.mean(trace.meta["cell"][:2]))
        points.append({"cell_over_radius": round(cell / radius, 4), "factor": round(factor, 4),
                       "cell": cell, "requested_resolution": float(c * radius)})
    table = {
        "version": FORMAT_VERSION,
        "measured_with": {
            "young": CAL_YOUNG, "poisson": CAL_POISSON, "height": CAL_HEIGHT, "radius": radius,
            "timestep": timestep, "depth_range": list(CAL_RANGE), "speed": 0.01,
            "how": "benchmarks/flex_resolution.py --calibrate (palpate.sim.flex_calibrate.measure_calibration)",
        },
        "points": points,
    }
    if path is not None:
        Path(path).write_text(json.dumps(table, indent=1) + "\n")
    return table
