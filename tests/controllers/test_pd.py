"""Tests of the PD controller."""

from __future__ import annotations

import math

import pytest

from hpdob import PD


def test_torque_formula():
    pd = PD(50.0, 5.0)
    u = pd.torque(J_n=2e-4, r=1.0, r_dot=2.0, r_ddot=3.0, theta=0.5, omega=1.0, tau_hat=0.01)
    assert u == pytest.approx(2e-4 * (3.0 + 50 * 0.5 + 5 * 1.0) + 0.01, rel=1e-15)


def test_without_feedforward():
    pd = PD(50.0, 5.0, feedforward=False)
    u = pd.torque(J_n=2e-4, r=1.0, r_dot=2.0, r_ddot=3.0, theta=0.5, omega=1.0)
    assert u == pytest.approx(2e-4 * (50 * 0.5 + 5 * 1.0), rel=1e-15)


@pytest.mark.parametrize(("kp", "kd", "name"), [(-1, 5, "kp"), (50, math.nan, "kd")])
def test_bad_gains(kp, kd, name):
    with pytest.raises(ValueError, match=rf"^{name} must be a non-negative finite gain"):
        PD(kp, kd)


def test_feedforward_must_be_bool():
    with pytest.raises(TypeError, match=r"^feedforward must be True or False, got 1"):
        PD(1.0, 1.0, feedforward=1)
