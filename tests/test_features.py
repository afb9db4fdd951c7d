"""Contact features c_P, c_A (eq. 6.2, 6.3) and height along the press axis, computed by hand on small arrays."""

from __future__ import annotations

import numpy as np
import pytest

from palpate.core.errors import ValidationError
from palpate.core.perception.features import contact_features
from palpate.core.perception.sync import SyncedStream

AREA = 4e-6  # m^2 (2 mm pitch)

COUNTS = np.array(
    [
        [[0, 0, 0, 0], [0, 0, 0, 0], [0, 0, 0, 0], [0, 0, 0, 0]],
        [[0, 1, 0, 0], [0, 2, 3, 0], [0, 0, 0, 0], [0, 0, 0, 0]],
        [[0, 5, 1, 0], [2, 40, 30, 0], [0, 10, 255, 0], [0, 0, 0, 3]],
    ],
    dtype=np.uint8,
)


def _stream(counts=COUNTS, position=None):
    n = len(counts)
    pos = np.array([[0.01, 0.02, 0.035], [0.011, 0.021, 0.034], [0.012, 0.022, 0.031]])[:n]
    return SyncedStream(
        t=np.arange(n) * 0.02,
        counts=counts,
        sensel_area=AREA,
        position=pos if position is None else position,
        quaternion=np.tile([1.0, 0, 0, 0], (n, 1)),
        valid=np.array([True, False, True])[:n],
    )


def test_c_p_and_c_a_by_hand():
    s = contact_features(_stream())
    # Frame 2: 5+1+2+40+30+10+255+3 = 346 over 8 active sensels; uint8 sums must not wrap at 255.
    assert s.c_P.tolist() == [0.0, 6.0, 346.0]
    assert s.c_A == pytest.approx([0.0, 3 * AREA, 8 * AREA])
    assert s.height == pytest.approx([0.035, 0.034, 0.031])
    assert s.z == pytest.approx([0.035, 0.034, 0.031])
    np.testing.assert_allclose(s.xy, [[0.01, 0.02], [0.011, 0.021], [0.012, 0.022]])
    assert s.valid.tolist() == [True, False, True]
    assert not s.calibrated


def test_noise_threshold_silences_low_sensels_for_both_features():
    s = contact_features(_stream(), noise_threshold=2)
    # Only counts > 2 remain: frame 1 -> 3; frame 2 -> 5+40+30+10+255+3.
    assert s.c_P.tolist() == [0.0, 3.0, 343.0]
    assert s.c_A == pytest.approx([0.0, AREA, 6 * AREA])
    s = contact_features(_stream(), noise_threshold=254)
    assert s.c_P.tolist() == [0.0, 0.0, 255.0] and s.c_A == pytest.approx([0, 0, AREA])


def test_scalar_and_callable_calibration():
    s = contact_features(_stream(), calibration=0.01)
    assert s.c_P == pytest.approx([0.0, 0.06, 3.46]) and s.calibrated
    # A per-sensel nonlinear map; thresholded sensels contribute nothing even if the map gives them a force.
    s = contact_features(_stream(), calibration=lambda c: 0.001 * c**2 + 0.5, noise_threshold=2)
    expected = 0.001 * np.array([9.0, 25 + 1600 + 900 + 100 + 255**2 + 9]) + 0.5 * np.array([1, 6])
    assert s.c_P[1:] == pytest.approx(expected)
    assert s.c_P[0] == 0.0


def test_press_axis_defines_height():
    pos = np.array([[0.01, 0.02, 0.035], [0.011, 0.021, 0.034], [0.012, 0.022, 0.031]])
    s = contact_features(_stream(position=pos), press_axis=(1.0, 0.0, 0.0))
    assert s.height == pytest.approx(-pos[:, 0])
    s = contact_features(_stream(position=pos), press_axis=(0.0, 0.0, -3.0))  # normalised
    assert s.height == pytest.approx(pos[:, 2])


def test_to_samples_measures_c_d_from_first_contact():
    samples = contact_features(_stream()).to_samples()
    assert [smp.c_D for smp in samples] == pytest.approx([-0.001, 0.0, 0.003])
    assert samples[2].c_P == 346.0 and samples[2].xy == pytest.approx((0.012, 0.022)) and samples[2].z == 0.031
    assert [smp.c_D for smp in contact_features(_stream()).to_samples(h0=0.035)] == pytest.approx([0, 0.001, 0.004])


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"noise_threshold": -1}, "noise_threshold"),
        ({"noise_threshold": 255}, "noise_threshold"),
        ({"noise_threshold": 1.5}, "noise_threshold"),
        ({"calibration": -0.1}, "calibration"),
        ({"calibration": float("nan")}, "calibration"),
        ({"calibration": "fast"}, "calibration"),
        ({"calibration": lambda c: c.sum(axis=(1, 2))}, "shape"),
        ({"calibration": lambda c: c - 1.0}, "negative"),
        ({"calibration": lambda c: c * np.nan}, "non-finite"),
        ({"press_axis": (0.0, 0.0, 0.0)}, "press_axis"),
        ({"press_axis": (0.0, 1.0)}, "press_axis"),
    ],
)
def test_bad_arguments_raise_validation_error(kwargs, match):
    with pytest.raises(ValidationError, match=match):
        contact_features(_stream(), **kwargs)
