"""The logged loop of IDIM-IV: FeedbackLoop and its simulation (exact stick-slip integration)."""

from __future__ import annotations

import numpy as np
import pytest

from hpdob import PD, ParameterValueError
from hpdob.identification import FeedbackLoop, emps, emps_loop, simulate_loop
from hpdob.identification._loop_kernel import loop_kernel, run_loop

TS = 0.01


def push(force, n=1000):
    """A loop that only applies the feed-forward ``force`` (no feedback)."""
    return FeedbackLoop(np.zeros(n), kp=0.0, kd=0.0, feedforward=np.full(n, float(force)))


def test_coulomb_friction_stops_the_axis_where_the_textbook_says():
    # J v' = -c sign(v): v(t) = v0 - c t / J until t_stop = J v0 / c, then at rest for good
    J, c, v0 = 2.0, 1.0, 3.0
    theta, u = simulate_loop(push(0.0), (J, 0.0, c, 0.0), Ts=TS, velocity0=v0)
    t = np.arange(theta.size) * TS
    t_stop = J * v0 / c  # 6 s
    expected = np.where(t < t_stop, v0 * t - c * t**2 / (2 * J), J * v0**2 / (2 * c))
    np.testing.assert_allclose(theta, expected, rtol=1e-12, atol=1e-12)
    assert np.all(u == 0.0)


def test_viscous_friction_is_integrated_exactly():
    # J v' = -b v: q(t) = v0 J/b (1 - exp(-b t / J))
    J, b, v0 = 2.0, 1.0, 3.0
    theta, _ = simulate_loop(push(0.0), (J, b, 0.0, 0.0), Ts=TS, velocity0=v0)
    t = np.arange(theta.size) * TS
    np.testing.assert_allclose(theta, v0 * J / b * (1 - np.exp(-b * t / J)), rtol=1e-12)


def test_stiction_holds_below_the_coulomb_level_and_breaks_away_above():
    J, c = 2.0, 1.0
    held, _ = simulate_loop(push(0.99), (J, 0.0, c, 0.0), Ts=TS)
    assert np.all(held == 0.0)
    # the offset adds to the friction: 1.2 - 0.3 = 0.9 < c also holds
    held, _ = simulate_loop(push(1.2), (J, 0.0, c, 0.3), Ts=TS)
    assert np.all(held == 0.0)
    moved, _ = simulate_loop(push(3.0), (J, 0.0, c, 0.0), Ts=TS)
    t = np.arange(moved.size) * TS
    np.testing.assert_allclose(moved, (3.0 - c) / J * t**2 / 2, rtol=1e-12, atol=1e-15)


def test_controller_law_with_the_emps_velocity_filter():
    n = 300
    r = 0.01 * np.arange(n) * TS  # a ramp
    loop = FeedbackLoop(r, kp=50.0, kd=4.0, velocity_filter=(0.5, 0.0, -0.5), limit=0.012)
    theta, u = simulate_loop(loop, (0.1, 0.2, 0.003, 0.001), Ts=TS)
    y = np.concatenate([[theta[0], theta[0]], theta])  # positions before the start = y_0
    velocity = (y[2:] - y[:-2]) / (2 * TS)  # (y_k - y_(k-2)) / (2 Ts)
    expected = np.clip(50.0 * (r - theta) - 4.0 * velocity, -0.012, 0.012)
    np.testing.assert_allclose(u, expected, rtol=1e-14, atol=1e-17)
    assert np.any(np.abs(u) == 0.012)  # the limit acts


def test_compiled_kernel_equals_plain_python():
    log = emps()
    loop = emps_loop(log)
    n = 3000
    args = (
        95.1,
        203.5,
        20.4,
        -3.16,
        log.Ts,
        log.theta[0],
        0.0,
        loop.reference[:n].copy(),
        np.zeros(n),
        np.zeros(n),
        loop.kp,
        loop.kd,
        np.array(loop.velocity_filter),
        False,
        loop.limit,
        1e9,
    )
    outputs = [(np.empty(n), np.empty(n)) for _ in range(2)]
    assert run_loop(*args, *outputs[0]) == n
    assert loop_kernel()(*args, *outputs[1]) == n
    np.testing.assert_allclose(outputs[1][0], outputs[0][0], rtol=1e-13, atol=1e-18)
    np.testing.assert_allclose(outputs[1][1], outputs[0][1], rtol=1e-12, atol=1e-12)


def test_from_pd_is_hpdobs_pd_in_force_units():
    r = np.linspace(0.0, 1.0, 50)
    loop = FeedbackLoop.from_pd(
        PD(50.0, 5.0),
        J_n=2.8e-4,
        reference=r,
        reference_velocity=np.ones(50),
        reference_acceleration=np.full(50, 2.0),
    )
    assert loop.kp == pytest.approx(2.8e-4 * 50.0) and loop.kd == pytest.approx(2.8e-4 * 5.0)
    np.testing.assert_allclose(loop.feedforward, 2.8e-4 * 2.0)
    no_ff = FeedbackLoop.from_pd(
        PD(50.0, 5.0, feedforward=False), J_n=1.0, reference=r, reference_acceleration=np.ones(50)
    )
    assert no_ff.feedforward is None and no_ff.reference_velocity is None


def test_loop_validation():
    r = np.zeros(10)
    with pytest.raises(ParameterValueError, match="velocity_filter must be a differentiator"):
        FeedbackLoop(r, kp=1.0, kd=1.0, velocity_filter=(-1.0, 1.0))  # sign error
    with pytest.raises(ParameterValueError, match="kp must be a non-negative"):
        FeedbackLoop(r, kp=-1.0, kd=1.0)
    with pytest.raises(ParameterValueError, match="reference has 10, reference_velocity has 9"):
        FeedbackLoop(r, kp=1.0, kd=1.0, reference_velocity=np.zeros(9))
    with pytest.raises(ParameterValueError, match="J > 0, b >= 0 and coulomb >= 0"):
        simulate_loop(push(0.0, 10), (1.0, -1.0, 0.0, 0.0), Ts=TS)


def test_a_diverging_loop_is_reported():
    # a stiff position gain on a light axis: the sampled loop is unstable
    loop = FeedbackLoop(np.ones(2000), kp=1e6, kd=0.0, velocity_filter=(0.5, 0.0, -0.5))
    with pytest.raises(ParameterValueError, match="the simulated loop diverged"):
        simulate_loop(loop, (1e-3, 0.0, 0.0, 0.0), Ts=TS)
