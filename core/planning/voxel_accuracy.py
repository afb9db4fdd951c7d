"""The accuracy objective on voxel maps: the expected number of voxels one press down a column sets right.

A press fills a column from the surface down to its depth, one posterior per layer it reaches (seed 001), and a
voxel map's post-processing is vertical (eq. 3 and 5), so a press changes only its own column. Per reachable
voxel, the truth is believed as on a 2-D map (:func:`~palpate.core.planning.expected_accuracy.label_belief` within the
voxel's layer: explored voxels of the same layer vote for their material); the press's reading of it is predicted
from the memory's confusion (:func:`~palpate.core.planning.expected_accuracy.confusion_outcomes`), and the gain is the
chance the voxel's most probable material is the true one after the press less that chance now (an undecided voxel
counts as wrong, as the accuracy rule says). When the map's post-processing also fills unexplored voxels from their
explored neighbours in the same layer (``lateral``), each layer is scored as a 2-D map
(:func:`~palpate.core.planning.expected_accuracy.expected_accuracy_gain`: the pressed voxel and the neighbours eq. 6.15
fills from it).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.mapping.accuracy import decided_labels
from palpate.core.mapping.probability import update
from palpate.core.planning.expected_accuracy import confusion_outcomes, expected_accuracy_gain, label_belief
from palpate.core.planning.map_views import is_voxel, layers_reached


@dataclass(frozen=True)
class _Layer:
    """One layer of a voxel map as a 2-D map, (ny, nx, M)."""

    probabilities: np.ndarray
    explored: np.ndarray
    base: float = 10.0
    p_min: float = 1e-6


def _layer(p: np.ndarray, explored: np.ndarray, z: int, base: float, p_min: float) -> _Layer:
    return _Layer(np.ascontiguousarray(np.swapaxes(p[:, :, z], 0, 1)), np.ascontiguousarray(explored[:, :, z].T),
                  base, p_min)


def voxel_accuracy_gain(grid, post, table: tuple[np.ndarray, np.ndarray], max_depth: float | None = None, *,
                        reach: int = 2, correlation_cells: float = 1.0, temperature: float = 0.5,
                        lateral: bool = False) -> np.ndarray:
    """Expected voxels of the post-processed map set right by one press on each column, (ny, nx).

    Args:
        grid, post: the measured voxel map and its post-processed version.
        table: (outcomes (U, M), likelihood (M, U)) of a press, from
            :func:`palpate.core.planning.outcomes.outcome_table`.
        max_depth: deepest press, m (None = the whole column).
        reach, correlation_cells, temperature: the in-layer belief's (see ``label_belief``).
        lateral: the post-processing fills each layer's unexplored voxels from their explored neighbours
            (``VoxelGrid.postprocessed(lateral=True)``): a press then also sets its layer neighbours right.
    """
    if not is_voxel(grid):
        raise ValidationError(f"voxel_accuracy_gain needs a voxel map (nx, ny, nz, M), got probabilities of shape "
                              f"{np.shape(grid.probabilities)}")
    p = np.asarray(grid.probabilities, dtype=float)
    pp = np.asarray(post.probabilities, dtype=float)
    if pp.shape != p.shape:
        raise ValidationError(f"post-processed map has shape {pp.shape}, the map {p.shape}")
    nx, ny, _, m = p.shape
    rep, conf = confusion_outcomes(table)
    if rep.shape != (m, m):
        raise ValidationError(f"outcome table is for {rep.shape[0]} materials, the map has {m}")
    explored = np.asarray(grid.explored, dtype=bool)
    k = layers_reached(grid, max_depth)
    gain = np.zeros((ny, nx))
    for z in range(k):
        layer = _layer(p, explored, z, grid.base, grid.p_min)
        if lateral:
            gain += expected_accuracy_gain(layer, _layer(pp, explored, z, grid.base, grid.p_min), table, reach=reach,
                                           correlation_cells=correlation_cells, temperature=temperature)
            continue
        pz = layer.probabilities
        belief = label_belief(layer, reach=reach, correlation_cells=correlation_cells, temperature=temperature)
        label, decided = decided_labels(np.swapaxes(pp[:, :, z], 0, 1))
        p_named = belief @ conf  # chance the press names each material
        for o in range(m):
            post_t = belief * conf[:, o]
            post_t /= np.maximum(post_t.sum(axis=-1, keepdims=True), 1e-300)
            new_label = np.argmax(update(pz, rep[o], p_min=grid.p_min), axis=-1)
            right_after = np.take_along_axis(post_t, new_label[..., None], -1)[..., 0]
            right_now = np.take_along_axis(post_t, label[..., None], -1)[..., 0] * decided
            gain += p_named[..., o] * (right_after - right_now)
    return gain
