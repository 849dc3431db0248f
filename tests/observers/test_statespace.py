"""LTI views of the observer: state space vs runtime, and the closed-form estimation response.

The closed form Q = 1 - (z-1)^{m+1}/det(zI-M) (docs/analysis.md) is checked three
independent ways for every order 0-3: against the observer's state space in series with the
nominal plant (python-control frequency response), against a time-domain sine test on the
nominal discrete model with the runtime DisturbanceObserver, and its analytic invariants.
"""

from __future__ import annotations

import math

import control
import numpy as np
import pytest

from hpdob import (
    DisturbanceObserver,
    ParameterTypeError,
    ParameterValueError,
    ServoModel,
    design_observer,
    estimation_response,
    estimation_transfer,
)

TS = 1e-3
ORDERS = [0, 1, 2, 3]


@pytest.fixture
def model():
    return ServoModel(J=2.8e-4, b=2e-4).discretize(TS)  # b > 0: A has a friction pole


def designs(model, order):
    """A bandwidth design and a design with distinct, partly complex poles."""
    poles = [0.9, 0.8 + 0.1j, 0.8 - 0.1j, 0.7][: order + 1]
    if order == 1:
        poles = [0.9, 0.75]
    return [
        design_observer(model, order=order, bandwidth=100.0),
        design_observer(model, order=order, poles=poles, gain_direction=(0.3, 1.0)),
    ]


# -- to_statespace -----------------------------------------------------------------------


@pytest.mark.parametrize("order", ORDERS)
def test_statespace_equals_runtime_sample_by_sample(model, order, rng):
    n = 400
    x = rng.normal(size=(n, 2)) * [0.3, 5.0]
    u = rng.normal(size=n) * 0.05
    for design in designs(model, order):
        obs = DisturbanceObserver.from_design(design)
        runtime = []
        for k in range(n):
            runtime.append(obs.estimate(x[k]))
            obs.update(x[k], u[k])
        sys = obs.to_statespace()
        resp = control.forced_response(sys, T=np.arange(n) * TS, U=np.vstack([x.T, u]))
        out = np.ravel(resp.outputs)
        scale = np.abs(runtime).max()
        np.testing.assert_allclose(out, runtime, rtol=0, atol=1e-12 * scale)


def test_statespace_matrices_names_and_dt(model):
    design = design_observer(model, order=2, bandwidth=150.0)
    sys = design.to_statespace()
    same = DisturbanceObserver.from_design(design).to_statespace()
    assert sys.dt == TS and same.dt == TS
    assert sys.input_labels == ["theta", "omega", "u"]
    assert sys.output_labels == ["tau_hat"]
    assert sys.state_labels == ["z1", "z2", "z3"]
    np.testing.assert_array_equal(sys.A, design.error_matrix)
    np.testing.assert_array_equal(sys.B[:, :2], design.state_input)
    np.testing.assert_array_equal(sys.B[:, 2], design.control_input)
    np.testing.assert_array_equal(sys.C, [[0.0, 0.0, 1.0]])
    np.testing.assert_array_equal(sys.D, [[-design.gains[-1, 0], -design.gains[-1, 1], 0.0]])
    np.testing.assert_array_equal(same.A, sys.A)


# -- closed-form estimation response ------------------------------------------------------


def nominal_plant_ss(model):
    """x[k+1] = A x + B u - D tau (eq. 8) with inputs u, tau_dn and outputs theta, omega."""
    return control.ss(
        model.A,
        np.column_stack([model.B, -model.D]),
        np.eye(2),
        np.zeros((2, 2)),
        model.Ts,
        inputs=["u", "tau_dn"],
        outputs=["theta", "omega"],
    )


@pytest.mark.parametrize("order", ORDERS)
def test_closed_form_matches_statespace_in_series_with_nominal_plant(model, order):
    f = np.array([0.3, 2.0, 17.0, 80.0, 311.0, 499.0])
    w = 2 * np.pi * f
    for design in designs(model, order):
        obs = design.to_statespace()
        # tau -> plant -> (theta, omega) -> observer; u = 0 (the response does not depend on u)
        # (signals connect by name: theta, omega from the plant; u shared by both)
        series = control.interconnect(
            [nominal_plant_ss(model), obs], inplist=["tau_dn", "u"], outlist=["tau_hat"]
        )
        resp = series.frequency_response(w).frdata[0, 0]
        # (the state-space evaluation loses ~1e-9 near z = 1 with four observer poles at 0.9)
        np.testing.assert_allclose(estimation_response(design, f), resp, rtol=0, atol=1e-8)
        tf = estimation_transfer(design).frequency_response(w).frdata[0, 0]
        np.testing.assert_allclose(tf, resp, rtol=0, atol=1e-8)


