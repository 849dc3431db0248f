"""Runtime observers: tests that kill the mutants benchmarks/mutation.py found surviving."""

from __future__ import annotations

import math

import pytest

from hpdob import DisturbanceObserver, ServoModel
from hpdob.observers import outputs

MODEL = ServoModel(2.8e-4).discretize(1e-3)


def test_the_velocity_estimate_is_an_attribute_after_estimate():
    """A position-only observer's omega_hat of the current sample is ``.velocity`` (a float,
    the second output of the functional core), available between estimate() and update()."""
    obs = DisturbanceObserver(MODEL, order=1, bandwidth=100.0, measurement="position")
    obs.reset((0.0, 0.5))  # converged at 0.5 rad/s
    with pytest.raises(AttributeError, match="available after estimate"):
        _ = obs.velocity
    state = tuple(map(float, obs.state))
    obs.estimate(0.0)
    assert isinstance(obs.velocity, float)
    assert obs.velocity == outputs(obs.design, state, 0.0)[1] == pytest.approx(0.5, abs=1e-12)
    obs.update(0.0, 0.0)
    with pytest.raises(AttributeError, match="available after estimate"):
        _ = obs.velocity


def test_repr_prints_the_poles_to_six_digits():
    pole = math.exp(-0.1)  # 0.9048374180359595
    obs = DisturbanceObserver(MODEL, order=0, poles=[pole])
    assert "poles=[0.904837]" in repr(obs)
