"""Tests of the sensor and actuator configuration objects."""

from __future__ import annotations

import math

import pytest

from hpdob import Actuator, Encoder


def test_encoder_defaults():
    enc = Encoder(16384)
    assert enc.velocity == "backward-difference"
    assert enc.noise_std == 0.0
    assert enc.resolution == pytest.approx(2 * math.pi / 16384)


@pytest.mark.parametrize(
    ("kwargs", "exc", "pattern"),
    [
        ({"counts_per_rev": 0}, ValueError, r"^counts_per_rev must be a positive integer"),
        ({"counts_per_rev": 100.0}, TypeError, r"^counts_per_rev must be"),
        (
            {"counts_per_rev": 100, "velocity": "kalman"},
            ValueError,
            r"^velocity must be one of 'backward-difference', 'exact'; got 'kalman'",
        ),
        ({"counts_per_rev": 100, "noise_std": -1.0}, ValueError, r"^noise_std must be"),
        ({"counts_per_rev": 100, "seed": -3}, ValueError, r"^seed must be"),
    ],
)
def test_encoder_validation(kwargs, exc, pattern):
    with pytest.raises(exc, match=pattern):
        Encoder(**kwargs)


@pytest.mark.parametrize(
    ("kwargs", "exc", "pattern"),
    [
        ({"torque_limit": 0.0}, ValueError, r"^torque_limit must be a positive finite torque"),
        ({"torque_limit": math.inf}, ValueError, r"^torque_limit must be"),
        ({"delay_samples": -1}, ValueError, r"^delay_samples must be a non-negative integer"),
        ({"delay_samples": 1.0}, TypeError, r"^delay_samples must be"),
    ],
)
def test_actuator_validation(kwargs, exc, pattern):
    with pytest.raises(exc, match=pattern):
        Actuator(**kwargs)


def test_actuator_defaults():
    assert Actuator() == Actuator(torque_limit=None, delay_samples=0)
