"""External torque and force: the momentum observer and the per-joint observers against
MuJoCo's applied force (xfrc_applied), and the momentum observer against its literal recursion."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hpdob import PD, Actuator, ServoModel, design_observer
from hpdob.robots import (
    PANDA_READY,
    PANDA_TORQUE_LIMITS,
    ArmLoop,
    JointSines,
    TwoLinkArm,
    end_effector_force,
    joint_observer_external,
    momentum_observer,
    panda,
    simulate_arm,
)

pytest.importorskip("mujoco")

Q0 = np.array(PANDA_READY)
F = np.array([10.0, 0.0, 0.0])  # a 10 N step along x at the flange from t = 0.2 s
T_STEP = 0.2


def hold(t):
    return np.tile(Q0, (len(t), 1)), np.zeros((len(t), 7)), np.zeros((len(t), 7))


def step_force(t):
    return np.where(np.asarray(t)[:, None] >= T_STEP, F, 0.0)


K_O = 50.0
DOB_100 = {"order": 0, "bandwidth": 100.0}
#: the HPDOb at the DOb-100's encoder noise (benchmarks/bench_robots.py: 49 rad/s on every joint)
HPDOB_49 = {"order": 1, "bandwidth": 49.0}
HPDOB_55 = {"order": 1, "bandwidth": 55.0}
_RUNS = {}


def rest_run(spec):
    """The Panda at rest at the ready pose, PD + ``spec`` per joint, a 10 N step at the flange."""
    key = tuple(sorted(spec.items()))
    if key not in _RUNS:
        arm = panda()
        limits = [Actuator(torque_limit=t) for t in PANDA_TORQUE_LIMITS]
        loop = ArmLoop(arm, 1e-3, PD(400.0, 40.0), observers=spec, q0=Q0, actuator=limits)
        res = simulate_arm(loop, duration=T_STEP + 5.0 / K_O + 0.05, reference=hold,
                           external=step_force, tau0="gravity")  # fmt: skip
        _RUNS[key] = (arm, loop, res)
    return _RUNS[key]


@pytest.fixture(scope="module")
def at_rest():
    return rest_run(DOB_100)


def relative_error(est, res, start):
    late = res.t >= start
    truth = res.tau_external[late]
    return np.linalg.norm(est[late] - truth, axis=1) / np.linalg.norm(truth, axis=1)


def q_filtered(spec, J_n, x):
    """``Q x`` per joint from the order-m family's closed form ``1 - Q(z) = (z - 1)^(m+1) /
    prod (z - p_i)`` (the design's poles), written out here with scipy: independent of the
    observer matrices the estimate runs."""
    from scipy.signal import lfilter

    out = np.empty_like(x)
    for i, J in enumerate(J_n):
        poles = design_observer(ServoModel(J).discretize(1e-3), **spec).poles
        num, den = np.poly(np.ones(spec["order"] + 1)), np.real(np.poly(poles))
        out[:, i] = x[:, i] - lfilter(num, den, x[:, i])
    return out


def test_ground_truth_is_jt_f(at_rest):
    arm, _, res = at_rest
    k = np.searchsorted(res.t, 0.3)
    assert np.allclose(res.tau_external[k], arm.jacobian(res.q[k]).T @ F, atol=1e-12)
    assert np.all(res.tau_external[res.t < T_STEP] == 0.0)


def test_momentum_observer_within_2_percent_after_5_over_ko(at_rest):
    arm, _, res = at_rest
    est = momentum_observer(arm, res, gain=K_O)
    assert relative_error(est.tau, res, T_STEP + 5.0 / K_O).max() < 0.02  # measured 0.6 %
    assert np.abs(est.tau[res.t < T_STEP]).max() < 1e-9  # no contact, exact model: no force
    assert np.allclose(est.force[-1], F, atol=0.02 * 10.0)


def test_dob_per_joint_within_2_percent_after_5_over_ko(at_rest):
    """The target at the stated settings: DOb 100 rad/s per joint, K_o = 50 1/s, at rest."""
    arm, loop, res = at_rest
    est = joint_observer_external(res, arm, loop=loop)
    assert relative_error(est.tau, res, T_STEP + 5.0 / K_O).max() < 0.2 * 0.02  # measured 0.025 %
    assert np.abs(est.tau[res.t < T_STEP]).max() < 1e-6
    assert np.allclose(est.force[-1], F, atol=0.002 * 10.0)
    alone = joint_observer_external(res)  # without a model: -tau_hat, gravity included
    assert np.allclose(alone.tau, -res.tau_hat)


@pytest.mark.parametrize("spec", [DOB_100, HPDOB_49], ids=["dob-100", "hpdob-49"])
def test_joint_estimate_is_q_of_the_external_torque(spec):
    """The model terms pass through the observer's own Q, so the estimate is Q tau_ext (to the
    discretisation of the coupling), Q from the family's closed form."""
    _, loop, res = rest_run(spec)
    est = joint_observer_external(res, loop.plant, loop=loop)
    expected = q_filtered(spec, loop.nominal_inertia, res.tau_external)
    scale = np.linalg.norm(res.tau_external[-1])
    assert np.abs(est.tau - expected).max() < 1e-3 * scale  # measured 2e-4


