"""How right a map is against ground truth: the one accuracy rule every report, benchmark and map method uses.

A cell is right when its most probable material is the true one *and* that material is decided: a cell whose top
two probabilities differ by no more than :data:`UNDECIDED_MARGIN` (e.g. the uniform prior of an unexplored cell)
counts as wrong, rather than as whichever material happens to come first.
"""

from __future__ import annotations

import numpy as np

UNDECIDED_MARGIN = 1e-9


def decided_labels(p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(most probable material index, decided mask) per cell of probabilities ``p`` (materials on the last axis)."""
    p = np.asarray(p)
    top2 = np.partition(p, p.shape[-1] - 2, axis=-1)[..., -2:]
    return p.argmax(axis=-1), (top2[..., 1] - top2[..., 0]) > UNDECIDED_MARGIN


def map_accuracy(p: np.ndarray, truth: np.ndarray, mask: np.ndarray | None = None) -> float | None:
    """Fraction of cells with a true material (``truth >= 0``, and inside ``mask`` when given) that are right.

    Args:
        p: probabilities, cell shape + (M,).
        truth: true material index per cell (cell shape), -1 where there is none.
        mask: optional boolean cell mask restricting which cells count (e.g. the explored ones).

    Returns:
        The fraction in [0, 1], or None when no cell counts.
    """
    label, decided = decided_labels(p)
    keep = np.asarray(truth) >= 0
    if mask is not None:
        keep &= mask
    n = int(keep.sum())
    if n == 0:
        return None
    return float(np.count_nonzero((label[keep] == truth[keep]) & decided[keep]) / n)
