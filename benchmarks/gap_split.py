"""Gap splitting for the exploration benchmarks: info_gain that first presses inside the lattice's gaps.

After info_gain's starting lattice, a wall between two presses that read different materials lies somewhere in the
unpressed run between them, and eq. 6.15 fills that run from its ends: where inside the gap the wall lies, nothing
has pinned (docs/results.md, "Estimating where a press would read otherwise"). This policy enumerates those
gaps along rows, columns and both diagonals (two presses at most ``spread_stride`` cells apart, only unpressed cells
between, readings that differ) and, before each of info_gain's greedy choices, presses the unpressed cell that lies
inside the most gaps (a greedy set cover, recomputed after every press so each reading re-splits what it touched;
ties go to info_gain's value). ``gap_min_cells`` sets how short a gap stops being split (2: one bisection of the
lattice's gaps; 1: until every wall sits between adjacent presses); ``gap_agree`` also counts gaps whose ends agree
but pass within ``gap_reach`` cells of a press of another material, at that weight; ``gap_every`` interleaves: one
split, then ``gap_every - 1`` greedy choices; ``gap_weight`` > 0 drops the priority and adds that many cells of value
per gap to info_gain's instead. Nothing reads the scene generator or its families. A candidate, not shipped: on the
tuning seeds it lowers the tail of the block its variants were chosen on and not of the other, at a higher median
(docs/results.md, "Splitting the lattice's gaps").

Run through benchmarks/exploration_families.py (``--policies ...,gap_split``, offline only; ``--info-gain`` settings
apply to it, ``--gap FIELD=VALUE`` sets the fields below).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from family_runs import Run, offline_run
from scene_families import FamilyScene

from palpate.core.errors import ValidationError
from palpate.core.mapping.accuracy import decided_labels
from palpate.core.planning.info_gain import InfoGain
from palpate.core.planning.map_views import argmax_cell, target_depth
from palpate.core.planning.policies import Target

#: Steps (dy, dx) of the lines gaps are looked for along: rows, columns, both diagonals.
DIRECTIONS = ((0, 1), (1, 0), (1, 1), (1, -1))
#: ``--gap`` fields a sweep may set (numbers).
GAP_FIELDS = ("gap_min_cells", "gap_agree", "gap_reach", "gap_every", "gap_weight")


def readings(grid) -> np.ndarray:
    """(ny, nx) the pressed cells' most probable measured material (-1 where undecided or unpressed)."""
    label, decided = decided_labels(np.asarray(grid.probabilities))
    return np.where(decided & np.asarray(grid.explored, dtype=bool), label, -1)


def _shift(a: np.ndarray, dy: int, dx: int, fill) -> np.ndarray:
    """``a`` moved so that out[y, x] = a[y + dy, x + dx] (``fill`` off the grid)."""
    ny, nx = a.shape[:2]
    out = np.full_like(a, fill)
    ys, yd = (slice(0, ny - dy), slice(dy, ny)) if dy >= 0 else (slice(-dy, ny), slice(0, ny + dy))
    xs, xd = (slice(0, nx - dx), slice(dx, nx)) if dx >= 0 else (slice(-dx, nx), slice(0, nx + dx))
    out[ys, xs] = a[yd, xd]
    return out


def near_other(explored: np.ndarray, label: np.ndarray, reach: float) -> np.ndarray:
    """(ny, nx, M + 1) True where a press that read material m (index m + 1; 0 = undecided) lies within ``reach``
    cells (Euclidean) of the cell."""
    r = int(np.floor(reach))
    m = int(label.max()) + 2
    onehot = np.zeros((*label.shape, m), dtype=bool)
    ys, xs = np.nonzero(explored)
    onehot[ys, xs, label[ys, xs] + 1] = True
    out = np.zeros_like(onehot)
    for dy in range(-r, r + 1):
        for dx in range(-r, r + 1):
            if dy * dy + dx * dx <= reach * reach:
                out |= _shift(onehot, dy, dx, False)
    return out


