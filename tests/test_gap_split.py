"""The gap-splitting candidate (benchmarks/gap_split.py): its gap counts against a brute force over every pair of
presses, the policy presses inside a gap between presses that read differently once the lattice is done and
chooses as info_gain where no gap is left, and --gap FIELD=VALUE takes only its fields."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))

from exploration_families import parse_gap  # noqa: E402
from gap_split import DIRECTIONS, GapSplit, gap_counts  # noqa: E402

from palpate.core.errors import ValidationError  # noqa: E402
from palpate.core.mapping.grids import Grid2D  # noqa: E402
from palpate.core.planning.info_gain import InfoGain  # noqa: E402
from palpate.core.planning.outcomes import outcome_posteriors  # noqa: E402


def brute_counts(explored, label, stride, min_cells, agree, reach):
    """Every pair of presses along every direction, walked cell by cell."""
    ny, nx = label.shape
    out = np.zeros((ny, nx))
    presses = [(y, x) for y in range(ny) for x in range(nx) if explored[y, x]]
    for y, x in presses:
        for dy, dx in DIRECTIONS:
            for k in range(2, stride + 1):
                ey, ex = y + k * dy, x + k * dx
                if not (0 <= ey < ny and 0 <= ex < nx) or not explored[ey, ex]:
                    continue
                cells = [(y + j * dy, x + j * dx) for j in range(1, k)]
                if any(explored[c] for c in cells) or len(cells) < min_cells:
                    continue
                for c in cells:
                    if label[y, x] != label[ey, ex]:
                        out[c] += 1
                    elif agree > 0 and any(label[p] != label[y, x] and (p[0] - c[0]) ** 2 + (p[1] - c[1]) ** 2
                                           <= reach ** 2 for p in presses):
                        out[c] += agree
    return out


@pytest.mark.parametrize("stride,min_cells,agree", [(3, 1, 0.0), (3, 2, 0.0), (4, 1, 0.5), (2, 1, 0.25)])
def test_gap_counts_match_a_brute_force(stride, min_cells, agree):
    rng = np.random.default_rng(stride * 10 + min_cells)
    for _ in range(6):
        ny, nx = rng.integers(4, 10, size=2)
        explored = rng.random((ny, nx)) < 0.35
        label = np.where(explored, rng.integers(-1, 3, size=(ny, nx)), -1)
        got = gap_counts(explored, label, stride, min_cells, agree, 2.8)
        assert np.allclose(got, brute_counts(explored, label, stride, min_cells, agree, 2.8))


def lattice_map(memory, wall_x: int | None):
    """A 10 x 10 map with info_gain's stride-3 lattice pressed: m0 left of column ``wall_x``, m1 from it on
    (None: m0 everywhere)."""
    answers = outcome_posteriors(memory, 20, seed=1)
    grid = Grid2D(["m0", "m1", "m2"], (10, 10))
    for iy in range(0, 10, 3):
        for ix in range(0, 10, 3):
            material = int(wall_x is not None and ix >= wall_x)
            grid.update_cell(ix, iy, answers[material, 0])
    return grid


def test_after_the_lattice_it_presses_inside_a_gap_whose_ends_differ(three_material_memory):
    grid = lattice_map(three_material_memory, 5)  # the wall between lattice columns 3 and 6
    for weight in (0.0, 0.5):
        policy = GapSplit(three_material_memory, gap_weight=weight)
        t = policy.next_target(grid, grid.postprocessed(), (9, 9))
        assert t is not None and t.ix in (4, 5), (weight, t)


def test_without_gaps_it_chooses_as_info_gain(three_material_memory):
    grid = lattice_map(three_material_memory, None)
    post = grid.postprocessed()
    plain = InfoGain(three_material_memory).next_target(grid, post, (9, 9))
    got = GapSplit(three_material_memory).next_target(grid, post, (9, 9))
    assert (got.ix, got.iy) == (plain.ix, plain.iy)


def test_settings_are_checked(capsys):
    assert parse_gap(argparse.ArgumentParser(), ["gap_min_cells=2", "gap_weight=0.5"]) == {
        "gap_min_cells": 2, "gap_weight": 0.5}
    for bad in ("entropy_weight=1", "gap_weight", "gap_every=two"):
        with pytest.raises(SystemExit):
            parse_gap(argparse.ArgumentParser(prog="exploration_families.py"), [bad])
        assert "--gap" in capsys.readouterr().err
    with pytest.raises(ValidationError):
        GapSplit(memory=None, gap_every=0)
