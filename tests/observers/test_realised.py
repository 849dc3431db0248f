"""Realised poles of the position-only family, the ESO and the Kalman observer (issue 16).

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

from hpdob import ExtendedStateObserver, ParameterValueError, ServoModel, design_observer
from hpdob.observers import design_eso, design_kalman

MODEL = ServoModel(2.8e-4).discretize(1e-3)
mpmath = pytest.importorskip("mpmath")


def mp_eigenvalues(F, digits=80) -> np.ndarray:
    """Eigenvalues of the double matrix ``F`` (every entry at its exact value) by mpmath."""
    with mpmath.workdps(digits):
        matrix = mpmath.matrix([[mpmath.mpf(float(v)) for v in row] for row in np.asarray(F)])
        return np.array([complex(e) for e in mpmath.eig(matrix, left=False, right=False)])


def match(found, reference) -> float:
    """Largest distance between the two multisets of roots, paired greedily."""
    left = list(reference)
    worst = 0.0
    for z in found:
        i = int(np.argmin([abs(z - r) for r in left]))
        worst = max(worst, abs(z - left.pop(i)))
    return worst


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


# -- ESO ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("m", range(5))
@pytest.mark.parametrize("form", ["current", "predictive"])
def test_eso_realised_poles_agree_with_high_precision_eigenvalues(m, form):
    design = design_eso(MODEL, bandwidth=300.0, extended_order=m, form=form, pole_tolerance=None)
    reference = mp_eigenvalues(design.system.F)
    spread = np.max(np.abs(reference - np.mean(reference)))
    assert match(design.realised_poles, reference) < 1e-9 * max(spread, 1e-6)


@pytest.mark.parametrize(
    ("m", "bandwidth", "realised"),
    [  # 80-digit mpmath eigenvalues of the rounded F (Ts = 1 ms)
        (2, 5.0, 0.995811),  # requested 0.995012
        (1, 1.0, 0.999138),  # requested 0.999000
        (3, 50.0, 0.954465),  # requested 0.951229
    ],
)
def test_eso_designs_far_off_are_refused(m, bandwidth, realised):
    design = design_eso(MODEL, bandwidth=bandwidth, extended_order=m, pole_tolerance=None)
    assert np.max(np.abs(design.realised_poles)) == pytest.approx(realised, abs=2e-6)
    with pytest.raises(ParameterValueError, match=r"an ESO of extended order .* off by"):
        design_eso(MODEL, bandwidth=bandwidth, extended_order=m)
    with pytest.raises(ParameterValueError, match=r"off by"):  # the runtime object too
        ExtendedStateObserver(MODEL, bandwidth=bandwidth, extended_order=m)


@pytest.mark.parametrize(("m", "bandwidth"), [(4, 5.0), (2, 1.0), (1, 0.01)])
def test_unstable_esos_are_refused_even_without_a_tolerance(m, bandwidth):
    # 80-digit eigenvalues of the rounded F: |z| = 1.0023, 1.00006, 1.00008 (all > 1)
    assert np.max(np.abs(mp_eigenvalues(_eso_matrix(m, bandwidth)))) > 1.0
    with pytest.raises(ParameterValueError, match=r"is not stable .* exact Schur-Cohn"):
        design_eso(MODEL, bandwidth=bandwidth, extended_order=m, pole_tolerance=None)


def _eso_matrix(m, bandwidth):
    """The F of an ESO design, whatever the checks say (rebuilt from its documented formula:
    Ackermann's gain on the ZOH chain, current form)."""
    from hpdob.observers._eso import observer_gain, zoh

    n, Ts = m + 3, MODEL.Ts
    A_c, B_c = np.eye(n, k=1), np.zeros(n)
    B_c[1] = 1.0 / MODEL.J
    Phi, _ = zoh(A_c, B_c, Ts)
    C = np.zeros((1, n))
    C[0, 0] = 1.0
    L_p = observer_gain(Phi, C, np.full(n, math.exp(-bandwidth * Ts)), scale=Ts ** np.arange(n))
    L = np.linalg.solve(Phi, L_p)
    return Phi @ (np.eye(n) - np.outer(L, C[0]))


def test_eso_bandwidth_whose_pole_rounds_to_one_and_tolerance():
    with pytest.raises(ParameterValueError, match=r"bandwidth=1e-20 rad/s is too small"):
        design_eso(MODEL, bandwidth=1e-20)
    with pytest.raises(ValueError, match=r"^pole_tolerance must be a fraction >= 0 or None"):
        design_eso(MODEL, bandwidth=100.0, pole_tolerance=math.nan)


@pytest.mark.parametrize("m", range(3))
def test_eso_canonical_designs_are_accepted_unchanged(m):
    for bandwidth in (50.0, 200.0, 1000.0):
        design = design_eso(MODEL, bandwidth=bandwidth, extended_order=m)
        free = design_eso(MODEL, bandwidth=bandwidth, extended_order=m, pole_tolerance=None)
        np.testing.assert_array_equal(design.system.F, free.system.F)
        np.testing.assert_array_equal(design.gain, free.gain)


# -- Kalman ------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("order", "r", "q", "lowest"),
    # scipy's non-stabilising Riccati answer depends on the LAPACK build: spectral radii (80-digit
    # mpmath eigenvalues of F) 15938.877, 1.018438, 1.064843 on one, 1.02581 and 1.06576 for the
    # last two on another; the refusal, not the exact radius, is the invariant
    [(2, 1e-9, 1e-4, 100.0), (3, 1e-9, 1e-8, 1.0), (4, 1e-9, 1e-12, 1.0)],
)
def test_kalman_designs_that_are_not_stable_are_refused(order, r, q, lowest):
    with pytest.raises(ParameterValueError, match=r"is not stable in double precision") as info:
        design_kalman(MODEL, order=order, position_noise_std=r, process_noise_std=q)
    message = str(info.value)
    assert f"position_noise_std={r!r}" in message and f"process_noise_std={q!r}" in message
    shown = float(message.split("spectral radius about ")[1].split(",")[0])
    assert shown > lowest


@pytest.mark.parametrize(("order", "r", "q"), [(0, 1e-9, 1.0), (1, 1e-4, 1e4), (2, 1e-9, 1.0)])
def test_kalman_designs_close_to_the_unit_circle_stay_accepted(order, r, q):
    design = design_kalman(MODEL, order=order, position_noise_std=r, process_noise_std=q)
    radius = np.max(np.abs(mp_eigenvalues(design.system.F)))
    assert 0.9999 < radius < 1.0  # measured: 0.99999993, 0.99991, 0.9999989
