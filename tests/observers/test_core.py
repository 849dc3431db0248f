"""Tests of the functional core: the paper's equations coded literally, and exactness."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hpdob import ServoModel, design_observer, estimate, initial_state, update

J, B_VISC, TS = 3.06e-4, 5e-5, 1e-3


def paper_matrices():
    """A_Dn, B_Dn, D_Dn of the paper's motor from the textbook closed forms (b > 0, no series).

    Independent of hpdob's discretisation; a = b Ts / J = 1.6e-4 is large enough for the naive
    formulas to keep ~12 digits, which is all the 1e-12 comparisons below need.
    """
    a = B_VISC * TS / J
    e = math.exp(-a)
    A = np.array([[1.0, TS * (1 - e) / a], [0.0, e]])
    Bv = np.array([TS * TS * (a - 1 + e) / a**2 / J, TS * (1 - e) / a / J])
    return A, Bv, Bv.copy()


def random_sequences(rng, n):
    x = rng.normal(scale=[2.0, 50.0], size=(n, 2))  # rad, rad/s
    u = rng.normal(scale=0.2, size=n)  # N m
    return x, u


def run_general(design, x, u):
    state = initial_state(design)
    estimates = []
    for xk, uk in zip(x, u, strict=True):
        estimates.append(estimate(design, state, xk))
        state = update(design, state, xk, uk)
    return np.array(estimates)


@pytest.mark.parametrize("pole", [0.9048374180359595, 0.5, 0.97])
def test_dob_equals_eqs_11_13(rng, pole):
    """Conventional DOb, eqs. (11) and (13), with the eq. (25) gain."""
    A, Bv, D = paper_matrices()
    k = 1 - pole  # eq. (12)
    L = k / np.sum(np.abs(D)) * np.array([1.0, 1.0])  # eq. (25)
    x, u = random_sequences(rng, 2000)
    z_hat, expected = 0.0, []
    for xk, uk in zip(x, u, strict=True):
        expected.append(z_hat - L @ xk)  # eq. (13)
        z_hat = (
            (1 - L @ D) * z_hat + L @ (A + np.outer(D, L) - np.eye(2)) @ xk + (L @ Bv) * uk
        )  # eq. (11)
    model = ServoModel(J, B_VISC).discretize(TS)
    got = run_general(design_observer(model, order=0, poles=[pole]), x, u)
    expected = np.array(expected)
    np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-12 * np.max(np.abs(expected)))


@pytest.mark.parametrize("poles", [(0.9048374180359595,) * 2, (0.8, 0.6), (0.7 + 0.2j, 0.7 - 0.2j)])
def test_hpdob_equals_eqs_20_21_23(rng, poles):
    """HPDOb, eqs. (20), (21) and (23), with the eq. (24) and (25) gains."""
    A, Bv, D = paper_matrices()
    l1, l2 = poles
    k1, k2 = (1 - l1 * l2).real, (2 - l1 - l2).real  # eq. (24)
    norm1 = np.sum(np.abs(D))
    L1, L2 = k1 / norm1 * np.ones(2), k2 / norm1 * np.ones(2)  # eq. (25)
    x, u = random_sequences(rng, 2000)
    z1, z2, expected = 0.0, 0.0, []
    for xk, uk in zip(x, u, strict=True):
        expected.append(z2 - L2 @ xk)  # eq. (23)
        z1_next = (
            (1 - L1 @ D) * z2 + (L1 @ Bv) * uk + (L1 @ A + (L1 @ D) * L2 - L2) @ xk
        )  # eq. (20)
        z2_next = (
            -z1 + (2 - L2 @ D) * z2 + (L2 @ Bv) * uk + (L1 + L2 @ A + (L2 @ D) * L2 - 2 * L2) @ xk
        )  # eq. (21)
        z1, z2 = z1_next, z2_next
    model = ServoModel(J, B_VISC).discretize(TS)
    got = run_general(design_observer(model, order=1, poles=poles), x, u)
    expected = np.array(expected)
    np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-12 * np.max(np.abs(expected)))


def closed_loop_polynomial_disturbance(order, degree, *, n_steps=3000):
    """Nominal discrete plant (eq. 8), PD + compensation, tau_k a polynomial of ``degree``."""
    model = ServoModel(2.8e-4).discretize(TS)
    design = design_observer(model, order=order, poles=np.linspace(0.55, 0.75, order + 1))
    t = np.arange(n_steps) * TS
    coefficients = [0.02, -0.05, 0.04, -0.01, 0.003][: degree + 1]
    tau = sum(c * t**i for i, c in enumerate(coefficients))  # N m, polynomial in k
    x = np.array([0.01, 0.0])
    state = initial_state(design, x, 0.0)
    tau_hat = np.empty(n_steps)
    for k in range(n_steps):
        tau_hat[k] = estimate(design, state, x)
        u = -2.8e-4 * (400.0 * x[0] + 40.0 * x[1]) + tau_hat[k]
        state = update(design, state, x, u)
        x = model.step(x, u, tau[k])
    return tau, tau_hat


@pytest.mark.parametrize("order", [0, 1, 2, 3])
def test_order_m_cancels_degree_m_polynomials_exactly(order):
    tau, tau_hat = closed_loop_polynomial_disturbance(order, order)
    tail = slice(-500, None)
    np.testing.assert_allclose(tau_hat[tail], tau[tail], rtol=1e-9, atol=0)


@pytest.mark.parametrize("order", [1, 2, 3])
def test_order_m_minus_1_leaves_the_predicted_error(order):
    """Order m-1 under a degree-m polynomial: e_{k+1} = M e_k + Delta^m tau with a constant
    forcing Delta^m tau = m! c_m Ts^m, so tau - tau_hat -> m! c_m Ts^m / prod(1 - p_i)
    (the DC gain of z^{m-1} / det(zI - M))."""
    tau, tau_hat = closed_loop_polynomial_disturbance(order - 1, order)
    c_m = [0.02, -0.05, 0.04, -0.01, 0.003][order]
    poles = np.linspace(0.55, 0.75, order)
    predicted = math.factorial(order) * c_m * TS**order / np.prod(1 - poles)
    error = tau[-500:] - tau_hat[-500:]
    np.testing.assert_allclose(error, predicted, rtol=1e-4)
    assert np.min(np.abs(error) / np.abs(tau[-500:])) > 1e-8  # far above the 1e-9 of order m


def test_initial_state_matches_constant_disturbance(paper_model):
    for order in range(4):
        design = design_observer(paper_model, order=order, bandwidth=80.0)
        x0 = (0.3, -1.5)
        state = initial_state(design, x0, 0.07)
        np.testing.assert_allclose(state, 0.07 + design.gains @ np.array(x0), rtol=1e-15)
        assert estimate(design, state, x0) == pytest.approx(0.07, rel=1e-14)
        assert all(type(v) is float for v in state)


def test_constant_disturbance_at_rest_is_a_fixed_point(paper_model):
    """reset(x0, tau0) is the steady state for tau0 acting at rest (u = tau0 keeps x0 still)."""
    for order in range(4):
        design = design_observer(paper_model, order=order, bandwidth=120.0)
        x0 = (1.2, 0.0)
        state = initial_state(design, x0, 0.05)
        nxt = update(design, state, x0, 0.05)  # u = tau: the plant stays at rest
        np.testing.assert_allclose(nxt, state, rtol=1e-14, atol=1e-16)


def test_pure_functions_do_not_mutate(paper_model):
    design = design_observer(paper_model, order=2, bandwidth=100.0)
    state = initial_state(design)
    x = np.array([0.1, 0.2])
    new = update(design, state, x, 0.01)
    assert new != state and state == initial_state(design)
    np.testing.assert_array_equal(x, [0.1, 0.2])


@pytest.mark.parametrize(
    ("x", "u", "exc", "pattern"),
    [
        (
            (math.nan, 0.0),
            0.0,
            ValueError,
            r"^x\[0\] \(theta\) must be a finite angle \[rad\], got nan",
        ),
        (
            (0.0, math.inf),
            0.0,
            ValueError,
            r"^x\[1\] \(omega\) must be a finite velocity .*got inf",
        ),
        ((0.0, 0.0), math.nan, ValueError, r"^u must be a finite control torque \[N m\], got nan"),
        ((0.0, 0.0), "1", TypeError, r"^u must be a finite control torque"),
        ((0.0, 0.0, 0.0), 0.0, ValueError, r"^x must be a measured state .*2 entries"),
        (np.zeros((2, 1)), 0.0, ValueError, r"^x must be .*shape \(2,\), got .*\(2, 1\)"),
        (np.zeros(3), 0.0, ValueError, r"^x must be .*shape \(2,\), got .*\(3,\)"),
        (5.0, 0.0, ValueError, r"^x must be a measured state"),
        (("a", 0.0), 0.0, TypeError, r"^x\[0\] \(theta\) must be"),
        ((True, 0.0), 0.0, TypeError, r"^x\[0\] \(theta\) must be"),
    ],
)
def test_bad_measurements(paper_model, x, u, exc, pattern):
    design = design_observer(paper_model, order=1, bandwidth=100.0)
    state = initial_state(design)
    with pytest.raises(exc, match=pattern):
        update(design, state, x, u)


def test_accepts_other_real_types(paper_model):
    design = design_observer(paper_model, order=1, bandwidth=100.0)
    state = initial_state(design)
    reference = update(design, state, (0.5, -1.0), 0.25)
    for x, u in [
        (np.array([0.5, -1.0]), np.float64(0.25)),
        ([np.float32(0.5), -1], 0.25),
        ((np.float64(0.5), np.int64(-1)), np.array(0.25)),
    ]:
        assert update(design, state, x, u) == reference


def test_state_must_fit_the_design(paper_model):
    design = design_observer(paper_model, order=1, bandwidth=100.0)
    with pytest.raises(ValueError, match=r"state must be a tuple of order \+ 1 = 2 floats"):
        update(design, (0.0,), (0.0, 0.0), 0.0)
    with pytest.raises(ValueError, match="state must be a tuple"):
        estimate(design, [0.0, 0.0], (0.0, 0.0))
    with pytest.raises(ValueError, match=r"^tau0 must be a finite disturbance torque"):
        initial_state(design, (0.0, 0.0), math.inf)
