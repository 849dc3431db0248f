"""Realised poles of the position-only family (issue 16; the ESO's and the Kalman observer's
are in tests/observers/test_eso.py and test_kalman.py).

As for the state-measuring family (tests/observers/test_synthesis.py), the gains rounded to
doubles place a repeated pole of multiplicity n on a ring of radius up to ~eps^(1/n): position-
only designs of order m (n = m + 3) and the ESO of extended order m (n = m + 3) were accepted
with poles far off the requested ones (position-only order 8 at 100 rad/s: |z| = 0.947 for
0.905; ESO m = 2 at 5 rad/s: 0.9958 for 0.9950), the ESO even when unstable (m = 4 at 5 rad/s:
|z| = 1.0023), and the Kalman design returned wildly unstable filters when scipy's Riccati
solver gave a non-stabilising answer for noise levels far apart (spectral radius 1.6e4 for r =
1e-9 rad, q = 1e-4, order 2). Reference: eigenvalues of the rounded state matrix by mpmath at
80 digits (an independent solver); the exact characteristic polynomial of a matrix against the
position-only family's own affine formula (docs/theory.md, section 9).
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest
from observer_tools import RIGID_MODEL as MODEL
from observer_tools import match, mp_eigenvalues

from hpdob import ParameterValueError, ServoModel, design_observer


# -- the exact characteristic polynomial of a matrix -----------------------------------------
def test_characteristic_polynomial_of_a_companion_matrix_is_exact():
    from hpdob.observers._realised import matrix_characteristic_polynomial

    # (z - 1/2)(z - 1/4)(z + 3)(z - 2^-20): ascending coefficients, dyadic and exact in doubles
    roots = [Fraction(1, 2), Fraction(1, 4), Fraction(-3), Fraction(1, 2**20)]
    poly = [Fraction(1)]
    for r in roots:
        poly = [Fraction(0), *poly]
        poly = [poly[i] - r * (poly[i + 1] if i + 1 < len(poly) else 0) for i in range(len(poly))]
    assert all(Fraction(float(c)) == c for c in poly)
    n = len(roots)
    companion = np.zeros((n, n))
    companion[1:, :-1] = np.eye(n - 1)
    companion[:, -1] = [-float(c) for c in poly[:n]]
    numbers, e = matrix_characteristic_polynomial(companion)
    assert [Fraction(c, 2**e) for c in numbers] == poly


@pytest.mark.parametrize("order", range(4))
def test_characteristic_polynomial_agrees_with_the_position_family_formula(order):
    from hpdob.observers._position import realised_polynomial
    from hpdob.observers._realised import matrix_characteristic_polynomial

    design = design_observer(
        MODEL, order=order, bandwidth=80.0, measurement="position", velocity_bandwidth=250.0
    )
    numbers, e = matrix_characteristic_polynomial(design.error_matrix)
    assert [Fraction(c, 2**e) for c in numbers] == realised_polynomial(design.error_matrix, order)


# -- position-only ----------------------------------------------------------------------------
POSITION_CASES = [
    (0, {"bandwidth": 100.0}),
    (1, {"bandwidth": 100.0}),
    (2, {"bandwidth": 50.0, "velocity_bandwidth": 300.0}),
    (4, {"bandwidth": 100.0}),
    (8, {"bandwidth": 100.0}),
    (1, {"poles": [0.9, 0.9, 0.5 + 0.3j, 0.5 - 0.3j]}),
]


@pytest.mark.parametrize(("order", "kwargs"), POSITION_CASES, ids=str)
def test_position_realised_poles_agree_with_high_precision_eigenvalues(order, kwargs):
    design = design_observer(
        MODEL, order=order, measurement="position", pole_tolerance=None, **kwargs
    )
    reference = mp_eigenvalues(design.error_matrix)
    spread = np.max(np.abs(reference - np.mean(reference)))
    assert match(design.realised_poles, reference) < 1e-9 * max(spread, 1e-6)
    assert design.realised_poles.shape == design.poles.shape == (order + 3,)


@pytest.mark.parametrize(
    ("order", "Ts", "bandwidth"),
    # the rounded gains (hence the furthest pole) differ between LAPACK builds: measured |z| of
    # 0.9473/0.9479, 0.9904/0.9855 and 0.9821/0.9822 on two, for requested 0.905, 0.905, 0.980
    [(8, 1e-3, 100.0), (10, 1e-4, 1000.0), (4, 1e-3, 20.0)],
)
def test_position_designs_far_off_are_refused(order, Ts, bandwidth):
    model = ServoModel(2.8e-4).discretize(Ts)
    kwargs = {"order": order, "bandwidth": bandwidth, "measurement": "position"}
    design = design_observer(model, pole_tolerance=None, **kwargs)
    # reference: 80-digit mpmath eigenvalues of the rounded error matrix this build produced
    realised = np.max(np.abs(mp_eigenvalues(design.error_matrix)))
    assert np.max(np.abs(design.realised_poles)) == pytest.approx(realised, abs=2e-6)
    assert realised - math.exp(-bandwidth * Ts) > 0.05 * (1 - math.exp(-bandwidth * Ts))
    with pytest.raises(ParameterValueError, match=r"position-only observer of order") as info:
        design_observer(model, **kwargs)
    message = str(info.value)
    assert "more than pole_tolerance=0.05" in message and "\n" not in message
    assert f"bandwidth={bandwidth!r}" in message


@pytest.mark.parametrize("order", range(3))
@pytest.mark.parametrize("bandwidth", [50.0, 100.0, 200.0])
def test_position_canonical_designs_are_accepted_unchanged(order, bandwidth):
    kwargs = {"order": order, "bandwidth": bandwidth, "measurement": "position"}
    design = design_observer(MODEL, **kwargs)
    free = design_observer(MODEL, pole_tolerance=None, **kwargs)
    for name in ("gains", "predictor_gains", "error_matrix"):
        np.testing.assert_array_equal(getattr(design, name), getattr(free, name))
    p = math.exp(-bandwidth * 1e-3)
    off = np.abs(design.realised_poles - p) / (1 - p)
    assert np.all(off < [1e-4, 1e-3, 1e-2][order])  # measured: 8e-6, 3e-4, 3e-3


def test_position_pole_tolerance_is_validated():
    with pytest.raises(ValueError, match=r"^pole_tolerance must be a fraction >= 0 or None"):
        design_observer(MODEL, order=1, bandwidth=100.0, measurement="position",
                        pole_tolerance=-1.0)  # fmt: skip
    with pytest.raises(TypeError, match=r"^pole_tolerance must be a fraction >= 0 or None"):
        design_observer(MODEL, order=1, bandwidth=100.0, measurement="position",
                        pole_tolerance=np.array([0.05, 0.1]))  # fmt: skip
    loose = design_observer(MODEL, order=4, bandwidth=100.0, measurement="position",
                            pole_tolerance=0.1)  # fmt: skip  # 4.1% off, measured
    assert loose.realised_poles.shape == (7,)
