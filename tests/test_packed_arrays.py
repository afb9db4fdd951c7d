"""Arrays of decimals packed as integers in JSON: read back exactly as the same decimals in a list would parse,
and every way a packed object can be damaged or oversized is refused before it is decoded."""

from __future__ import annotations

import json

import numpy as np
import pytest

from palpate.core.errors import ValidationError
from palpate.core.files import decimal_array, pack_decimals


@pytest.mark.parametrize("decimals,scale", [(0, 1e3), (1, 1e6), (4, 1.0), (6, 1e-2), (1, 1e12)])
def test_packed_decimals_read_back_as_their_decimals_parse(decimals, scale):
    rng = np.random.default_rng(decimals)
    values = np.round(rng.normal(0.0, scale, size=(3, 5, 7)), decimals)
    listed = json.loads(json.dumps(values.tolist()))  # the floats a list of these decimals parses to
    packed = json.loads(json.dumps(pack_decimals(values, decimals)))
    got = decimal_array(packed, "x", 3)
    assert got.dtype == float and got.shape == (3, 5, 7)
    np.testing.assert_array_equal(got, np.asarray(listed))
    # the integers' width follows the values': small values take 2 bytes each
    assert packed["dtype"] == ("<i8" if scale * 10**decimals > 2**31 else "<i4" if scale * 10**decimals > 2**14
                               else "<i2")


def test_a_list_reads_as_before():
    np.testing.assert_array_equal(decimal_array([[1.5, 2.0]], "x", 2), [[1.5, 2.0]])
    with pytest.raises(ValidationError, match="2-D array"):
        decimal_array([1.5, 2.0], "x", 2)


def _packed():
    return pack_decimals(np.arange(12.0).reshape(3, 4) / 10, 1)


@pytest.mark.parametrize("edit,match", [
    (lambda d: d.pop("divisor"), "packed array"),
    (lambda d: d.update(extra=1), "packed array"),
    (lambda d: d.update(packed="float"), "packed array"),
    (lambda d: d.update(dtype="<f8"), "packed array"),
    (lambda d: d.update(dtype="object"), "packed array"),
    (lambda d: d.update(shape=[12]), "packed array"),
    (lambda d: d.update(shape=[3, 4.0]), "packed array"),
    (lambda d: d.update(shape=[-3, -4]), "packed array"),
    (lambda d: d.update(shape=[True, 12]), "packed array"),
    (lambda d: d.update(divisor=7), "packed array"),
    (lambda d: d.update(divisor=10.0), "packed array"),
    (lambda d: d.update(base64=1234), "packed array"),
    (lambda d: d.update(shape=[3, 5]), "base64 characters"),
    (lambda d: d.update(base64=d["base64"][:-4]), "base64 characters"),
    (lambda d: d.update(base64="!" + d["base64"][1:]), "not base64"),
    (lambda d: d.update(shape=[100000, 100000]), "at most"),
])
def test_a_damaged_packed_array_is_refused(edit, match):
    doc = _packed()
    edit(doc)
    with pytest.raises(ValidationError, match=match):
        decimal_array(doc, "FILE: key", 2, max_size=10**6)


def test_values_a_packing_cannot_hold_exactly_are_refused():
    for values, decimals in (([np.nan], 1), ([np.inf], 1), ([1e15], 2), ([1.0], 13), ([1.0], -1)):
        with pytest.raises(ValidationError, match="pack_decimals"):
            pack_decimals(values, decimals)
