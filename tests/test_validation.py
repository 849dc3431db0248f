"""Tests of the shared argument checks in hpdob._validation.

The checks themselves are private helpers of the library (every public function validates
with them); the exceptions they raise are public (``hpdob.ParameterValueError`` and
``hpdob.ParameterTypeError``)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hpdob import ParameterTypeError, ParameterValueError
from hpdob._validation import (
    as_grid,
    as_real_vector,
    numeric_array,
    readonly,
    require_instance,
)


@pytest.mark.parametrize(
    "value",
    [
        None,
        "1.0",
        b"1",
        ["1", "2"],
        [True, False],
        [0.5, True],
        np.array([1 + 1j, 2]),
        [[1, 2], [3]],
    ],
)
def test_real_vectors_reject_text_bools_complex_and_ragged(value):
    with pytest.raises(ParameterTypeError, match=r"^x must be a vector, got "):
        as_real_vector(value, "x", "a vector")


def test_real_vector_is_a_new_float_array():
    source = np.array([1, 2])
    vector = as_real_vector(source, "x", "a vector")
    assert vector.dtype == float
    vector[0] = 5.0
    assert source[0] == 1  # the caller's array is untouched


def test_complex_arrays_keep_their_imaginary_part():
    np.testing.assert_array_equal(
        numeric_array([0.5 + 0.1j, 0.5 - 0.1j], "p", "poles", dtype=complex),
        [0.5 + 0.1j, 0.5 - 0.1j],
    )


@pytest.mark.parametrize(
    ("value", "kwargs", "pattern"),
    [
        ([], {}, r"^g must hold at least one value \(bandwidths\), got \[\]"),
        ([1.0, 0.0], {}, r"^g must be bandwidths, got 0.0 in g"),
        ([1.0, -1.0], {"allow_zero": True}, r"^g must be bandwidths, got -1.0 in g"),
        ([1.0, math.nan], {}, r"^g must be bandwidths with finite entries"),
        ([2.0, 1.0], {"increasing": True}, r"^g must be strictly increasing, got \[2\. 1\.\]"),
        ([1.0, 1.0], {"increasing": True}, r"^g must be strictly increasing"),
    ],
)
def test_bad_grids(value, kwargs, pattern):
    with pytest.raises(ParameterValueError, match=pattern):
        as_grid(value, "g", "bandwidths", **kwargs)


def test_grids():
    np.testing.assert_array_equal(as_grid(3.0, "g", "bandwidths"), [3.0])
    np.testing.assert_array_equal(as_grid([0.0, 2.0], "g", "f", allow_zero=True), [0.0, 2.0])
    np.testing.assert_array_equal(as_grid([3.0, 1.0], "g", "bandwidths"), [3.0, 1.0])


def test_require_instance_names_the_classes_with_articles():
    with pytest.raises(ParameterTypeError, match=r"^a must be an int or a float, got str$"):
        require_instance("1", (int, float), "a")
    with pytest.raises(ParameterTypeError, match=r"^a must be a float or None, got str$"):
        require_instance("1", float, "a", optional=True)
    assert require_instance(None, float, "a", optional=True) is None
    assert require_instance(2.0, float, "a") == 2.0


def test_readonly():
    array = readonly(np.zeros(2))
    with pytest.raises(ValueError, match="read-only"):
        array[0] = 1.0


@pytest.mark.parametrize(
    "value",
    [np.arange(6.0).reshape(2, 3), np.asfortranarray(np.arange(6.0).reshape(2, 3)),
     np.array([np.nan, np.inf, -0.0]), np.zeros(0), np.float64(2.5) * np.ones(()),
     np.arange(8.0)[::2]],
)  # fmt: skip
def test_numeric_array_of_a_float_array_is_the_generic_copy(value):
    # the fast path for float arrays (the matrices hpdob computes) returns what the generic
    # path returns: a new, writeable array with the same values, shape and memory layout
    from hpdob._validation import numeric_array

    out = numeric_array(value, "x", "numbers")
    generic = np.array(np.asarray(value), dtype=float)
    assert out is not value and not np.shares_memory(out, value) and out.flags.writeable
    assert out.shape == generic.shape and out.tobytes() == generic.tobytes()
    assert out.flags.c_contiguous == generic.flags.c_contiguous
    assert out.flags.f_contiguous == generic.flags.f_contiguous


@pytest.mark.parametrize(
    ("value", "dtype", "pattern"),
    [(np.ma.masked_array([1.0, 2.0], mask=[False, True]), float, "masked"),
     (np.array([True, False]), float, "bool"), (np.array([1j]), float, "complex"),
     (np.array(["1.0"]), float, "str")],
)  # fmt: skip
def test_numeric_array_still_refuses_what_is_not_a_float_array(value, dtype, pattern):
    from hpdob._validation import numeric_array

    with pytest.raises(TypeError, match=pattern):
        numeric_array(value, "x", "numbers", dtype=dtype)
    assert numeric_array(np.array([1.0, 2.0]), "x", "numbers", dtype=complex).dtype == complex
