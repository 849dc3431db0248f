"""ADRC's extended state observer (hpdob.observers: design_eso, ExtendedStateObserver).

Moved here unchanged from tests/observers/test_peers.py (the literal equations: Herbst 2013's
closed-form gains of the current observer for m = 0, an independent gain computation for m = 1),
tests/observers/test_realised.py (realised poles against mpmath eigenvalues at 80 digits) and
tests/test_reliability_families.py (issue 16's audit). ``RIGID_MODEL`` is the frictionless
motor those last two used under the name ``MODEL``.
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest
from observer_tools import (
    B_N,
    J_N,
    MODEL,
    RIGID_MODEL,
    TS,
    match,
    mp_eigenvalues,
    run_observer,
    trace,
)

from hpdob import (
    ExtendedStateObserver,
    Observer,
    ParameterValueError,
)
from hpdob.observers import design_eso


# -- ESO ----------------------------------------------------------------------------------------
def run_literal_eso(Phi, Gamma, L, Lp, theta, u, form):
    """The discrete ESO's two forms as written in the reference, from rest: current
    ``x_hat = x_bar + L (theta - x_bar_1)``, ``x_bar+ = Phi x_hat + Gamma u``; predictive
    ``x_hat+ = Phi x_hat + Gamma u + Lp (theta - x_hat_1)``; ``tau_hat = -J_n f - b_n omega``."""
    x = np.zeros(len(L))  # x_bar (current) or x_hat (predictive), at rest
    tau = []
    for th, uk in zip(theta, u, strict=True):
        if form == "current":
            x_hat = x + L * (th - x[0])
            tau.append(-J_N * x_hat[2] - B_N * x_hat[1])
            x = Phi @ x_hat + Gamma * uk
        else:
            tau.append(-J_N * x[2] - B_N * x[1])
            x = Phi @ x + Gamma * uk + Lp * (th - x[0])
    return np.array(tau)


def literal_eso_m0(theta, u, g, form):
    """Second-order LADRC's ESO, written out: x = [theta, omega, f], theta'' = f + b0 u,
    ZOH with Phi = [[1, T, T^2/2], [0, 1, T], [0, 0, 1]], Gamma = b0 [T^2/2, T, 0]. Current
    observer gains (all poles at beta = exp(-g T)) from G. Herbst, "A simulative study on active
    disturbance rejection control (ADRC) as a control tool for practitioners", Electronics 2
    (2013): L = [1 - beta^3, 3/(2T) (1 - beta)^2 (1 + beta), (1 - beta)^3 / T^2]; the
    predictive gains are L_p = Phi L = [3 - 3 beta, (1 - beta)^2 (5 + beta) / (2T),
    (1 - beta)^3 / T^2]."""
    T, b0, beta = TS, 1.0 / J_N, math.exp(-g * TS)
    Phi = np.array([[1.0, T, T * T / 2], [0.0, 1.0, T], [0.0, 0.0, 1.0]])
    Gamma = b0 * np.array([T * T / 2, T, 0.0])
    L = np.array([1 - beta**3, 1.5 / T * (1 - beta) ** 2 * (1 + beta), (1 - beta) ** 3 / T**2])
    Lp = np.array([3 - 3 * beta, (1 - beta) ** 2 * (5 + beta) / (2 * T), (1 - beta) ** 3 / T**2])
    return run_literal_eso(Phi, Gamma, L, Lp, theta, u, form)


def charpoly(A) -> list:
    """det(zI - A), highest power first, by the Faddeev-LeVerrier recursion in exact rational
    arithmetic on the float entries (eigenvalues of a Jordan-like Phi are too inaccurate)."""

    n = len(A)
    M = [[Fraction(float(v)) for v in row] for row in A]
    coefficients = [Fraction(1)]
    B = [[Fraction(int(i == j)) for j in range(n)] for i in range(n)]
    for k in range(1, n + 1):
        MB = [[sum(M[i][h] * B[h][j] for h in range(n)) for j in range(n)] for i in range(n)]
        c = -sum(MB[i][i] for i in range(n)) / k
        coefficients.append(c)
        B = [[MB[i][j] + (c if i == j else 0) for j in range(n)] for i in range(n)]
    return coefficients


def exact_solve(A, b) -> list:
    """Gaussian elimination in rationals."""
    n = len(b)
    rows = [[*A[i], b[i]] for i in range(n)]
    for col in range(n):
        pivot = next(r for r in range(col, n) if rows[r][col] != 0)
        rows[col], rows[pivot] = rows[pivot], rows[col]
        for r in range(n):
            if r != col and rows[r][col] != 0:
                f = rows[r][col] / rows[col][col]
                rows[r] = [a - f * c for a, c in zip(rows[r], rows[col], strict=True)]
    return [rows[i][n] / rows[i][i] for i in range(n)]


def literal_eso_m1(theta, u, g, form):
    """The generalised ESO with f'' = 0: x = [theta, omega, f, f'], Phi the ZOH of the integrator
    chain written out, the gain found here by matching det(zI - Phi + L_p C) = (z - beta)^4
    coefficient by coefficient (a linear solve: the determinant is affine in L_p)."""
    T, b0, beta = TS, 1.0 / J_N, math.exp(-g * TS)
    Phi = np.array(
        [[1, T, T**2 / 2, T**3 / 6], [0, 1, T, T**2 / 2], [0, 0, 1, T], [0, 0, 0, 1]], float
    )
    Gamma = b0 * np.array([T**2 / 2, T, 0.0, 0.0])

    base = charpoly(Phi)
    columns = []  # det(zI - Phi + e_j C) - det(zI - Phi): affine in L_p, so one column per j
    for j in range(4):
        shifted = Phi.copy()
        shifted[j, 0] -= 1.0
        columns.append([a - b for a, b in zip(charpoly(shifted), base, strict=True)])
    target = [Fraction(c) - b for c, b in zip(np.poly(np.full(4, beta)), base, strict=True)]
    matrix = [[columns[j][i] for j in range(4)] for i in range(1, 5)]
    Lp = np.array([float(v) for v in exact_solve(matrix, target[1:])])
    L = np.linalg.solve(Phi, Lp)
    return run_literal_eso(Phi, Gamma, L, Lp, theta, u, form)


@pytest.mark.parametrize("form", ["current", "predictive"])
@pytest.mark.parametrize(("m", "literal"), [(0, literal_eso_m0), (1, literal_eso_m1)])
def test_eso_equals_its_literal_equations(rng, form, m, literal):
    theta, u = trace(rng)
    obs = ExtendedStateObserver(MODEL, bandwidth=150.0, extended_order=m, form=form)
    tau, _ = run_observer(obs, theta, u)
    expected = literal(theta, u, 150.0, form)
    np.testing.assert_allclose(tau, expected, rtol=1e-7, atol=1e-9 * np.abs(expected).max())


@pytest.mark.parametrize("m", [0, 1, 2])
@pytest.mark.parametrize("form", ["current", "predictive"])
def test_eso_poles_and_constant_disturbance(m, form):
    eso = design_eso(MODEL, bandwidth=200.0, extended_order=m, form=form)
    beta = math.exp(-0.2)
    np.testing.assert_allclose(np.poly(eso.system.F), np.poly(np.full(m + 3, beta)), atol=1e-9)
    # on the nominal plant, a constant load torque is estimated exactly once settled
    obs = Observer(eso)
    x, tau = np.zeros(2), 0.013
    for _ in range(10000):
        tau_hat = obs.estimate(float(x[0]))
        u = -J_N * (50 * x[0] + 5 * x[1]) + tau_hat
        obs.update(float(x[0]), u)
        x = MODEL.step(x, u, tau)
    assert obs.estimate(float(x[0])) == pytest.approx(tau, rel=1e-7)


# -- realised poles (mpmath at 80 digits) ---------------------------------------------------------
@pytest.mark.parametrize("m", range(5))
@pytest.mark.parametrize("form", ["current", "predictive"])
def test_eso_realised_poles_agree_with_high_precision_eigenvalues(m, form):
    design = design_eso(
        RIGID_MODEL, bandwidth=300.0, extended_order=m, form=form, pole_tolerance=None
    )
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
    design = design_eso(RIGID_MODEL, bandwidth=bandwidth, extended_order=m, pole_tolerance=None)
    assert np.max(np.abs(design.realised_poles)) == pytest.approx(realised, abs=2e-6)
    with pytest.raises(ParameterValueError, match=r"an ESO of extended order .* off by"):
        design_eso(RIGID_MODEL, bandwidth=bandwidth, extended_order=m)
    with pytest.raises(ParameterValueError, match=r"off by"):  # the runtime object too
        ExtendedStateObserver(RIGID_MODEL, bandwidth=bandwidth, extended_order=m)


@pytest.mark.parametrize(("m", "bandwidth"), [(4, 5.0), (2, 1.0), (1, 0.01)])
def test_unstable_esos_are_refused_even_without_a_tolerance(m, bandwidth):
    # 80-digit eigenvalues of the rounded F: |z| = 1.0023, 1.00006, 1.00008 (all > 1)
    assert np.max(np.abs(mp_eigenvalues(_eso_matrix(m, bandwidth)))) > 1.0
    with pytest.raises(ParameterValueError, match=r"is not stable .* exact Schur-Cohn"):
        design_eso(RIGID_MODEL, bandwidth=bandwidth, extended_order=m, pole_tolerance=None)


def _eso_matrix(m, bandwidth):
    """The F of an ESO design, whatever the checks say (rebuilt from its documented formula:
    Ackermann's gain on the ZOH chain, current form)."""
    from hpdob.observers._eso import observer_gain, zoh

    n, Ts = m + 3, RIGID_MODEL.Ts
    A_c, B_c = np.eye(n, k=1), np.zeros(n)
    B_c[1] = 1.0 / RIGID_MODEL.J
    Phi, _ = zoh(A_c, B_c, Ts)
    C = np.zeros((1, n))
    C[0, 0] = 1.0
    L_p = observer_gain(Phi, C, np.full(n, math.exp(-bandwidth * Ts)), scale=Ts ** np.arange(n))
    L = np.linalg.solve(Phi, L_p)
    return Phi @ (np.eye(n) - np.outer(L, C[0]))


def test_eso_bandwidth_whose_pole_rounds_to_one_and_tolerance():
    with pytest.raises(ParameterValueError, match=r"bandwidth=1e-20 rad/s is too small"):
        design_eso(RIGID_MODEL, bandwidth=1e-20)
    with pytest.raises(ValueError, match=r"^pole_tolerance must be a fraction >= 0 or None"):
        design_eso(RIGID_MODEL, bandwidth=100.0, pole_tolerance=math.nan)


@pytest.mark.parametrize("m", range(3))
def test_eso_canonical_designs_are_accepted_unchanged(m):
    for bandwidth in (50.0, 200.0, 1000.0):
        design = design_eso(RIGID_MODEL, bandwidth=bandwidth, extended_order=m)
        free = design_eso(RIGID_MODEL, bandwidth=bandwidth, extended_order=m, pole_tolerance=None)
        np.testing.assert_array_equal(design.system.F, free.system.F)
        np.testing.assert_array_equal(design.gain, free.gain)


def test_eso_pole_that_rounds_to_one_is_refused():
    # exp(-1e-20 * 1e-3) == 1.0: the ESO had every pole at 1 (not asymptotically stable)
    assert math.exp(-1e-20 * 1e-3) == 1.0
    with pytest.raises(ParameterValueError, match=r"^bandwidth=1e-20 rad/s is too small"):
        design_eso(RIGID_MODEL, bandwidth=1e-20)
