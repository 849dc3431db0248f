"""External torque and force: the momentum observer and the per-joint observers against
MuJoCo's applied force (xfrc_applied), and the momentum observer against its literal recursion."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hpdob import PD, Actuator
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


@pytest.fixture(scope="module")
def at_rest():
    arm = panda()
    loop = ArmLoop(arm, 1e-3, PD(400.0, 40.0), observers={"order": 1, "bandwidth": 100.0}, q0=Q0,
                   actuator=[Actuator(torque_limit=t) for t in PANDA_TORQUE_LIMITS])  # fmt: skip
    return arm, loop, simulate_arm(loop, duration=0.45, reference=hold, external=step_force,
                                   tau0="gravity")  # fmt: skip


def test_ground_truth_is_jt_f(at_rest):
    arm, _, res = at_rest
    k = np.searchsorted(res.t, 0.3)
    assert np.allclose(res.tau_external[k], arm.jacobian(res.q[k]).T @ F, atol=1e-12)
    assert np.all(res.tau_external[res.t < T_STEP] == 0.0)


def test_momentum_observer_within_2_percent_after_5_over_ko(at_rest):
    arm, _, res = at_rest
    K_o = 50.0
    est = momentum_observer(arm, res, gain=K_o)
    late = res.t >= T_STEP + 5.0 / K_o
    truth = res.tau_external[late]
    error = np.linalg.norm(est.tau[late] - truth, axis=1) / np.linalg.norm(truth, axis=1)
    assert error.max() < 0.02  # measured 0.6 %
    assert np.abs(est.tau[res.t < T_STEP]).max() < 1e-9  # no contact, exact model: no force
    assert np.allclose(est.force[-1], F, atol=0.02 * 10.0)


def test_joint_observers_external_torque_and_force(at_rest):
    arm, loop, res = at_rest
    est = joint_observer_external(res, arm, nominal_inertia=loop.nominal_inertia,
                                  nominal_friction=loop.nominal_friction)  # fmt: skip
    late = res.t >= T_STEP + 0.15
    truth = res.tau_external[late]
    error = np.linalg.norm(est.tau[late] - truth, axis=1) / np.linalg.norm(truth, axis=1)
    assert error.max() < 0.02  # measured 0.06 %
    assert np.abs(est.tau[res.t < T_STEP]).max() < 1e-6
    assert np.allclose(est.force[-1], F, atol=0.02 * 10.0)
    alone = joint_observer_external(res)  # without a model: -tau_hat, gravity included
    assert np.allclose(alone.tau, -res.tau_hat)


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
    joint = joint_observer_external(res, nominal, nominal_inertia=loop.nominal_inertia,
                                    nominal_friction=loop.nominal_friction)  # fmt: skip
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
