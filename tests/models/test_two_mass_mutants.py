"""The two-mass drive: tests that kill the mutants benchmarks/mutation.py found surviving."""

from __future__ import annotations

import numpy as np

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
