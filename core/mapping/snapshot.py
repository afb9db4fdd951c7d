"""A map's state at one moment of an exploration, kept for figures and reports."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class MapSnapshot:
    """Copies of a map's probabilities and explored mask, with a label (e.g. "k = 5", "post-processed")."""

    label: str
    probabilities: np.ndarray
    explored: np.ndarray

    @classmethod
    def of(cls, grid, label: str) -> MapSnapshot:
        """Snapshot of a Grid2D or VoxelGrid (the arrays are copied)."""
        return cls(label, np.array(grid.probabilities), np.array(grid.explored))
