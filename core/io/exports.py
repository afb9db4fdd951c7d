"""Export of what exploration perceived as a haptic material (seed 002): the post-processed probabilities plus
per-cell palpation features (rate-hardness, contact-area spread rate, local indentation)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from palpate.core import __version__
from palpate.core.errors import ValidationError
from palpate.core.mapping.grids import Grid2D
from palpate.core.perception.press import PressResult
from palpate.core.world.haptic_material import HapticMaterialMap
from palpate.core.world.scenario import Scenario


def export_haptic_material(post: Grid2D, grid: Grid2D, results: Sequence[PressResult], scenario: Scenario,
                           folder: Path, name: str) -> Path:
    """Write the seed 002 export of one explored object: probabilities plus per-cell palpation features."""
    probs = np.asarray(post.probabilities)
    ny, nx = probs.shape[:2]
    sums = {k: np.zeros((ny, nx)) for k in ("rate_hardness", "contact_area_spread_rate", "local_indentation")}
    counts = np.zeros((ny, nx))
    newton_per_count = scenario.fingertip.sensel_area / scenario.taxels.gain
    for r in results:
        if r.fit is None or r.press.n_samples < 3:
            continue
        try:
            ix, iy = grid.cell_of(*r.location)
        except ValidationError:
            continue
        force = r.press.c_P * newton_per_count
        sums["rate_hardness"][iy, ix] += _initial_slope(r.press.c_D, force)
        sums["contact_area_spread_rate"][iy, ix] += _initial_slope(r.press.c_A, force, whole=True)
        sums["local_indentation"][iy, ix] += r.depth
        counts[iy, ix] += 1
    measured = counts > 0
    feats = {k: np.where(measured, v / np.maximum(counts, 1), 0.0) for k, v in sums.items()}
    hm = HapticMaterialMap(tuple(grid.origin), float(grid.cell_size), list(scenario.references), probs, feats,
                           measured, meta={"object": name, "scenario": scenario.name, "palpate": __version__,
                                           "force_calibration_N_per_count": newton_per_count})
    return hm.write(folder)


def _initial_slope(x: np.ndarray, y: np.ndarray, whole: bool = False) -> float:
    """dy/dx by least squares over the first third of the press (or all of it): the 'initial rate' of seed 002."""
    n = len(x) if whole else max(3, len(x) // 3)
    xs, ys = np.asarray(x[:n], float), np.asarray(y[:n], float)
    dx = xs - xs.mean()
    denom = float(dx @ dx)
    if denom <= 0 or not np.isfinite(denom):
        return 0.0
    return max(0.0, float(dx @ (ys - ys.mean())) / denom)
