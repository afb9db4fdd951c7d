"""The committed felt-cell archive of the exploration-families benchmark is read with checks, and only for the
contact law's code it was made with (benchmarks/family_runs.py)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))

import family_runs as fr  # noqa: E402
from scene_families import scene  # noqa: E402

from palpate.core.errors import ValidationError  # noqa: E402


@pytest.fixture
def archive(tmp_path, monkeypatch):
    """Point the benchmark at an archive in tmp_path; returns a writer of its entries."""
    path = tmp_path / "felt_cells.npz"
    monkeypatch.setattr(fr, "FELT_ARCHIVE", path)
    fr._archive.cache_clear()

    def write(**entries):
        np.savez(path, **entries)
        fr._archive.cache_clear()

    yield write
    fr._archive.cache_clear()


def test_an_entry_of_todays_law_is_read(archive):
    fs = scene(100000)
    felt = np.arange(np.prod(fs.grid_cells)).reshape(fs.grid_cells[::-1]) % len(fs.references)
    archive(**{fr._felt_name(fs): felt.astype(np.int8)})
    np.testing.assert_array_equal(fr._archived(fr._felt_name(fs), fs), felt)


def test_an_entry_of_another_laws_code_is_not_used(archive):
    fs = scene(100000)
    felt = np.zeros(fs.grid_cells[::-1], dtype=np.int8)
    archive(**{f"felt_{fs.seed}_0000000000": felt})
    assert fr._felt_name(fs) != f"felt_{fs.seed}_0000000000"
    assert fr._archived(fr._felt_name(fs), fs) is None


@pytest.mark.parametrize("bad", ["shape", "index", "float"])
def test_a_bad_entry_is_refused(archive, bad):
    fs = scene(100000)
    felt = np.zeros(fs.grid_cells[::-1], dtype=np.int8)
    felt = {"shape": felt[:-1], "index": felt + len(fs.references), "float": felt + 0.5}[bad]
    archive(**{fr._felt_name(fs): felt})
    with pytest.raises(ValidationError, match="reference indices"):
        fr._archived(fr._felt_name(fs), fs)


def test_an_oversized_archive_is_refused_before_reading(archive, monkeypatch):
    fs = scene(100000)
    archive(**{fr._felt_name(fs): np.zeros(fs.grid_cells[::-1], dtype=np.int8)})
    monkeypatch.setattr(fr, "MAX_ARCHIVE_BYTES", 10)
    with pytest.raises(ValidationError, match="more than 10"):
        fr._archived(fr._felt_name(fs), fs)
