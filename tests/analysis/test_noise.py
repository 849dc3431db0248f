"""Noise gains: exact (Lyapunov) values against seeded Monte Carlo simulations, quadrature and
an analytic case."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hpdob import (
    PD,
    DisturbanceObserver,
    Encoder,
    ParameterValueError,
    ServoModel,
    design_observer,
    noise_gains,
    observer_noise_gain,
    simulate,
)
from hpdob.signals import Constant

TS = 1e-3
NOMINAL = ServoModel(2.8e-4)
PLANT = ServoModel(3.06e-4, 5e-5)  # the canonical motor without Coulomb friction
PDC = PD(50.0, 5.0)
SIGMA = 1e-4  # rad (or rad/s): small enough to stay linear, the result is per unit anyway
N = 24_000  # samples; the first 2000 are discarded as transient


def observer(order, bandwidth=100.0):
    return design_observer(NOMINAL.discretize(TS), order=order, bandwidth=bandwidth)


def rms(values):
    return float(np.sqrt(np.mean(np.square(values[2000:]))))


@pytest.mark.parametrize(
    ("order", "velocity"), [(0, "exact"), (1, "exact"), (3, "exact"), (1, "backward-difference")]
)
def test_position_noise_gains_match_monte_carlo_simulation(order, velocity):
    """hpdob.simulate with a seeded noisy encoder of negligible quantisation (2**40 counts)."""
    design = observer(order)
    sensor = Encoder(2**40, velocity=velocity, noise_std=SIGMA, seed=11 + order)
    exact = noise_gains(
        plant=PLANT, nominal=NOMINAL, Ts=TS, controller=PDC, observer=design, sensor=sensor
    )
    res = simulate(
        plant=PLANT,
        nominal=NOMINAL,
        Ts=TS,
        duration=N * TS,
        controller=PDC,
        observer=design,
        reference=Constant(0.0),
        sensor=sensor,
        substeps=1,
    )
    assert rms(res.tau_hat) / SIGMA == pytest.approx(exact.tau_hat_position, rel=0.03)
    assert rms(res.u) / SIGMA == pytest.approx(exact.u_position, rel=0.03)


def velocity_noise_loop(design, seed):
    """An independent loop: true plant ZOH step, PD, runtime observer, noisy velocity."""
    plant = PLANT.discretize(TS)
    obs = DisturbanceObserver.from_design(design)
    noise = SIGMA * np.random.default_rng(seed).standard_normal(N)
    x = np.zeros(2)
    tau_hat, u = np.empty(N), np.empty(N)
    for k in range(N):
        measured = (float(x[0]), float(x[1] + noise[k]))
        tau_hat[k] = obs.estimate(measured)
        u[k] = -NOMINAL.J * (PDC.kp * measured[0] + PDC.kd * measured[1]) + tau_hat[k]
        obs.update(measured, u[k])
        x = plant.step(x, u[k])
    return tau_hat, u


@pytest.mark.parametrize("order", [0, 2])
def test_velocity_noise_gains_match_monte_carlo(order):
    design = observer(order)
    exact = noise_gains(plant=PLANT, nominal=NOMINAL, Ts=TS, controller=PDC, observer=design)
    tau_hat, u = velocity_noise_loop(design, seed=5)
    assert rms(tau_hat) / SIGMA == pytest.approx(exact.tau_hat_velocity, rel=0.03)
    assert rms(u) / SIGMA == pytest.approx(exact.u_velocity, rel=0.03)


def quadrature_h2(design, channel):
    """sqrt(mean |H(e^jw)|^2) by the trapezoid rule on the unit circle (spectrally accurate
    for a rational H; 200 000 points resolve poles at radius 0.997)."""
    sys = design.to_statespace()
    n = 200_000
    z = np.exp(2j * np.pi * (np.arange(n) + 0.5) / n)
    A, B, C, D = sys.A, sys.B[:, [channel]], sys.C, sys.D[0, channel]
    x = np.linalg.solve(
        z[:, None, None] * np.eye(A.shape[0]) - A, np.broadcast_to(B, (n, *B.shape))
    )
    H = (C @ x)[:, 0, 0] + D
    return math.sqrt(np.mean(np.abs(H) ** 2))


@pytest.mark.parametrize(("order", "bandwidth"), [(1, 100.0), (3, 3.0), (3, 2000.0)])
def test_lyapunov_matches_frequency_domain_quadrature(order, bandwidth):
    """Including poles 4-fold at 0.997 (m = 3, 3 rad/s), where a Kronecker solve on the
    companion form loses digits; the Schur-form solve keeps them."""
    design = observer(order, bandwidth)
    for channel, noise in enumerate(("position", "velocity")):
        assert observer_noise_gain(design, noise=noise) == pytest.approx(
            quadrature_h2(design, channel), rel=1e-8
        )


def test_dob_noise_gain_in_closed_form():
    """m = 0: tau_hat = -l_w n + Kx_w sum_k lam^(k-1) n_(k-1), so the H2 norm squared is
    l_w^2 + Kx_w^2 / (1 - lam^2) for velocity noise."""
    design = observer(0, 150.0)
    lam = design.error_matrix[0, 0]
    expected = math.sqrt(design.gains[0, 1] ** 2 + design.state_input[0, 1] ** 2 / (1 - lam**2))
    assert observer_noise_gain(design) == pytest.approx(expected, rel=1e-13)


def test_estimate_noise_gain_on_nominal_plant_does_not_depend_on_controller():
    design = observer(2, 250.0)
    own = (observer_noise_gain(design, noise="position"), observer_noise_gain(design))
    for controller in (PD(50.0, 5.0), PD(400.0, 40.0), PD(0.0, 0.0)):
        if controller.kp == 0:
            continue  # kp = kd = 0 leaves the double integrator marginally stable
        g = noise_gains(
            plant=NOMINAL, nominal=NOMINAL, Ts=TS, controller=controller, observer=design
        )
        assert (g.tau_hat_position, g.tau_hat_velocity) == pytest.approx(own, rel=1e-9)


def test_pd_only_has_no_estimate_noise_and_unstable_loop_is_refused():
    g = noise_gains(plant=PLANT, nominal=NOMINAL, Ts=TS, controller=PDC)
    assert g.tau_hat_position == 0.0 and g.tau_hat_velocity == 0.0
    assert g.u_position > 0 and g.theta_velocity > 0
    with pytest.raises(ParameterValueError, match=r"asymptotically stable.*spectral radius"):
        noise_gains(
            plant=ServoModel(0.05 * NOMINAL.J),
            nominal=NOMINAL,
            Ts=TS,
            controller=PDC,
            observer=observer(1),
        )
    with pytest.raises(
        ParameterValueError, match="noise must be one of 'velocity', 'position', 'encoder'"
    ):
        observer_noise_gain(observer(1), noise="acceleration")


@pytest.mark.parametrize("velocity", ["exact", "backward-difference"])
def test_one_channels_gains_are_noise_gains_bit_for_bit(velocity):
    """tune asks for the position channel only (channel_noise_gains, one Lyapunov solve
    instead of two): the same figures as noise_gains, bit for bit, and the same refusal."""
    from hpdob import ServoLoop
    from hpdob.analysis import channel_noise_gains
    from hpdob.observers import design_kalman

    kalman = design_kalman(NOMINAL.discretize(TS), order=1, position_noise_std=1e-4,
                           process_noise_std=1e-2)  # fmt: skip
    for design in (observer(0), observer(2, 40.0), kalman):
        loop = ServoLoop(plant=PLANT, nominal=NOMINAL, Ts=TS, controller=PDC, observer=design,
                         sensor=Encoder(16384, velocity=velocity))  # fmt: skip
        g = noise_gains(loop)
        for channel in ("position", "velocity"):
            got = channel_noise_gains(loop, channel)
            expected = [getattr(g, f"{name}_{channel}") for name in ("tau_hat", "u", "theta")]
            assert got.tolist() == expected
    unstable = loop.replace(plant=ServoModel(0.05 * NOMINAL.J))
    with pytest.raises(ParameterValueError, match=r"asymptotically stable.*spectral radius"):
        channel_noise_gains(unstable, "position")
    with pytest.raises(ParameterValueError, match="channel must be one of"):
        channel_noise_gains(loop, "encoder")


def _schur_systems(count: int, seed: int):
    """Stable systems in real Schur form (seeded), a third with real poles up to 1e-12 from the
    unit circle (the observer's slow clusters: scipy's condition estimate warns on them)."""
    from scipy.linalg import schur

    rng = np.random.default_rng(seed)
    for trial in range(count):
        n = int(rng.integers(1, 13))
        A = rng.standard_normal((n, n))
        if trial % 3 == 0:
            A = np.diag(1.0 - 10.0 ** rng.uniform(-12, -1, n))
            A += np.triu(0.1 * rng.standard_normal((n, n)), 1)
        A = A / (max(abs(np.linalg.eigvals(A))) * (1.0 + 10.0 ** rng.uniform(-10, 0)))
        T, U = schur(A, output="real")
        B = U.T @ rng.standard_normal((n, 1))
        yield T, B @ B.T


def test_the_lyapunov_solve_is_scipys_bit_for_bit_and_never_warns():
    """The noise gains' Lyapunov solve gives scipy.linalg.solve_discrete_lyapunov's numbers
    bit for bit (the direct Kronecker solve below 10 states by the LAPACK routines
    scipy.linalg.solve runs, the bilinear method from 10 on) without warning: silencing
    scipy's condition warning with warnings.catch_warnings raced with numba's compiling in
    tune()'s run thread (a LinAlgWarning escaped as an error, or a filter stayed set)."""
    import warnings

    from scipy.linalg import LinAlgWarning, solve_discrete_lyapunov

    from hpdob.analysis._noise import discrete_lyapunov

    warned = 0
    for T, Q in _schur_systems(600, seed=4):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", LinAlgWarning)
            reference = solve_discrete_lyapunov(T, Q)
        warned += bool(caught)
        got = discrete_lyapunov(T, Q)  # filterwarnings = error: any warning fails
        assert np.array_equal(got.view(np.int64), reference.view(np.int64))
    assert warned > 0  # the cases scipy warns on are among them


@pytest.mark.parametrize("where", ["a", "q"])
def test_the_lyapunov_solve_refuses_non_finite_input_as_scipy_does(where):
    """A NaN or inf in either matrix: scipy.linalg.solve's ValueError, not a solve of it."""
    from scipy.linalg import solve_discrete_lyapunov

    from hpdob.analysis._noise import discrete_lyapunov

    a, q = np.array([[0.5, 0.1], [0.0, 0.3]]), np.eye(2)
    (a if where == "a" else q)[0, 1] = np.nan
    for solver in (solve_discrete_lyapunov, discrete_lyapunov):
        with pytest.raises(ValueError, match="infs or NaNs"):
            solver(a, q)
