"""The estimate's covariance (identification/_solve.py): batch means over contiguous rows, for a
residual correlated over neighbouring rows. Checked against closed forms (white and AR(1)
errors) and against the spread of the estimates over seeds on SYNTHETIC logs
(tests/synthetic_logs.py; benchmarks/bench_identify_std.py is the larger study). Then the IV
iteration's parts: the loop's relative error, the input-driven loop's definition, the
iteration's bound and the one check of a given loop."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from hpdob import ParameterValueError
from hpdob.identification._solve import estimate_iv
from synthetic_logs import synthetic_log


def _ar1(rng, n: int, rho: float) -> np.ndarray:
    """AR(1) noise e_k = rho e_(k-1) + w_k, w white of unit variance, started stationary."""
    w = rng.standard_normal(n)
    e = np.empty(n)
    e[0] = w[0] / np.sqrt(1.0 - rho**2)
    for k in range(1, n):
        e[k] = rho * e[k - 1] + w[k]
    return e


def test_white_errors_give_the_textbook_covariance():
    """White errors: batch means estimate what sigma^2 (X^T X)^-1 does (mean over 30 seeds;
    one estimate from 20 batches scatters by about 30 %)."""
    ratios = []
    for seed in range(30):
        rng = np.random.default_rng(seed)
        X = np.column_stack([rng.standard_normal(4000), np.ones(4000)])
        y = X @ [2.0, -1.0] + 0.3 * rng.standard_normal(4000)
        _, covariance, iid = estimate_iv(X, y, X)
        ratios.append(np.diag(covariance) / np.diag(iid))
    np.testing.assert_allclose(np.mean(ratios, axis=0), 1.0, atol=0.15)


def test_ar1_errors_give_the_long_run_variance():
    """The mean of N samples of AR(1) noise (rho = 0.8) has variance sigma_w^2 / (1 - rho)^2 / N
    = 25 / N (its spectrum at zero frequency); the textbook estimate sigma_e^2 / N =
    1 / (1 - rho^2) / N is 9 times smaller."""
    n, rho = 20000, 0.8
    reported, textbook, means = [], [], []
    for seed in range(30):
        e = _ar1(np.random.default_rng(seed), n, rho)
        X = np.ones((n, 1))
        theta, covariance, iid = estimate_iv(X, e, X)
        means.append(theta[0])
        reported.append(covariance[0, 0])
        textbook.append(iid[0, 0])
    exact = 1.0 / (1.0 - rho) ** 2 / n
    assert np.mean(reported) == pytest.approx(exact, rel=0.15)
    assert np.mean(textbook) == pytest.approx(exact * (1.0 - rho) ** 2 / (1.0 - rho**2), rel=0.1)
    assert 1 / 1.5 < np.std(means, ddof=1) / np.sqrt(np.mean(reported)) < 1.5


def test_several_logs_are_batched_apart():
    """Two logs: batches never straddle them; each log's rows alone give the same estimate."""
    rng = np.random.default_rng(1)
    X = np.column_stack([rng.standard_normal(2000), np.ones(2000)])
    y = X @ [1.0, 0.5] + _ar1(rng, 2000, 0.5)
    _, one, _ = estimate_iv(X, y, X, [(0, 2000)])
    _, two, _ = estimate_iv(X, y, X, [(0, 1000), (1000, 2000)])
    assert np.all(np.diag(two) > 0) and not np.allclose(one, two)
    np.testing.assert_allclose(two, two.T)


def test_the_std_matches_the_spread_over_seeds_on_synthetic_logs():
    """24 PRBS logs (1024 counts, 2 ms, Coulomb 10 % of the input's RMS) that differ by their
    bit sequence and input noise, identified by default: the spread of J, b and Coulomb over
    the seeds is within a factor 1.5 of the mean reported std (measured 1.09, 1.01, 0.96;
    with the first 16 seeds only, 1.07, 0.66, 0.73: a spread from 16 draws scatters by 18 %),
    while the textbook std of b is more than 1.7 times too large (0.44)."""
    estimates, std, iid = [], [], []
    for seed in range(24):
        s = synthetic_log(kind="prbs", counts=1024, Ts=2e-3, coulomb_fraction=0.1, seed=seed)
        fit = s.log.identify(diagnostics=False)
        estimates.append([fit.J, fit.b, fit.coulomb])
        std.append([fit.J_std, fit.b_std, fit.coulomb_std])
        iid.append([fit.std_iid[n] for n in ("J", "b", "coulomb")])
    spread = np.std(estimates, axis=0, ddof=1)
    ratio = spread / np.mean(std, axis=0)
    assert np.all((ratio > 1 / 1.5) & (ratio < 1.5)), ratio
    assert spread[1] / np.mean(iid, axis=0)[1] < 0.6