def test_hpdob_49_misses_2_percent_by_its_own_q():
    """The HPDOb at 49 rad/s cannot meet 2 % at 5/K_o = 0.1 s: its estimate is Q tau_ext and the
    step error of 1 - Q = (z - 1)^2/(z - p)^2 is still 3.0 % there (continuous time:
    e^{-4.9} (4.9 - 1) = 2.9 %); from 55 rad/s it is below 2 %."""
    from scipy.signal import lfilter

    for spec, meets in ((HPDOB_49, False), (HPDOB_55, True)):
        arm, loop, res = rest_run(spec)
        error = relative_error(joint_observer_external(res, arm, loop=loop).tau, res,
                               T_STEP + 5.0 / K_O).max()  # fmt: skip
        p = np.exp(-spec["bandwidth"] * 1e-3)  # the bandwidth design's double pole
        step_error = -lfilter(np.poly([1.0, 1.0]), np.poly([p, p]), np.ones(101))[100]
        assert abs(error - step_error) < 0.1 * step_error  # measured 2.90 vs 3.0 %, 1.83 vs 1.90 %
        assert (error < 0.02) == meets


def test_unknown_payload_reads_as_its_weight():
    """The nominal model lacks the 1 kg payload: at rest both estimators report its weight
    (0, 0, -9.81) N as an external force -- the false force of a wrong model."""
    heavy, nominal = panda(payload=1.0), panda()
    loop = ArmLoop(heavy, 1e-3, PD(400.0, 40.0), observers={"order": 0, "bandwidth": 100.0},
                   nominal=nominal, q0=Q0,
                   actuator=[Actuator(torque_limit=t) for t in PANDA_TORQUE_LIMITS])  # fmt: skip
    res = simulate_arm(loop, duration=0.4, reference=hold, tau0="gravity")
    weight = np.array([0.0, 0.0, -9.81])
    est = momentum_observer(nominal, res, gain=50.0)
    assert np.allclose(est.force[-1], weight, atol=0.02 * 9.81)
    joint = joint_observer_external(res, nominal, loop=loop)
    assert np.allclose(joint.force[-1], weight, atol=0.02 * 9.81)


def test_momentum_observer_is_its_literal_recursion():
    """r_{k+1} = K_o (p_{k+1} - p_0 - sigma_{k+1}), sigma_{k+1} = sigma_k + Ts (u_k +
    (beta_k + beta_{k+1})/2 + r_k), beta = C^T qd - g - B qd, with M, C^T qd and g of the
    two-link arm written out here."""
    arm = TwoLinkArm(m=(1.3, 0.9), l=(0.5, 0.4), lc=(0.22, 0.17), I=(0.021, 0.013),
                     b=(0.1, 0.05))  # fmt: skip
    loop = ArmLoop(arm, 1e-3, PD(400.0, 40.0))
    ref = JointSines(center=(0.0, 0.0), amplitude=(1.0, 0.8), frequency=(0.8, 1.2))

    def push(t):
        return np.stack([np.where(t >= 0.1, 0.5, 0.0), np.where(t >= 0.1, -0.3, 0.0)], axis=1)

    res = simulate_arm(loop, duration=0.4, reference=ref, external=push)
    K_o, Ts = 60.0, 1e-3
    (m1, m2), (l1, _), (c1, c2), (I1, I2) = arm.m, arm.l, arm.lc, arm.I
    r = np.zeros((len(res.t), 2))
    sigma, p0, beta_prev = np.zeros(2), None, None
    for k, (q, qd) in enumerate(zip(res.q, res.qd, strict=True)):
        co, si = math.cos(q[1]), math.sin(q[1])
        m12 = m2 * (c2**2 + l1 * c2 * co) + I2
        M = np.array([[m1 * c1**2 + I1 + m2 * (l1**2 + c2**2 + 2 * l1 * c2 * co) + I2, m12],
                      [m12, m2 * c2**2 + I2]])  # fmt: skip
        p = M @ qd
        ctq = np.array([0.0, -m2 * l1 * c2 * si * qd[0] * (qd[0] + qd[1])])
        s12 = math.sin(q[0] + q[1])
        g = np.array([(m1 * c1 + m2 * l1) * 9.81 * math.sin(q[0]) + m2 * c2 * 9.81 * s12,
                      m2 * c2 * 9.81 * s12])  # fmt: skip
        beta = ctq - g - np.array(arm.b) * qd
        if p0 is None:
            p0 = p
        else:
            sigma = sigma + Ts * (res.u[k - 1] + 0.5 * (beta_prev + beta) + r[k - 1])
            r[k] = K_o * (p - p0 - sigma)
        beta_prev = beta
    est = momentum_observer(arm, res, gain=K_o, measured=False)
    assert np.allclose(est.tau, r, rtol=0, atol=1e-9)
    # and it converges on the applied torque (the arm in motion), to 2 %
    late = res.t >= 0.1 + 5.0 / K_o
    assert np.abs(est.tau[late] - res.tau_external[late]).max() < 0.02 * 0.5


