"""The two-mass drive: tests that kill the mutants benchmarks/mutation.py found surviving."""

from __future__ import annotations

import math

import numpy as np
import scipy.linalg

from hpdob.models import TwoMassServo


def test_state_matrix_is_newtons_law_on_both_inertias():
    """x' = A_C x + B_C u - D_C tau is, written out for a damped drive at a random state,
    J_m omega' = u - b_m omega - k (theta - theta_l) - c (omega - omega_l) and
    J_l omega_l' = k (theta - theta_l) + c (omega - omega_l) - b_l omega_l - tau."""
    Jm, Jl, k, c, bm, bl = 3e-4, 6e-4, 5.0, 2e-3, 5e-5, 8e-5
    plant = TwoMassServo(Jm, Jl, k, damping=c, b_motor=bm, b_load=bl)
    th, om, th_l, om_l = np.random.default_rng(3).normal(size=4)
    u, tau = 0.3, -0.2
    x = np.array([th, om, th_l, om_l])
    dx = plant.A_C @ x + plant.B_C * u - plant.D_C * tau
    twist, rate = k * (th - th_l), c * (om - om_l)
    np.testing.assert_allclose(dx[[0, 2]], [om, om_l], rtol=1e-15)
    np.testing.assert_allclose(Jm * dx[1], u - bm * om - twist - rate, rtol=1e-12)
    np.testing.assert_allclose(Jl * dx[3], twist + rate - bl * om_l - tau, rtol=1e-12)


def test_step_is_the_zoh_recurrence_with_the_load_torque():
    """DiscreteTwoMassServo.step(x, u, tau) = A x + B u - D tau, and it equals the exact ZOH of
    the continuous drive (scipy.linalg.expm of [[A_C, B_C, -D_C], [0, 0, 0]] over Ts)."""
    plant = TwoMassServo(3e-4, 6e-4, 5.0, damping=2e-3, b_motor=5e-5, b_load=8e-5)
    Ts, u, tau = 1e-3, 0.3, -0.2
    discrete = plant.discretize(Ts)
    x = np.random.default_rng(5).normal(size=4)
    step = discrete.step(x, u, tau)
    np.testing.assert_allclose(step, discrete.A @ x + discrete.B * u - discrete.D * tau,
                               rtol=1e-14, atol=1e-14)  # fmt: skip
    M = np.zeros((6, 6))
    M[:4, :4], M[:4, 4], M[:4, 5] = plant.A_C, plant.B_C, -plant.D_C
    exact = scipy.linalg.expm(M * Ts) @ np.concatenate([x, [u, tau]])
    np.testing.assert_allclose(step, exact[:4], rtol=1e-9, atol=1e-12)


def test_the_motor_coulomb_torque_is_c_tanh_omega_over_v():
    plant = TwoMassServo(3e-4, 6e-4, 5.0, coulomb=0.01, coulomb_velocity=0.02)
    omega = np.array([-1.0, -0.01, 0.0, 0.005, 3.0])
    np.testing.assert_allclose(plant.coulomb_torque(omega), 0.01 * np.tanh(omega / 0.02),
                               rtol=1e-15, atol=0)  # fmt: skip
    assert plant.coulomb_torque(0.02) == 0.01 * math.tanh(1.0)
