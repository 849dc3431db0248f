"""Tests of the stateful DisturbanceObserver against the functional core."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hpdob import DisturbanceObserver, ServoModel, design_observer, estimate, initial_state, update


@pytest.mark.parametrize("order", range(5))
def test_object_agrees_with_functional_core(paper_model, rng, order):
    obs = DisturbanceObserver(paper_model, order=order, bandwidth=150.0)
    design = design_observer(paper_model, order=order, bandwidth=150.0)
    state = initial_state(design, (0.2, 1.0), 0.01)
    obs.reset((0.2, 1.0), 0.01)
    for _ in range(500):
        x, u = rng.normal(size=2), float(rng.normal())
        assert obs.estimate(x) == estimate(design, state, x)  # bit for bit
        obs.update(x, u)
        state = update(design, state, x, u)
        np.testing.assert_array_equal(obs.state, state)


def test_attributes(paper_model):
    obs = DisturbanceObserver(paper_model, order=1, poles=[0.9, 0.8], gain_direction=(0, 1))
    assert obs.model is paper_model and obs.order == 1 and obs.bandwidth is None
    np.testing.assert_array_equal(obs.poles, [0.9, 0.8])
    assert obs.gains.shape == (2, 2) and obs.error_matrix.shape == (2, 2)
    np.testing.assert_array_equal(obs.gain_direction, [0.0, 1.0])
    assert obs.design.k.shape == (2,)
    assert obs.state.shape == (2,)
    assert "order=1" in repr(obs)


@pytest.mark.parametrize(
    ("x", "u"),
    [
        ((math.nan, 0.0), 0.1),
        ((0.0, -math.inf), 0.1),
        ((0.0, 0.0), math.nan),
        ((0.0, 0.0), math.inf),
        ((0.0,), 0.1),
        ("ab", 0.1),
    ],
)
def test_rejected_update_keeps_state(paper_model, x, u):
    obs = DisturbanceObserver(paper_model, order=2, bandwidth=100.0)
    obs.update((0.1, 0.2), 0.3)
    before = obs.state
    with pytest.raises((TypeError, ValueError), match=r"^(x|u)"):
        obs.update(x, u)
    np.testing.assert_array_equal(obs.state, before)


def test_rejected_estimate_and_reset_keep_state(paper_model):
    obs = DisturbanceObserver(paper_model, order=1, bandwidth=100.0)
    obs.update((0.1, 0.2), 0.3)
    before = obs.state
    with pytest.raises(ValueError, match=r"x\[1\] \(omega\)"):
        obs.estimate((0.0, math.nan))
    with pytest.raises(ValueError, match="tau0"):
        obs.reset((0.0, 0.0), math.nan)
    with pytest.raises(ValueError, match=r"x0\[0\]"):
        obs.reset((math.inf, 0.0))
    np.testing.assert_array_equal(obs.state, before)


def test_rejected_construction(paper_model):
    with pytest.raises(ValueError, match="bandwidth"):
        DisturbanceObserver(paper_model, order=1, bandwidth=-1.0)
    with pytest.raises(TypeError, match="order"):
        DisturbanceObserver(paper_model, order="1", bandwidth=1.0)
    with pytest.raises(TypeError):
        DisturbanceObserver(paper_model, 1, None, 100.0)  # keyword-only beyond the model


def test_reset_copy_and_from_design(paper_model):
    obs = DisturbanceObserver(paper_model, order=1, bandwidth=100.0)
    obs.reset((1.0, 0.0), 0.02)
    assert obs.estimate((1.0, 0.0)) == pytest.approx(0.02, rel=1e-14)
    twin = obs.copy()
    twin.update((1.0, 0.5), 0.3)
    assert not np.array_equal(twin.state, obs.state)
    rebuilt = DisturbanceObserver.from_design(obs.design, x0=(1.0, 0.0), tau0=0.02)
    np.testing.assert_array_equal(rebuilt.state, obs.state)
    with pytest.raises(TypeError, match="design must be an ObserverDesign"):
        DisturbanceObserver.from_design(paper_model)


def test_state_is_a_copy(paper_model):
    obs = DisturbanceObserver(paper_model, order=1, bandwidth=100.0)
    s = obs.state
    s[:] = 5.0
    np.testing.assert_array_equal(obs.state, [0.0, 0.0])


def test_sample_loop_rejects_constant_disturbance():
    """The documented loop: measure, estimate, compensate, update, on the nominal discrete plant."""
    model = ServoModel(2.8e-4).discretize(1e-3)
    for order in range(4):
        obs = DisturbanceObserver(model, order=order, bandwidth=100.0)
        x, tau = np.zeros(2), 0.01
        for _ in range(3000):
            tau_hat = obs.estimate(x)
            u = -2.8e-4 * (400.0 * x[0] + 40.0 * x[1]) + tau_hat
            obs.update(x, u)
            x = model.step(x, u, tau)
        assert obs.estimate(x) == pytest.approx(tau, rel=1e-9)
        assert abs(x[0]) < 1e-9