@pytest.mark.parametrize("order", ORDERS)
def test_closed_form_matches_time_domain_sine_test(model, order):
    """Steady-state amplitude and phase of tau_hat for a sampled sine on the nominal model."""
    f, periods, settle = 5.0, 10, 1500  # 200 samples per period: an exact DFT bin
    n_win = round(periods / (f * TS))
    n = settle + n_win
    k = np.arange(n)
    tau = 0.02 * np.sin(2 * np.pi * f * k * TS + 0.4)
    for design in designs(model, order):
        obs = DisturbanceObserver.from_design(design)
        x, est = np.zeros(2), np.empty(n)
        for i in range(n):
            est[i] = obs.estimate(x)
            u = -2.8e-4 * (50 * x[0] + 5 * x[1]) + est[i]  # PD + compensation: u varies
            obs.update(x, u)
            x = model.step(x, u, tau[i])
        window = slice(settle, n)
        phasor = np.exp(-2j * np.pi * f * k[window] * TS)
        measured = np.mean(est[window] * phasor) / np.mean(tau[window] * phasor)
        expected = estimation_response(design, f)[0]
        assert abs(measured - expected) < 1e-9 * abs(expected)
        measured_error = np.mean((tau - est)[window] * phasor) / np.mean(tau[window] * phasor)
        error = estimation_response(design, f, error=True)[0]
        assert abs(measured_error - error) < 1e-8 * max(abs(error), 1e-6)


@pytest.mark.parametrize("order", ORDERS)
def test_closed_form_invariants(model, order):
    design = design_observer(model, order=order, bandwidth=200.0)
    lam = math.exp(-200.0 * TS)
    # Unit DC gain, and 1 - Q = ((z - 1)/(z - lam))^{m+1} written out for a bandwidth design.
    assert estimation_response(design, 0.0)[0] == pytest.approx(1.0, abs=1e-15)
    f = np.geomspace(1e-3, 499.0, 50)
    z = np.exp(2j * np.pi * f * TS)
    literal = ((z - 1) / (z - lam)) ** (order + 1)
    np.testing.assert_allclose(estimation_response(design, f, error=True), literal, rtol=1e-12)
    # The error falls with the (m+1)-th power of frequency at low frequency.
    small = np.abs(estimation_response(design, [1e-3, 2e-3], error=True))
    assert small[1] / small[0] == pytest.approx(2.0 ** (order + 1), rel=1e-5)
    # Q is strictly proper (one sample of lag at least): numerator degree <= m.
    Q = estimation_transfer(design)
    assert len(np.trim_zeros(Q.num[0][0], "f")) <= order + 1
    assert len(Q.den[0][0]) == order + 2
    E = estimation_transfer(design, error=True)
    np.testing.assert_allclose(
        E.num[0][0], [math.comb(order + 1, j) * (-1) ** j for j in range(order + 2)]
    )
    assert E.output_labels == ["tau_error"] and Q.output_labels == ["tau_hat"]


def test_paper_dob_q_filter_is_first_order(model):
    """Order 0, pole p: tau_hat_k = p tau_hat_{k-1} + (1 - p) tau_{k-1}, i.e. (1-p)/(z-p)."""
    design = design_observer(model, order=0, poles=[0.85])
    Q = estimation_transfer(design)
    np.testing.assert_allclose(np.trim_zeros(Q.num[0][0], "f"), [0.15], rtol=1e-13)
    np.testing.assert_allclose(Q.den[0][0], [1.0, -0.85], rtol=1e-13)


# -- bad arguments -------------------------------------------------------------------------


def test_bad_arguments(model):
    design = design_observer(model, order=1, bandwidth=100.0)
    with pytest.raises(ParameterTypeError, match="observer must be a DisturbanceObserver"):
        estimation_response("HPDOb", 1.0)
    with pytest.raises(ParameterTypeError, match="observer must be"):
        estimation_transfer(None)
    with pytest.raises(ParameterValueError, match=r"frequency must be non-negative.*-1\.0"):
        estimation_response(design, [1.0, -1.0])
    with pytest.raises(ParameterValueError, match="frequency must hold at least one"):
        estimation_response(design, [])
    with pytest.raises(ParameterTypeError, match="error must be True or False"):
        estimation_transfer(design, error=1)
    # Unstable requested poles are refused where they are requested, naming the value.
    with pytest.raises(ParameterValueError, match=r"poles must lie strictly inside.*1\.2"):
        DisturbanceObserver(model, order=1, poles=[1.2, 0.5])