@pytest.mark.parametrize(
    "logs", [[(0, 1000), (1000, 3000)], [(0, 1000), (1000, 1100), (1100, 3000)]]
)
def test_long_run_covariance_is_the_batch_means_of_the_scores(logs):
    """Formed batch by batch: bit for bit the batch sums of the whole score matrix (a log of
    100 rows after the first: 10 batches of its own length)."""
    from hpdob.identification._solve import COVARIANCE_BATCHES, long_run_covariance

    rng = np.random.default_rng(2)
    Z, error = rng.standard_normal((3000, 4)), rng.standard_normal(3000)
    scores = Z * error[:, None]
    S, count = np.zeros((4, 4)), 0
    for start, stop in logs:
        G = max(2, min(COVARIANCE_BATCHES, (stop - start) // 10))
        edges = np.linspace(start, stop, G + 1).astype(int)
        for lo, hi in itertools.pairwise(edges):
            s = scores[lo:hi].sum(axis=0)
            S += np.outer(s, s)
        count += G
    assert np.array_equal(long_run_covariance(Z, error, logs), S * count / (count - 1))


def test_relative_error_is_the_norm_of_the_difference_in_percent():
    """Eq. 11's percentage, not rounded: 0.125 of a unit vector is 12.5 %."""
    from hpdob.identification._solve import relative_error

    assert relative_error(np.array([1.0, 0.0]), np.array([0.875, 0.0])) == 12.5
    assert relative_error(np.array([0.0, 0.0]), np.zeros(2)) == 0.0
    assert relative_error(np.array([0.0, 0.0]), np.ones(2)) == np.inf


def test_relative_error_into_a_given_array_is_the_same_number():
    """out= takes the difference (numpy's temporary otherwise): the same number, bit for bit."""
    from hpdob.identification._solve import relative_error

    rng = np.random.default_rng(11)
    measured, simulated = rng.standard_normal(30_001), rng.standard_normal(30_001)
    out = np.empty_like(measured)
    assert relative_error(measured, simulated, out=out) == relative_error(measured, simulated)
    assert np.array_equal(out, measured - simulated)


@pytest.mark.parametrize("n", [1, 4095, 4096, 4097, 30_001])
def test_the_loop_mismatch_by_blocks_is_the_relative_error_to_rounding(n):
    """The check's difference block by block (MISMATCH_BLOCK samples): relative_error's number
    to rounding, and its cases at 0."""
    from hpdob.identification._solve import mismatch, relative_error

    rng = np.random.default_rng(n)
    measured, simulated = rng.standard_normal(n), rng.standard_normal(n)
    assert mismatch(measured, simulated) == pytest.approx(
        relative_error(measured, simulated), rel=1e-13
    )
    assert mismatch(np.zeros(n), np.zeros(n)) == 0.0
    assert mismatch(np.zeros(n), np.ones(n)) == np.inf
    assert mismatch(measured, measured) == 0.0


def test_the_input_loop_is_a_slow_pd_on_the_low_passed_position():
    """Bandwidth INPUT_LOOP_FRACTION x the decimation cut-off: its PD gains J w^2 and 2 J w,
    its reference the position through a 2nd-order Butterworth filter at that bandwidth,
    forward and back (sosfiltfilt), the logged input as its feed-forward."""
    from types import SimpleNamespace

    from scipy import signal

    from hpdob.identification._solve import INPUT_LOOP_FRACTION, input_loop

    Ts, cutoff, J = 1e-3, 40.0, 0.02
    t = np.arange(4000) * Ts
    theta = np.sin(2 * np.pi * t) + 0.1 * np.sin(2 * np.pi * 30 * t)
    u = np.cos(2 * np.pi * t)
    loop = input_loop(theta, u, J, SimpleNamespace(decimation_cutoff=cutoff, Ts=Ts))
    omega = 2 * np.pi * INPUT_LOOP_FRACTION * cutoff
    assert loop.kp == J * omega**2 and loop.kd == 2 * J * omega
    sos = signal.butter(2, INPUT_LOOP_FRACTION * cutoff, fs=1 / Ts, output="sos")
    np.testing.assert_array_equal(loop.reference, signal.sosfiltfilt(sos, theta))
    np.testing.assert_array_equal(loop.reference_velocity, np.gradient(loop.reference, Ts))
    np.testing.assert_array_equal(loop.feedforward, u)


@pytest.fixture(scope="module")
def prbs():
    return synthetic_log(kind="prbs", counts=1024, Ts=2e-3, coulomb_fraction=0.1, seed=0).log


def test_the_iteration_stops_at_max_iterations(prbs):
    """A tolerance no change meets: exactly max_iterations iterations, not converged."""
    from hpdob.identification import IdentificationWarning

    for most in (2, 3):
        with pytest.warns(IdentificationWarning, match=f"did not converge in {most} iterations"):
            fit = prbs.identify(method="idim-iv-input", max_iterations=most, tolerance=1e-300,
                                diagnostics=False)  # fmt: skip
        assert fit.iterations == most and not fit.converged


def test_the_iteration_stops_when_no_parameter_moves_by_a_hundredth_of_its_std(prbs):
    """Iteration n, the first to converge, moved every parameter by at most 0.01 of its std
    from iteration n - 1, which did not converge (so n > 1 here: the IDIM-LS start is off)."""
    from hpdob.identification import IdentificationWarning

    names = ("J", "b", "coulomb", "offset")
    fit = prbs.identify(method="idim-iv-input", diagnostics=False)
    assert fit.converged and fit.iterations >= 2
    with pytest.warns(IdentificationWarning, match="did not converge"):
        before = prbs.identify(method="idim-iv-input", max_iterations=fit.iterations - 1,
                               diagnostics=False)  # fmt: skip
    change = np.abs([getattr(fit, n) - getattr(before, n) for n in names])
    assert np.all(change <= 0.01 * np.array([getattr(fit, f"{n}_std") for n in names]))


def _motion(n=5000, Ts=1e-3, phase=0.0):
    t = np.arange(n) * Ts
    q = 0.3 * np.sin(2 * np.pi * t + phase) + 0.05 * np.sin(2 * np.pi * 3 * t)
    u = np.gradient(np.gradient(q, Ts), Ts) + 2 * np.sign(np.gradient(q, Ts)) + 0.5
    return t, q, u


def test_a_loop_that_is_not_the_logs_is_refused_before_the_first_iteration():
    """The loop is checked once, simulated with the IDIM-LS estimate: refused before any IV
    iteration is reported; with several logs, the message names the log whose loop it is."""
    from hpdob import identify
    from hpdob.identification import FeedbackLoop, Log

    t, q, u = _motion()
    resting = FeedbackLoop(np.zeros(t.size), kp=0.0, kd=0.0)  # not the loop that moved the axis
    reports = []
    with pytest.raises(ParameterValueError, match=r"^loop does not describe .* IDIM-LS estimate"):
        identify(t, q, u, method="idim-iv", loop=resting,
                 progress=lambda *report: reports.append(report))  # fmt: skip
    assert ("iterating", 0, 20) in reports
    assert not [r for r in reports if r[0] == "iterating" and r[1] > 0]
    logs = [Log(t, q, u, source="a"), Log(*_motion(phase=1.0), source="b")]
    with pytest.raises(ParameterValueError, match=r"^loop of a does not describe"):
        identify(logs, method="idim-iv", loop=[resting, resting])


def test_a_simulable_estimate_has_no_negative_friction_and_a_positive_inertia():
    """Negative friction is set to 0 for the loop's simulation; J <= 0 is refused, naming the
    estimate: the IDIM-LS one (iteration 1) or IV iteration k (iteration k + 1)."""
    from hpdob.identification._solve import simulable

    np.testing.assert_array_equal(simulable(np.array([2.0, -1.0, -3.0, -4.0]), 1),
                                  [2.0, 0.0, 0.0, -4.0])  # fmt: skip
    with pytest.raises(ParameterValueError, match=r"loop of a: the IDIM-LS estimate has J = -1 "):
        simulable(np.array([-1.0, 1.0, 1.0, 0.0]), 1, " of a")
    with pytest.raises(ParameterValueError, match=r"loop: IV iteration 2 has J = 0 <= 0"):
        simulable(np.array([0.0, 1.0, 1.0, 0.0]), 3)


def test_the_input_simulation_is_the_loops_without_its_reference_velocity():
    """``run_simulation(input_loop(...))`` bit for bit, without the loop holding its own
    reference velocity: the tracemalloc peak stays under four arrays of the log's length
    (measured 3.66 at 200 000 samples; 4.67 with the loop's own reference velocity)."""
    import tracemalloc
    from types import SimpleNamespace

    from hpdob.identification._loop import run_simulation
    from hpdob.identification._solve import input_loop, input_simulation

    Ts, n = 1e-3, 200_000
    t = np.arange(n) * Ts
    theta, u = np.sin(2 * np.pi * t), 0.01 * np.cos(2 * np.pi * t)
    settings = SimpleNamespace(decimation_cutoff=40.0, Ts=Ts)
    parameters = np.array([1e-3, 2e-3, 0.01, 0.0])
    loop = input_loop(theta, u, parameters[0], settings)
    expected, _ = run_simulation(loop, parameters, Ts=Ts, theta0=theta[0], velocity0=0.0,
                                 command=False)  # fmt: skip
    del loop
    tracemalloc.start()
    try:
        simulated = input_simulation(theta, u, parameters, settings, 0.0)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    np.testing.assert_array_equal(simulated, expected)
    assert peak < 4 * theta.nbytes, peak / theta.nbytes
