"""Modulus calibration of the `flex` fidelity: how much stiffer the trilinear flex block is than Hertz.

A `dof="trilinear"` flexcomp interpolates displacement over cells much larger than the Hertz contact radius, so
a block of Young's modulus E answers a sphere press with about twice the Hertz force. The ratio depends mostly on
the cell size relative to the tip radius, so it is stored as a table of ``factor`` against ``cell/radius``
(models/flex_calibration.json) and the flex level builds the block with ``E / factor``.

How the table is measured (:func:`measure_calibration`, rerun by ``benchmarks/flex_resolution.py --calibrate``):
a homogeneous block of the reference material (200 kPa, nu 0.3), as wide as the default press window and
``CAL_HEIGHT`` thick, is pressed at 10 mm/s with the uncalibrated modulus; ``factor`` is the least-squares ratio
of the simulated force to the Hertz force F = 4/3 E/(1-nu^2) sqrt(R) d^1.5 over indentations ``CAL_RANGE``.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from palpate.core.errors import ValidationError

#: The shipped table.
CALIBRATION_PATH = Path(__file__).resolve().parent.parent / "models" / "flex_calibration.json"
#: Indentation range over which force is matched to Hertz, m ("small indentation").
CAL_RANGE = (0.0003, 0.0015)
#: Thickness of the calibration block, m (several contact radii at the top of CAL_RANGE).
CAL_HEIGHT = 0.02
#: Reference material of the calibration: Young's modulus Pa, Poisson ratio.
CAL_YOUNG = 2.0e5
CAL_POISSON = 0.3
FORMAT_VERSION = 1


def load_calibration(path: Path | str = CALIBRATION_PATH) -> dict:
    """Read and validate a calibration table.

    Returns:
        dict with "cell_over_radius" and "factor" (sorted float arrays, factor > 0) and the file's "measured_with".

    Raises:
        ValidationError: missing file, bad JSON, wrong version, or a bad key, naming the file and the key.
    """
    path = Path(path)
    try:
        raw = json.loads(path.read_text())
    except FileNotFoundError:
        raise ValidationError(
            f"{path}: flex calibration table not found; regenerate it with "
            "`.venv/bin/python benchmarks/flex_resolution.py --calibrate`"
        ) from None
    except json.JSONDecodeError as exc:
        raise ValidationError(f"{path}: not valid JSON (line {exc.lineno}): {exc.msg}") from None
    if not isinstance(raw, dict) or raw.get("version") != FORMAT_VERSION:
        raise ValidationError(f"{path}: key 'version' must be {FORMAT_VERSION}, got {raw.get('version')!r}")
    points = raw.get("points")
    if not isinstance(points, list) or not points:
        raise ValidationError(f"{path}: key 'points' must be a non-empty list of {{cell_over_radius, factor}}")
    rows = []
    for i, p in enumerate(points):
        try:
            c, f = float(p["cell_over_radius"]), float(p["factor"])
        except (KeyError, TypeError, ValueError):
            raise ValidationError(f"{path}: points[{i}] needs numeric 'cell_over_radius' and 'factor'") from None
        if not (np.isfinite(c) and c > 0 and np.isfinite(f) and f > 0):
            raise ValidationError(f"{path}: points[{i}] must have cell_over_radius > 0 and factor > 0, got {p}")
        rows.append((c, f))
    rows.sort()
    arr = np.array(rows)
    if np.any(np.diff(arr[:, 0]) <= 0):
        raise ValidationError(f"{path}: 'points' repeat a cell_over_radius value")
    return {"cell_over_radius": arr[:, 0], "factor": arr[:, 1], "measured_with": raw.get("measured_with", {})}


def modulus_factor(cell: float, radius: float, table: dict | None = None) -> tuple[float, bool]:
    """Stiffness factor of the flex block for cells of edge ``cell`` (m) under a tip of ``radius`` (m).

    Returns:
        (factor, extrapolated): divide E by factor to match Hertz at small indentation; extrapolated is True when
        cell/radius lies outside the measured table (the nearest end is used).
    """
    tab = load_calibration() if table is None else table
    x = cell / radius
    xs, fs = tab["cell_over_radius"], tab["factor"]
    extrapolated = bool(x < xs[0] * 0.999 or x > xs[-1] * 1.001)
    return float(np.interp(x, xs, fs)), extrapolated


def hertz_force(indentation: np.ndarray, young: float, poisson: float, radius: float) -> np.ndarray:
    """Hertz force of a rigid sphere (radius m) on an elastic half-space, N: 4/3 E/(1-nu^2) sqrt(R) d^1.5."""
    d = np.clip(np.asarray(indentation, dtype=float), 0.0, None)
    return 4.0 / 3.0 * young / (1.0 - poisson**2) * np.sqrt(radius) * d**1.5


def hertz_ratio(indentation: np.ndarray, force: np.ndarray, young: float, poisson: float, radius: float,
                depth_range: tuple[float, float] = CAL_RANGE) -> float:
    """Least-squares ratio c of force = c * Hertz(d) over the indentations inside ``depth_range`` (m)."""
    d = np.asarray(indentation, dtype=float)
    sel = (d >= depth_range[0]) & (d <= depth_range[1])
    if sel.sum() < 3:
        raise ValidationError(f"hertz_ratio: fewer than 3 samples with indentation in {depth_range} m")
    h = hertz_force(d[sel], young, poisson, radius)
    return float(np.dot(h, np.asarray(force)[sel]) / np.dot(h, h))


def measure_calibration(cells_over_radius: list[float], *, radius: float = 0.008, timestep: float = 0.005,
                        path: Path | str | None = None) -> dict:
    """Measure the factor at each cell/radius (see module docstring) and optionally write the table to ``path``.

    Returns:
        the JSON-ready table (also written when ``path`` is given).
    """
    # imported here: sim.flex imports this module for the lookup
    from palpate.sim.flex import reference_press

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
            "how": "benchmarks/flex_resolution.py --calibrate (palpate.sim.flex_calibration.measure_calibration)",
        },
        "points": points,
    }
    if path is not None:
        Path(path).write_text(json.dumps(table, indent=1) + "\n")
    return table
