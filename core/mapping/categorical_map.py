"""What a 2-D grid and a voxel grid have in common: per-cell categorical distributions over the reference
materials, their entropy, MAP estimate and accuracy, fusing measurements into cells (one or many at once), and
writing them to files."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.mapping.accuracy import map_accuracy
from palpate.core.mapping.geometry import check_materials
from palpate.core.mapping.map_files import write_map_files
from palpate.core.mapping.probability import (
    check_base,
    check_mask,
    check_probs,
    entropy,
    sum_last,
    update_cells_inplace,
    update_unchecked,
)


def read_only(arr: np.ndarray) -> np.ndarray:
    view = arr.view()
    view.flags.writeable = False
    return view


class CategoricalMap:
    """Shared behaviour of :class:`~palpate.core.mapping.grids.Grid2D` and
    :class:`~palpate.core.mapping.grids.VoxelGrid`: arrays, entropy, MAP, accuracy, updates, files."""

    _kind = ""
    _axes = ""

    def __init__(self, materials, shape: tuple[int, ...], p_min: float, base: float):
        self.materials = check_materials(materials)
        m = len(self.materials)
        if not (np.isfinite(p_min) and 0 < p_min < 1.0 / m):
            raise ValidationError(f"p_min must be in (0, 1/M) = (0, {1.0 / m:.4g}), got {p_min!r}")
        self.p_min = float(p_min)
        self.base = check_base(base)
        self._p = np.full(shape + (m,), 1.0 / m)
        self._explored = np.zeros(shape, dtype=bool)

    @property
    def probabilities(self) -> np.ndarray:
        """Read-only view of the per-cell distributions; see the class docstring for the axis order."""
        return read_only(self._p)

    @property
    def explored(self) -> np.ndarray:
        """Read-only boolean mask of cells that received at least one measurement."""
        return read_only(self._explored)

    def entropy(self, base: float | None = None) -> np.ndarray:
        """Entropy of every cell, in units of ``base`` (default: the map's base)."""
        return entropy(self._p, base=self.base if base is None else base)

    def mean_entropy(self, base: float | None = None) -> float:
        """Mean entropy over all cells (the seeds' measure of how uncertain the whole map still is)."""
        return float(self.entropy(base).mean())

    def map_estimate(self) -> np.ndarray:
        """Index of the most probable material per cell (maximum a posteriori)."""
        return self._p.argmax(axis=-1)

    def accuracy(self, truth_idx, mask=None) -> float:
        """Fraction of cells whose MAP material equals ``truth_idx`` (the rule of
        :func:`~palpate.core.mapping.accuracy.map_accuracy`: an undecided cell counts as wrong).

        Args:
            truth_idx: int array with the map's cell shape; -1 marks cells with no truth (outside the object or
                a material not in the map), which are ignored.
            mask: optional boolean array of the same shape restricting which cells count (e.g. explored only).

        Raises:
            ValidationError: wrong shape, indices outside [-1, M), or no cell left to count.
        """
        shape = self._p.shape[:-1]
        truth = np.asarray(truth_idx)
        if truth.shape != shape or not np.issubdtype(truth.dtype, np.integer):
            raise ValidationError(f"truth_idx must be an integer array of shape {shape}, got {truth.dtype} "
                                  f"{truth.shape}")
        m = len(self.materials)
        if ((truth < -1) | (truth >= m)).any():
            raise ValidationError(f"truth_idx must be in [-1, {m}) (-1 = no truth), got values outside")
        acc = map_accuracy(self._p, truth, None if mask is None else check_mask(mask, shape, "mask"))
        if acc is None:
            raise ValidationError("accuracy: no cell with a truth label (and inside mask) to count")
        return acc

    def _like(self, p: np.ndarray):
        """A map with this one's geometry and explored mask holding ``p`` (post-processed values): built without
        first filling a uniform array it would throw away."""
        out = object.__new__(type(self))
        out.__dict__.update(self.__dict__)
        out.materials = list(self.materials)
        out._p = p
        out._explored = self._explored.copy()
        return out

    def _with_arrays(self, p: np.ndarray, explored: np.ndarray):
        """Install loaded (already validated) arrays; returns self."""
        self._p = p.astype(float)
        self._explored = explored.copy()
        return self

    def _update_at(self, index: tuple, p_meas) -> None:
        """Fuse a measurement whose shape the caller checked; the map's own cells need no re-validation."""
        try:
            meas = np.asarray(p_meas, dtype=float)
        except (TypeError, ValueError):
            meas = check_probs(p_meas, "likelihood_or_posterior")  # raises, naming what is wrong
        self._p[index] = update_unchecked(self._p[index], meas, self.p_min)
        self._explored[index] = True

    def _update_many(self, cell_index: tuple[np.ndarray, ...], p_meas) -> None:
        """Fuse measurements (n, M) into the cells at ``cell_index`` (one integer array per axis, checked by the
        caller), in order: exactly what one :meth:`_update_at` per measurement would do."""
        m = len(self.materials)
        meas = check_probs(p_meas, "p_meas")
        if meas.shape != (len(cell_index[0]), m):
            raise ValidationError(f"p_meas must have shape ({len(cell_index[0])}, {m}) (one row per cell, one value "
                                  f"per material {self.materials}), got {meas.shape}")
        if meas.size and not (sum_last(meas) > 0).all():
            row = int(np.argmax(~(sum_last(meas) > 0)))
            raise ValidationError(f"p_meas[{row}] is all zero: it has no material in common with any cell")
        flat = np.ravel_multi_index(cell_index, self._explored.shape)
        self._p = np.ascontiguousarray(self._p)  # rows below are views of it
        self._explored = np.ascontiguousarray(self._explored)
        cells = self._p.reshape(-1, m)
        # Updates clamp every cell above zero, but a loaded map may hold exact zeros: then a measurement must share
        # a material with its cell's prior (checked before anything changes).
        # (a batch much smaller than the map looks at its own cells only)
        small = 8 * flat.size < len(cells)
        if flat.size and not (np.take(cells, flat, axis=0) if small else self._p).min() > 0:
            _, first = np.unique(flat, return_index=True)
            disjoint = ~((np.take(cells, flat[first], axis=0) > 0) & (meas[first] > 0)).any(axis=1)
            if disjoint.any():
                row = int(first[np.argmax(disjoint)])
                raise ValidationError(f"p_meas[{row}]: the cell {tuple(int(i[row]) for i in cell_index)} and the "
                                      "measurement have no material with non-zero probability in common")
        update_cells_inplace(cells, flat, meas, self.p_min)
        self._explored.reshape(-1)[flat] = True

    def _meta(self) -> dict:
        return {
            "kind": self._kind,
            "axes": self._axes,
            "materials": list(self.materials),
            "shape": list(self.shape),  # (nx, ny) or (nx, ny, nz), as the constructor takes it
            "cell_size_m": self.cell_size,
            "origin_m": list(self.origin),
            "base": self.base,
            "p_min": self.p_min,
        }

    def save(self, path) -> tuple[Path, Path]:
        """Write the map: arrays to ``path`` (NPZ, no pickled objects) and metadata to the same name with .json.

        Returns:
            (npz path, json path).
        """
        return write_map_files(path, self._p, self._explored, self._meta())


def cell_indices(named: dict[str, object], sizes: tuple[int, ...]) -> tuple[np.ndarray, ...]:
    """Index arrays of a batch of cells, validated: one 1-D integer array per axis (``named`` maps each axis's
    name to its indices, in the order of ``sizes``), all of one length, each index in [0, size)."""
    out = []
    n = None
    for (name, values), size in zip(named.items(), sizes, strict=True):
        arr = np.asarray(values)
        if arr.ndim != 1 or not (np.issubdtype(arr.dtype, np.integer) or arr.size == 0):
            raise ValidationError(f"{name} must be a 1-D array of integer cell indices, got {arr.dtype} {arr.shape}")
        if n is not None and len(arr) != n:
            raise ValidationError(f"{name} has {len(arr)} indices, the others {n}; give one per measurement")
        n = len(arr)
        if n and (arr.min() < 0 or arr.max() >= size):
            bad = int(np.argmax((arr < 0) | (arr >= size)))
            raise ValidationError(f"{name}[{bad}] = {arr[bad]} is outside the grid (0 <= {name} < {size})")
        out.append(arr.astype(np.intp, copy=False))
    return tuple(out)

