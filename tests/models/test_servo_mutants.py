"""Servo model: tests that kill the mutants benchmarks/mutation.py found surviving."""

from __future__ import annotations

import pytest

from hpdob import ServoModel


def test_discretisation_whose_input_underflows_to_zero_is_refused():
    """Ts/J = 1e-600 underflows: B_D = [Ts^2 phi_2/J, Ts phi_1/J] is exactly [0, 0], a plant
    that no torque moves. It is refused like an overflowing one (B_D[1] must be positive)."""
    with pytest.raises(ValueError, match=r"the ratio Ts/J = 1e-300 s / 1e\+300 kg m\^2 is beyond"):
        ServoModel(1e300, 0.0).discretize(1e-300)
