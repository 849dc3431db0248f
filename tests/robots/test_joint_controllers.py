"""Every controller of the protocol per joint: the N-joint kernel's stacked controller rows
compute, bit for bit, each joint's controller as its own generated Python computes it."""

from __future__ import annotations

import numpy as np
import pytest

from hpdob import PD, Actuator, Encoder, ServoModel
from hpdob.controllers import ADRC, PID, FilteredPD  # the controller protocol (issue 20)
from hpdob.robots import ArmLoop, JointSines, TwoLinkArm, simulate_arm

ARM = TwoLinkArm(m=(1.3, 0.9), l=(0.5, 0.4), lc=(0.22, 0.17), I=(0.021, 0.013), J=(0.05, 0.03))
REFERENCE = JointSines(center=(0.0, 0.0), amplitude=0.6, frequency=1.0)

PAIRS = [
    (PD(400.0, 40.0), PID(400.0, 2000.0, 40.0, tracking_time=0.05)),
    (FilteredPD(400.0, 40.0, time_constant=2e-3), ADRC(20.0, observer_bandwidth=150.0)),
    (PID(300.0, 1000.0, 35.0), PD(400.0, 40.0, velocity="observer")),
]


@pytest.mark.parametrize("pair", PAIRS, ids=["pd-pid", "filtered-adrc", "pid-pd-observer"])
def test_stacked_controllers_equal_each_joints_controller(pair):
    observers = [{"order": 0, "bandwidth": 80.0}, {"order": 1, "bandwidth": 100.0}]
    if pair[1].__class__ is PD and pair[1].velocity == "observer":
        observers[1] = {"order": 1, "bandwidth": 100.0, "measurement": "position"}
    loop = ArmLoop(ARM, 1e-3, list(pair), observers=observers, sensor=Encoder(2**16),
                   actuator=[Actuator(torque_limit=3.0), Actuator()])  # fmt: skip
    res = simulate_arm(loop, duration=0.4, reference=REFERENCE, tau0=(1.0, -0.5))
    assert np.abs(res.u[:, 0]).max() == 3.0  # the limit binds: anti-windup sees u_bar
    r, rd, rdd = REFERENCE(res.t)
    for i, controller in enumerate(pair):
        system = controller.design(ServoModel(loop.nominal_inertia[i], 0.0), 1e-3)
        python = system.python
        c = python.reset(loop.q0[i], 0.0, (1.0, -0.5)[i])
        signals = {"r": r[:, i], "r_dot": rd[:, i], "r_ddot": rdd[:, i],
                   "theta": res.q_measured[:, i], "omega": res.qd_measured[:, i],
                   "tau_hat": res.tau_hat[:, i]}  # fmt: skip
        if "omega_hat" in system.inputs:
            from hpdob.observers import initial_state, outputs, update

            obs = loop.systems[i]
            s = initial_state(obs, x0=(loop.q0[i], 0.0), tau0=-0.5)
            omega_hat = []
            for k in range(len(res.t)):
                omega_hat.append(outputs(obs, s, res.q_measured[k, i])[1])
                s = update(obs, s, res.q_measured[k, i], res.u[k, i])
            signals["omega_hat"] = np.array(omega_hat)
        expected = []
        for k in range(len(res.t)):
            inputs = [float(signals[name][k]) for name in system.inputs]
            u = python.command(c, *inputs)
            expected.append(u)
            c = python.update(c, *inputs, float(res.u[k, i]))
        expected = np.array(expected)
        limited = np.clip(expected, -3.0, 3.0) if i == 0 else expected
        assert np.array_equal(res.u[:, i], limited), (i, type(controller).__name__)
