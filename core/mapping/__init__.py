"""Probabilistic material maps: per-cell categorical distributions over the reference materials.

- :mod:`.probability`: validation, entropy and the clamped recursive update (seed 001 eq. 2, 4);
- :mod:`.extrapolation`: post-processing from explored cells (seed 000 eq. 6.15, seed 001 eq. 3, 5);
- :mod:`.neighbourhood`: grid shifts and 3x3 sums shared with planning;
- :mod:`.geometry`: where a map lies (:class:`MapGeometry`), cell centres;
- :mod:`.grids`: :class:`Grid2D` and :class:`VoxelGrid`; :mod:`.map_files`: their NPZ + JSON files;
- :mod:`.accuracy`: the one accuracy rule against ground truth.
"""

from palpate.core.mapping.accuracy import map_accuracy
from palpate.core.mapping.extrapolation import extrapolate_unexplored, extrapolate_vertical, verify_continuity
from palpate.core.mapping.geometry import MapGeometry
from palpate.core.mapping.grids import Grid2D, VoxelGrid, new_map
from palpate.core.mapping.probability import entropy, update

__all__ = ["Grid2D", "MapGeometry", "VoxelGrid", "entropy", "extrapolate_unexplored", "extrapolate_vertical",
           "map_accuracy", "new_map", "update", "verify_continuity"]
