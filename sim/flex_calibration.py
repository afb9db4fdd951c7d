"""Modulus calibration of the `flex` fidelity: how much stiffer the trilinear flex block is than Hertz.

A `dof="trilinear"` flexcomp interpolates displacement over cells much larger than the Hertz contact radius, so
a block of Young's modulus E answers a sphere press with about twice the Hertz force. The ratio depends mostly on
the cell size relative to the tip radius, so it is stored as a table of ``factor`` against ``cell/radius``
(models/flex_calibration.json) and the flex level builds the block with ``E / factor``.

How the table is measured (:func:`palpate.sim.flex_calibrate.measure_calibration`, rerun by
``benchmarks/flex_resolution.py --calibrate``): a homogeneous block of the reference material (200 kPa, nu 0.3), as
wide as the default press window and ``CAL_HEIGHT`` thick, is pressed at 10 mm/s with the uncalibrated modulus;
``factor`` is the least-squares ratio of the simulated force to the Hertz force F = 4/3 E/(1-nu^2) sqrt(R) d^1.5
over indentations ``CAL_RANGE``.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.world.resources import models_dir

#: The shipped table.
CALIBRATION_PATH = models_dir() / "flex_calibration.json"
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
