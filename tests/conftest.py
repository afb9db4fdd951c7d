"""Shared pytest fixtures: deterministic random generators and the shipped data folder."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

os.environ.setdefault("MPLBACKEND", "Agg")

DATA = Path(__file__).parent / "data"
REPO = Path(__file__).resolve().parent.parent


@pytest.fixture
def rng() -> np.random.Generator:
    """A seeded generator: every test that draws random numbers is deterministic."""
    return np.random.default_rng(20261122)


@pytest.fixture
def data_dir() -> Path:
    return DATA


@pytest.fixture
def repo_dir() -> Path:
    return REPO


@pytest.fixture(scope="session")
def three_material_memory():
    """A haptic memory over materials m0, m1, m2 fitted on synthetic presses (12 each, 15% spread) whose m0 and
    m1 overlap a little, so a press's predicted outcomes are not all certain (planning tests)."""
    from palpate.core.perception.memory import HapticMemory

    rng = np.random.default_rng(11)
    mus = np.array([[100.0, 1.0, 20.0, 0.5], [160.0, 1.4, 26.0, 0.7], [900.0, 3.0, 60.0, 1.5]])
    x = np.vstack([mu * (1 + 0.15 * rng.standard_normal((12, 4))) for mu in mus])
    names = ["m0", "m1", "m2"]
    return HapticMemory(names).fit(x, [m for m in names for _ in range(12)])