def gap_counts(explored: np.ndarray, label: np.ndarray, stride: int, min_cells: int = 1, agree: float = 0.0,
               reach: float = 2.8) -> np.ndarray:
    """(ny, nx) per unpressed cell, how many gaps it lies inside (weighted).

    A gap: two pressed cells on a row, column or diagonal, 2 to ``stride`` steps apart with only unpressed cells
    (at least ``min_cells``) between. One whose ends read differently (an undecided reading differs from every
    other) counts 1 on each cell between; one whose ends agree counts ``agree`` on each cell between that has a
    press of another material within ``reach`` cells (0: such gaps are not counted).
    """
    explored = np.asarray(explored, dtype=bool)
    label = np.asarray(label)
    count = np.zeros(label.shape)
    other = near_other(explored, label, reach) if agree > 0 else None
    for dy, dx in DIRECTIONS:
        for k in range(max(2, min_cells + 1), int(stride) + 1):
            end = _shift(explored, k * dy, k * dx, False)
            end_label = _shift(label, k * dy, k * dx, -2)
            between = np.ones_like(explored)
            for j in range(1, k):
                between &= ~_shift(explored, j * dy, j * dx, True)
            gap = explored & end & between
            differ = gap & (label != end_label)
            same = gap & (label == end_label)
            for j in range(1, k):
                # a gap starting at (y, x) covers (y + j dy, x + j dx): shift its mask the other way
                count += _shift(differ, -j * dy, -j * dx, False)
                if other is not None and same.any():
                    cover = _shift(same, -j * dy, -j * dx, False)
                    lab = _shift(np.where(same, label, -2), -j * dy, -j * dx, -2)
                    # a press of a material other than the gap's ends within reach of the cell
                    seen = other.copy()
                    ys, xs = np.nonzero(cover)
                    seen[ys, xs, lab[ys, xs] + 1] = False
                    count += agree * (cover & seen.any(axis=2))
    return np.where(explored, 0.0, count)


@dataclass
class GapSplit(InfoGain):
    """info_gain that presses inside the lattice's gaps before its greedy choices (module docstring).

    Args (beyond :class:`~palpate.core.planning.info_gain.InfoGain`'s):
        gap_min_cells: a gap with fewer unpressed cells between its ends is not split (>= 1).
        gap_agree: weight of a gap whose ends agree, on cells near a press of another material (0 = none).
        gap_reach: that nearness, cells.
        gap_every: one split per ``gap_every`` choices after the lattice (1 = split while any gap is left).
        gap_weight: 0 = a split comes first (the cell in most gaps, ties to info_gain's value); > 0 = no priority:
            this many cells of value per gap are added to info_gain's value instead.
    """

    gap_min_cells: int = 1
    gap_agree: float = 0.0
    gap_reach: float = 2.8
    gap_every: int = 1
    gap_weight: float = 0.0
    _after_lattice: int = dataclasses.field(default=0, init=False, repr=False)

    def __post_init__(self) -> None:
        super().__post_init__()
        if int(self.gap_min_cells) < 1 or int(self.gap_every) < 1:
            raise ValidationError("gap_min_cells and gap_every must be >= 1")
        if not (np.isfinite(self.gap_agree) and self.gap_agree >= 0 and self.gap_reach >= 1):
            raise ValidationError("gap_agree must be >= 0 and gap_reach >= 1 cell")
        if not (np.isfinite(self.gap_weight) and self.gap_weight >= 0):
            raise ValidationError("gap_weight must be a finite number >= 0")

    def next_target(self, grid, post=None, last=None) -> Target | None:
        got = super().next_target(grid, post, last)
        if got is None or self.lattice_cell(grid, last) is not None:
            return got
        turn = self._after_lattice % int(self.gap_every)
        self._after_lattice += 1
        if turn:
            return got
        counts = gap_counts(np.asarray(grid.explored, dtype=bool), readings(grid), max(2, int(self.spread_stride)),
                            int(self.gap_min_cells), float(self.gap_agree), float(self.gap_reach))
        top = counts.max()
        if top <= 0:
            return got
        value = self._terms[0] if self._terms is not None else np.zeros(counts.shape)
        if self.gap_weight > 0:
            allowed = self._terms[2] if self._terms is not None else counts > 0
            cell = argmax_cell(value + self.gap_weight * counts, allowed)
            if cell is None:
                return got
            return Target(cell[0], cell[1], target_depth(grid, post, cell[0], cell[1], self.max_depth), got.score)
        cell = argmax_cell(np.where(counts >= top, value, -np.inf), counts >= top)
        if cell is None:
            return got
        return Target(cell[0], cell[1], target_depth(grid, post, cell[0], cell[1], self.max_depth), got.score)


def with_gaps(policy: InfoGain, **gap) -> GapSplit:
    """A :class:`GapSplit` with every setting of ``policy`` (an info_gain policy) and the ``gap`` fields."""
    kept = {f.name: getattr(policy, f.name) for f in dataclasses.fields(InfoGain) if f.init}
    return GapSplit(**kept, **gap)


def gap_run(fs: FamilyScene, *, stop_at: float | None = None, settings: dict | None = None,
            gap: dict | None = None) -> Run:
    """The gap-splitting planner on one scene, presses answered offline as info_gain's (benchmarks/family_runs.py)."""
    unknown = sorted(set(gap or {}) - set(GAP_FIELDS))
    if unknown:
        raise ValidationError(f"unknown gap settings {unknown}; known: {', '.join(GAP_FIELDS)}")
    return offline_run(fs, "info_gain", stop_at=stop_at, settings=settings,
                       policy_for=lambda policy, truth: with_gaps(policy, **(gap or {})))
