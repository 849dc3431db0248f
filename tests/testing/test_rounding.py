"""Tests of the rounding-error bound of exported C observers against closed forms."""

from __future__ import annotations

import numpy as np
import pytest

from hpdob import ParameterValueError, design_observer
from hpdob.testing import error_amplification, export_error_bound

# Unit roundoffs of IEEE 754 binary64 and binary32 (round to nearest): 2^-53 and 2^-24.
UNIT_ROUNDOFF = {"double": 2.0**-53, "float": 2.0**-24}


def gamma(n, u):
    return n * u / (1 - n * u)


def test_amplification_sums_the_last_rows_of_matrix_powers(paper_model):
    # sum_j ||last row of M^j||_1 over the error matrix M, by plain matrix powers (until the
    # rows are below 1e-20 of the first; all poles <= 0.9 in magnitude: ~500 terms).
    design = design_observer(paper_model, order=2, poles=[0.9, 0.8 + 0.1j, 0.8 - 0.1j])
    M, power, total = design.error_matrix, np.eye(3), 0.0
    for _ in range(2000):
        total += np.abs(power[-1]).sum()
        power = power @ M
    assert error_amplification(design) == pytest.approx(total, rel=1e-12)


@pytest.mark.parametrize("pole", [0.9, 0.5, -0.3])
def test_order_0_amplification_is_the_geometric_sum(paper_model, pole):
    # M = [1 - k] = [pole]: sum_j |pole|^j = 1 / (1 - |pole|).
    design = design_observer(paper_model, order=0, poles=[pole])
    assert error_amplification(design) == pytest.approx(1 / (1 - abs(pole)), rel=1e-12)


@pytest.mark.parametrize("dtype", ["float", "double"])
def test_order_0_bound_on_a_constant_state_is_a_geometric_series(paper_model, dtype):
    """theta = omega = u = 0 and a constant state c: every sample adds the same rounding
    bound delta = gamma_7 (|k| c + |p| c) (terms -k z + ... + 1 z), carried by |1 - k|^j."""
    pole, c, n = 0.9, 3.0, 60
    design = design_observer(paper_model, order=0, poles=[pole])
    k = design.k[0]
    zeros = np.zeros(n)
    bound = export_error_bound(design, dtype, zeros, zeros, zeros, np.full((n, 1), c))
    unit = UNIT_ROUNDOFF[dtype] + UNIT_ROUNDOFF["double"]
    delta = gamma(7, unit) * (abs(k) * c + c)
    carried = delta * (1 - pole ** np.arange(n)) / (1 - pole)  # sum_{j<k} pole^(k-1-j)
    expected = carried + gamma(5, unit) * c  # plus the estimate's own rounding
    np.testing.assert_allclose(bound, expected, rtol=1e-12)


def test_initial_rounding_is_carried_by_the_error_dynamics(paper_model):
    design = design_observer(paper_model, order=0, poles=[0.5])
    n, init = 8, (2.0, 0.0, 0.25)  # theta0 = 2 rad, tau0 = 0.25 N m
    zeros = np.zeros(n)
    bound = export_error_bound(design, "float", zeros, zeros, zeros, np.zeros((n, 1)), init=init)
    unit = UNIT_ROUNDOFF["float"] + UNIT_ROUNDOFF["double"]
    e0 = gamma(5, unit) * (0.25 + abs(design.gains[0, 0]) * 2.0)
    np.testing.assert_allclose(bound, e0 * 0.5 ** np.arange(n), rtol=1e-12)


def test_bad_dtype(paper_model):
    design = design_observer(paper_model, order=0, poles=[0.5])
    with pytest.raises(ParameterValueError, match="dtype must be one of 'double', 'float'"):
        export_error_bound(design, "half", [0.0], [0.0], [0.0], [[0.0]])
