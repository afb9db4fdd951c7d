"""Property-based checks of palpate.core.mapping.grids: invariants that must hold for any finite input."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from palpate.core import mapping as maps
from palpate.core.errors import ValidationError

SETTINGS = settings(max_examples=60, deadline=None, derandomize=True,
                    suppress_health_check=[HealthCheck.too_slow])

# Likelihood values spanning many decades, including exact zeros and tiny subnormal-adjacent numbers.
likelihood_values = st.one_of(st.just(0.0), st.floats(1e-300, 1e300, allow_nan=False, allow_infinity=False))


@st.composite
def cells_and_measurements(draw):
    m = draw(st.integers(2, 5))
    n = draw(st.integers(1, 6))
    p_min = draw(st.sampled_from([1e-9, 1e-6, 1e-3]))
    prior = draw(hnp.arrays(float, (n, m), elements=st.floats(0.0, 1.0)))
    prior = prior + 1e-3  # a map prior is never all zero; scale is irrelevant
    meas = draw(st.lists(hnp.arrays(float, (n, m), elements=likelihood_values), min_size=1, max_size=8))
    return prior, meas, p_min


def _bounds_ok(p: np.ndarray, p_min: float) -> None:
    m = p.shape[-1]
    assert np.all(np.isfinite(p))
    np.testing.assert_allclose(p.sum(axis=-1), 1.0, atol=1e-9)
    # clamp then renormalise: the floor shrinks by at most 1 + (M-1) p_min
    floor = p_min / (1 + (m - 1) * p_min)
    assert p.min() >= floor * (1 - 1e-9)
    assert p.max() <= 1 - (m - 1) * floor + 1e-15  # 1e-15: float64 spacing near 1


@SETTINGS
@given(cells_and_measurements())
def test_repeated_updates_stay_valid_probabilities(data):
    prior, meas, p_min = data
    p = prior
    for z in meas:
        # an all-zero likelihood row carries no usable evidence and is rejected; skip those rows here
        z = np.where(z.sum(axis=-1, keepdims=True) > 0, z, 1.0)
        p = maps.update(p, z, p_min=p_min)
        _bounds_ok(p, p_min)


@SETTINGS
@given(cells_and_measurements())
def test_update_order_does_not_matter_without_clamping(data):
    prior, meas, _ = data
    meas = [np.where(z > 0, z, 1.0) for z in meas]  # no zeros, so each product is informative
    meas = [np.clip(z, 1e-3, 1e3) for z in meas]  # keep every cell far from the clamp
    fwd, bwd = prior, prior
    for z in meas:
        fwd = maps.update(fwd, z, p_min=1e-300)
    for z in reversed(meas):
        bwd = maps.update(bwd, z, p_min=1e-300)
    np.testing.assert_allclose(fwd, bwd, rtol=1e-9, atol=1e-300)


@st.composite
def grids(draw, ndim_grid: int = 2):
    m = draw(st.integers(2, 4))
    shape = tuple(draw(st.integers(1, 6)) for _ in range(ndim_grid))
    raw = draw(hnp.arrays(float, shape + (m,), elements=st.floats(0.0, 1.0)))
    # make a few cells exactly certain and the rest arbitrary (but normalised)
    raw = raw + 1e-12
    p = raw / raw.sum(axis=-1, keepdims=True)
    certain = draw(hnp.arrays(bool, shape))
    onehot = np.eye(m)[np.argmax(p, axis=-1)]
    p = np.where(certain[..., None], onehot, p)
    explored = draw(hnp.arrays(bool, shape))
    return p, explored


@SETTINGS
@given(grids(2))
def test_extrapolate_unexplored_keeps_distributions(data):
    p, explored = data
    with np.errstate(all="raise"):
        out = maps.extrapolate_unexplored(p, explored)
    assert np.all(np.isfinite(out)) and out.min() >= 0
    np.testing.assert_allclose(out.sum(axis=-1), 1.0, atol=1e-9)
    np.testing.assert_array_equal(out[explored], p[explored])
    changed = np.any(out != p, axis=-1)
    assert not (changed & explored).any()


@SETTINGS
@given(grids(3))
def test_vertical_stages_keep_distributions(data):
    p, explored = data
    with np.errstate(all="raise"):
        for fn in (maps.extrapolate_vertical, maps.verify_continuity):
            out = fn(p, explored)
            assert np.all(np.isfinite(out)) and out.min() >= 0
            np.testing.assert_allclose(out.sum(axis=-1), 1.0, atol=1e-9)
            # each output is a convex combination of inputs in its column: never outside their per-column range
            assert np.all(out <= p.max(axis=-2, keepdims=True) + 1e-12)
            assert np.all(out >= p.min(axis=-2, keepdims=True) - 1e-12)


@SETTINGS
@given(st.integers(2, 4), st.integers(1, 5),
       st.sampled_from([np.nan, np.inf, -np.inf, -1e-3, -5.0]), st.data())
def test_bad_values_are_rejected(m, n, bad, data):
    good = np.full((n, m), 1.0 / m)
    idx = (data.draw(st.integers(0, n - 1)), data.draw(st.integers(0, m - 1)))
    corrupted = good.copy()
    corrupted[idx] = bad
    with pytest.raises(ValidationError, match=r"finite|non-negative"):
        maps.update(good, corrupted)
    with pytest.raises(ValidationError, match=r"finite|non-negative"):
        maps.update(corrupted, good)
    with pytest.raises(ValidationError, match=r"finite|non-negative"):
        maps.entropy(corrupted)
    grid = np.broadcast_to(good, (2, n, m)).copy()
    grid[(0,) + idx] = bad
    with pytest.raises(ValidationError, match=r"finite|non-negative"):
        maps.extrapolate_unexplored(grid, np.zeros((2, n), dtype=bool))


@SETTINGS
@given(st.integers(2, 4), st.integers(1, 4), st.integers(1, 4))
def test_wrong_shapes_are_rejected(m, n, extra):
    prior = np.full((n, m), 1.0 / m)
    with pytest.raises(ValidationError, match="broadcast"):
        maps.update(prior, np.ones(m + extra))
    with pytest.raises(ValidationError, match="broadcast"):
        maps.update(prior, np.ones((n + extra, m)))
    with pytest.raises(ValidationError, match="explored"):
        maps.extrapolate_unexplored(prior[None], np.zeros((1, n + extra), dtype=bool))
    with pytest.raises(ValidationError, match="explored"):
        maps.verify_continuity(prior, np.zeros(n + extra, dtype=bool))
