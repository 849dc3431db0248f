"""Plant sub-stepping: tests that kill the mutants benchmarks/mutation.py found surviving."""

from __future__ import annotations

import numpy as np
import scipy.linalg

from hpdob import PD, ServoLoop, ServoModel, simulate
from hpdob.signals import Step

J, B, TS = 3.06e-4, 5e-5, 1e-3


def _exact_zoh(h: float):
    """``x+ = Phi x + Gamma (u - tau)`` of J theta'' = u - tau - b omega over ``h`` (expm)."""
    M = np.zeros((3, 3))
    M[0, 1], M[1, 1], M[1, 2] = 1.0, -B / J, 1.0 / J
    E = scipy.linalg.expm(M * h)
    return E[:2, :2], E[:2, 2]


def test_a_disturbance_step_at_a_half_sample_is_integrated_exactly():
    """The canonical disturbance steps at half samples (1.5005 s at 1 ms): the default sub-step
    count is even, so a step there falls on a sub-step boundary and the friction-free plant's
    run is its exact ZOH, each sample split in two halves (scipy.linalg.expm). With an odd count
    the step lands inside a sub-step that the midpoint rule treats as all before or all after
    it: 0.05 N m over 1/14 ms moves the velocity by 0.012 rad/s."""
    n, k_step, amplitude = 30, 10, 0.05
    loop = ServoLoop(plant=ServoModel(J, B), nominal=ServoModel(J), Ts=TS,
                     controller=PD(0.0, 0.0))  # fmt: skip
    run = simulate(loop, reference=lambda t: (0 * t, 0 * t, 0 * t), duration=n * TS,
                   disturbance=Step((k_step + 0.5) * TS, amplitude), x0=(0.0, 1.0))  # fmt: skip
    assert np.all(run.u == 0.0)
    Phi, Gamma = _exact_zoh(TS / 2)
    x, theta, omega = np.array([0.0, 1.0]), [], []
    for k in range(n):
        theta.append(x[0])
        omega.append(x[1])
        for half in range(2):
            tau = amplitude if k > k_step or (k == k_step and half == 1) else 0.0
            x = Phi @ x + Gamma * (0.0 - tau)
    np.testing.assert_allclose(run.theta, theta, rtol=0, atol=1e-12)
    np.testing.assert_allclose(run.omega, omega, rtol=0, atol=1e-9)
