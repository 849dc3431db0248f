"""The logged loop of IDIM-IV: FeedbackLoop and its simulation (exact stick-slip integration)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg

from hpdob import (
    ADRC,
    PD,
    PID,
    Actuator,
    Encoder,
    FilteredPD,
    ParameterTypeError,
    ParameterValueError,
    ServoLoop,
    ServoModel,
    simulate,
)
from hpdob.controllers import ForceControl, PositionForceSwitch, controller_system
from hpdob.identification import FeedbackLoop, emps, emps_loop, simulate_loop
from hpdob.identification._loop_kernel import loop_kernel, run_loop
from hpdob.signals import Sine, SmoothStep

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
    rows = (np.zeros(1, dtype=np.int64), np.zeros(0), np.zeros(0, dtype=np.int64))
    pd_law = (np.zeros(n), np.zeros(0), np.zeros(0, dtype=np.int64), rows, rows)
    outputs = [(np.empty(n), np.empty(n)) for _ in range(2)]
    assert run_loop(*args, *outputs[0], *pd_law) == n
    assert loop_kernel()(*args, *outputs[1], *pd_law) == n
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


# --- any linear controller of hpdob.controllers (issue 20: the controller consumed unchanged) ---

J_PLANT, B_PLANT, J_NOM, TS_LOOP = 3.06e-4, 5e-5, 2.8e-4, 1e-3
#: hpdob's linear controllers that need no observer (ADRC runs its own ESO on the angle).
CONTROLLERS = {
    "pid": PID(50.0, 100.0, 5.0),
    "filtered-pd": FilteredPD(50.0, 5.0, time_constant=3e-3),
    "adrc": ADRC(20.0, feedforward=True),
    "pd-without-feedforward": PD(50.0, 5.0, feedforward=False),
}


def reference_signals(n):
    t = np.arange(n) * TS_LOOP
    return (np.sin(3.0 * t), 3.0 * np.cos(3.0 * t), -9.0 * np.sin(3.0 * t))


def python_loop(system, r, r_dot, r_ddot, *, offset, limit, exact_velocity):
    """The loop written out plainly: the controller's dense matrices (u = H c + E v,
    c+ = F c + G [v, u_bar]) and the plant J v' = u - offset - b v by the exact ZOH (expm)."""
    A = np.array([[0.0, 1.0, 0.0], [0.0, -B_PLANT / J_PLANT, 1.0 / J_PLANT], [0.0, 0.0, 0.0]])
    Phi = scipy.linalg.expm(A * TS_LOOP)
    signals = {"r": r, "r_dot": r_dot, "r_ddot": r_ddot}
    c = system.N @ np.zeros(3)
    x = np.zeros(2)
    y_previous = 0.0
    theta, u = [], []
    for k in range(r.size):
        y = x[0]
        velocity = x[1] if exact_velocity else (y - y_previous) / TS_LOOP
        y_previous = y
        now = {"theta": y, "omega": velocity, "tau_hat": 0.0}
        v = np.array([signals[i][k] if i in signals else now[i] for i in system.inputs])
        command = float((system.H @ c + system.E @ v)[0])
        command = float(np.clip(command, -limit, limit))
        c = system.F @ c + system.G @ np.append(v, command)
        theta.append(y)
        u.append(command)
        x = (Phi @ np.append(x, command - offset))[:2]
    return np.array(theta), np.array(u)


@pytest.mark.parametrize("name", list(CONTROLLERS))
@pytest.mark.parametrize("exact_velocity", [False, True], ids=["encoder", "ideal"])
def test_any_linear_controller_runs_as_a_straightforward_python_loop(name, exact_velocity):
    n = 1500
    r, r_dot, r_ddot = reference_signals(n)
    limit = 0.004  # N m: the command saturates on the way up (PID's anti-windup acts)
    loop = FeedbackLoop.from_controller(
        CONTROLLERS[name], nominal=J_NOM, Ts=TS_LOOP, reference=r, reference_velocity=r_dot,
        reference_acceleration=r_ddot, velocity_filter=None if exact_velocity else (1.0, -1.0),
        limit=limit,
    )  # fmt: skip
    theta, u = simulate_loop(loop, (J_PLANT, B_PLANT, 0.0, 0.001), Ts=TS_LOOP)
    system = controller_system(CONTROLLERS[name], ServoModel(J_NOM), TS_LOOP)
    want_theta, want_u = python_loop(
        system, r, r_dot, r_ddot, offset=0.001, limit=limit, exact_velocity=exact_velocity
    )
    assert np.any(np.abs(u) == limit)  # the limit acts
    np.testing.assert_allclose(theta, want_theta, rtol=0, atol=1e-9 * np.max(np.abs(want_theta)))
    np.testing.assert_allclose(u, want_u, rtol=0, atol=1e-7 * limit)


