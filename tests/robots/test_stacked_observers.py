"""Every family per joint: the stacked program of the N-joint kernel computes, bit for bit,
what each joint's own observer computes through the functional core on the same signals."""

from __future__ import annotations

import numpy as np
import pytest

from hpdob import PD, Encoder
from hpdob.observers import initial_state, outputs, update
from hpdob.robots import ArmLoop, JointSines, TwoLinkArm, simulate_arm

ARM = TwoLinkArm(m=(1.3, 0.9), l=(0.5, 0.4), lc=(0.22, 0.17), I=(0.021, 0.013), J=(0.05, 0.03))
REFERENCE = JointSines(center=(0.0, 0.0), amplitude=0.6, frequency=1.0)

PAIRS = [
    ({"order": 0, "bandwidth": 80.0}, {"order": 2, "bandwidth": 60.0}),
    ({"type": "eso", "bandwidth": 250.0}, {"type": "eso", "bandwidth": 250.0, "extended_order": 1}),
    ({"type": "kalman", "position_noise_std": 1e-4, "process_noise_std": 50.0},
     {"order": 1, "bandwidth": 100.0, "measurement": "position"}),
    (None, {"order": 1, "bandwidth": 100.0}),
]  # fmt: skip


@pytest.mark.parametrize("pair", PAIRS, ids=["dob-order2", "eso", "kalman-position", "none-hpdob"])
def test_stacked_program_equals_each_joints_observer(pair):
    velocity = ["measured", "measured"]
    if pair[1].get("measurement") == "position":
        velocity[1] = "observer"  # the position-only observer's velocity estimate feeds the PD
    loop = ArmLoop(ARM, 1e-3, [PD(400.0, 40.0, velocity=v) for v in velocity],
                   observers=list(pair), sensor=Encoder(2**16))  # fmt: skip
    res = simulate_arm(loop, duration=0.3, reference=REFERENCE, tau0=(1.0, -0.5))
    for i, system in enumerate(loop.systems):
        if system is None:
            assert np.all(res.tau_hat[:, i] == 0.0)
            continue
        s = initial_state(system, x0=(loop.q0[i], 0.0), tau0=(1.0, -0.5)[i])
        expected = []
        for k in range(len(res.t)):
            x = (res.q_measured[k, i], res.qd_measured[k, i])
            x = x if len(system.measures) == 2 else x[0]
            expected.append(outputs(system, s, x)[0])
            s = update(system, s, x, res.u[k, i])
        assert np.array_equal(res.tau_hat[:, i], expected), i