def test_damped_pseudo_inverse_recovers_a_force():
    arm = panda()
    J = arm.jacobian(Q0)
    force = end_effector_force(arm, Q0[None], (J.T @ np.array([1.0, -2.0, 3.0]))[None], damping=0.0)
    assert np.allclose(force[0], [1.0, -2.0, 3.0], atol=1e-10)


def test_a_wrench_at_the_flange_is_recovered():
    """Force and moment applied through xfrc_applied; the momentum observer's torques and the
    6-row damped pseudo-inverse give both back (7 joints, 6 unknowns: determined)."""
    arm = panda()
    wrench = np.array([3.0, -4.0, 5.0, 0.5, -0.3, 0.2])

    def push(t):
        return np.where(np.asarray(t)[:, None] >= 0.1, wrench, 0.0)

    loop = ArmLoop(arm, 1e-3, PD(400.0, 40.0), observers={"order": 0, "bandwidth": 100.0},
                   q0=Q0)  # fmt: skip
    res = simulate_arm(loop, duration=0.4, reference=hold, external=push, tau0="gravity")
    jac = arm.jacobian(res.q[-1], rotational=True)
    assert np.allclose(res.tau_external[-1], jac.T @ wrench, atol=1e-12)
    est = momentum_observer(arm, res, gain=50.0)
    six = end_effector_force(arm, res.q[-1:], est.tau[-1:], damping=0.0, wrench=True)[0]
    assert np.allclose(six, wrench, atol=0.02 * np.abs(wrench).max())


@pytest.fixture(scope="module")
def false_force():
    """|F| [N] with no contact during the fast trajectory (t >= 0.5 s of 1.5 s), exact nominal
    model: {(sensor, estimator): rms} for the momentum observer and the per-joint observers."""
    from hpdob import Encoder

    arm = panda()
    limits = [Actuator(torque_limit=t) for t in PANDA_TORQUE_LIMITS]
    reference = JointSines(center=Q0, amplitude=0.5, frequency=1.4)
    rms = {}
    for sensor_name, sensor in (("ideal", None), ("encoder", Encoder(2**18))):
        for name, spec in (("DOb", DOB_100), ("HPDOb", HPDOB_49)):
            loop = ArmLoop(arm, 1e-3, PD(400.0, 40.0), observers=spec, q0=Q0, actuator=limits,
                           sensor=sensor)  # fmt: skip
            res = simulate_arm(loop, duration=1.5, reference=reference, tau0="gravity")
            late = res.t >= 0.5
            estimates = {name: joint_observer_external(res, arm, loop=loop),
                         f"momentum/{name}": momentum_observer(arm, res, gain=K_O)}  # fmt: skip
            for estimator, est in estimates.items():
                force = np.linalg.norm(est.force[late], axis=1)
                rms[sensor_name, estimator] = float(np.sqrt(np.mean(force**2)))
    return rms


def test_false_force_in_motion_with_ideal_sensing(false_force):
    """docs/robots.md: exact model, ideal sensor: the per-joint estimates read less false force
    than the momentum observer (0.04 against 0.21 N RMS; they cancel the coupling through the
    measured acceleration, the momentum observer lags it by K_o), all well under 1 N."""
    for name in ("DOb", "HPDOb"):
        momentum = false_force["ideal", f"momentum/{name}"]
        assert momentum < 0.5
        assert false_force["ideal", name] < 0.5 * momentum  # measured 0.22


def test_false_force_in_motion_with_the_encoder(false_force):
    """With the 18-bit encoder the momentum observer is the better force sensor (2.4 against
    4.6 N RMS): the per-joint estimates difference the noisy velocity once more."""
    for name in ("DOb", "HPDOb"):
        assert false_force["encoder", f"momentum/{name}"] < 0.7 * false_force["encoder", name]


def test_momentum_observer_refuses_a_gain_too_high_for_ts_as_a_value_error(at_rest):
    from hpdob import ParameterValueError

    arm, _, res = at_rest
    with pytest.raises(ParameterValueError, match=r"gain must be .* gain \* Ts < 1 .*got 1000.0"):
        momentum_observer(arm, res, gain=1000.0)  # 1000 1/s * 1 ms = 1
    with pytest.raises(ParameterValueError, match="model must be an arm model with the run's 7"):
        momentum_observer(TwoLinkArm(m=(1, 1), l=(1, 1), lc=(0.5, 0.5), I=(0.1, 0.1)), res,
                          gain=K_O)  # fmt: skip