@pytest.mark.parametrize("name", ["pid", "filtered-pd", "adrc"])
@pytest.mark.parametrize("sensor", ["ideal", "encoder"])
def test_the_loop_of_a_controller_is_its_simulate_run_without_observer(name, sensor):
    """The same controller on the same friction-free plant: hpdob.simulate (sub-stepped ZOH)
    and simulate_loop (closed-form ZOH) agree to rounding with the ideal sensor; with a fine
    encoder (2**40 counts/rev: resolution 5.7e-12 rad, which simulate quantises and
    simulate_loop does not) to the quantisation's effect."""
    controller = CONTROLLERS[name]
    encoder = Encoder(2**40) if sensor == "encoder" else None
    loop = ServoLoop(
        plant=ServoModel(J_PLANT, B_PLANT), nominal=ServoModel(J_NOM), Ts=TS_LOOP,
        controller=controller, sensor=encoder, actuator=Actuator(torque_limit=0.004),
    )  # fmt: skip
    reference = Sine(1.0, 0.5) + SmoothStep(0.2, 0.7, amplitude=0.5)
    run = simulate(loop, reference=reference, duration=2.0, x0=(0.1, -0.5))
    fitted = FeedbackLoop.from_controller(
        controller, nominal=loop.nominal, Ts=TS_LOOP, reference=run.r,
        reference_velocity=run.r_dot, reference_acceleration=run.r_ddot,
        velocity_filter=(1.0, -1.0) if encoder else None, limit=0.004,
    )  # fmt: skip
    theta, u = simulate_loop(fitted, (J_PLANT, B_PLANT, 0.0, 0.0), Ts=TS_LOOP, theta0=0.1,
                             velocity0=-0.5)  # fmt: skip
    assert np.any(np.abs(run.u) == 0.004)
    scale = np.max(np.abs(run.theta))
    # measured 2026-12-02: |theta| error up to 6e-13 (ideal) and 1.4e-11 (encoder) of the motion
    tolerance = 1e-10 if encoder is None else 1e-9
    np.testing.assert_allclose(theta, run.theta, rtol=0, atol=tolerance * scale)
    np.testing.assert_allclose(u, run.u, rtol=0, atol=tolerance * 1e3 * 0.004)


def test_from_controller_of_a_pd_is_from_pd_bit_for_bit():
    r, r_dot, r_ddot = reference_signals(400)
    args = {"reference": r, "reference_velocity": r_dot, "reference_acceleration": r_ddot,
            "limit": 0.01}  # fmt: skip
    old = FeedbackLoop.from_pd(PD(50.0, 5.0), J_n=J_NOM, **args)
    new = FeedbackLoop.from_controller(PD(50.0, 5.0), nominal=ServoModel(J_NOM), **args)
    written = FeedbackLoop(r, kp=J_NOM * 50.0, kd=J_NOM * 5.0, reference_velocity=r_dot,
                           feedforward=J_NOM * r_ddot, limit=0.01)  # fmt: skip
    assert old.controller is None and new.controller is None
    runs = [simulate_loop(loop, (J_PLANT, B_PLANT, 0.002, 0.0), Ts=TS_LOOP)
            for loop in (old, new, written)]  # fmt: skip
    for theta, u in runs[1:]:
        assert np.array_equal(theta, runs[0][0]) and np.array_equal(u, runs[0][1])


def test_controllers_that_need_an_observer_or_switch_are_refused():
    r = np.zeros(10)
    with pytest.raises(ParameterValueError, match=r"controller must read only .*tau_reac"):
        FeedbackLoop.from_controller(ForceControl(2000.0), nominal=J_NOM, Ts=TS_LOOP, reference=r)
    switch = PositionForceSwitch(50.0, 5.0, 2000.0, tau_ref=0.01, threshold=0.005)
    with pytest.raises(ParameterValueError, match="controller must read only"):
        FeedbackLoop.from_controller(switch, nominal=J_NOM, Ts=TS_LOOP, reference=r)
    with pytest.raises(ParameterValueError, match="controller must use the measured velocity"):
        FeedbackLoop.from_pd(PD(50.0, 5.0, velocity="observer"), J_n=J_NOM, reference=r)
    with pytest.raises(ParameterValueError, match="Ts must be given for a PID"):
        FeedbackLoop.from_controller(PID(50.0, 100.0, 5.0), nominal=J_NOM, reference=r)
    with pytest.raises(ParameterTypeError, match="controller must be a PD, PID"):
        FeedbackLoop.from_controller("pid", nominal=J_NOM, Ts=TS_LOOP, reference=r)
    with pytest.raises(ParameterValueError, match="nominal must be a ServoModel or a positive"):
        FeedbackLoop.from_controller(PD(1.0, 1.0), nominal=-1.0, reference=r)
    system = controller_system(PID(50.0, 100.0, 5.0), ServoModel(J_NOM), TS_LOOP)
    with pytest.raises(ParameterValueError, match="kp and kd must be 0 with a controller"):
        FeedbackLoop(r, kp=1.0, kd=0.0, controller=system)
    loop = FeedbackLoop(r, kp=0.0, kd=0.0, controller=system)
    with pytest.raises(ParameterValueError, match=r"Ts must be the sampling period .* 0\.001 s"):
        simulate_loop(loop, (J_PLANT, B_PLANT, 0.0, 0.0), Ts=2e-3)
