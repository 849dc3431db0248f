"""Functional core: tests that kill the mutants benchmarks/mutation.py found surviving."""

from __future__ import annotations

import numpy as np
import pytest

from hpdob import ServoModel, design_observer
from hpdob.observers import estimate, initial_state, update

MODEL = ServoModel(2.8e-4, 5e-5).discretize(1e-3)  # the paper's nominal motor (sec. IV)


@pytest.fixture(scope="module")
def position_only():
    return design_observer(MODEL, order=1, bandwidth=300.0, measurement="position")


def test_position_only_takes_a_one_element_array_as_the_angle(position_only):
    """A length-1 array (one entry of a logged column) is the angle itself."""
    state = initial_state(position_only, x0=(0.2, 0.0), tau0=0.01)
    assert estimate(position_only, state, np.array([0.25])) == estimate(position_only, state, 0.25)
    assert update(position_only, state, np.array([0.25]), 0.1) == update(
        position_only, state, 0.25, 0.1
    )


@pytest.mark.parametrize("theta", [np.array([0.1, 0.2, 0.3]), np.zeros((1, 1)), np.array([])])
def test_position_only_refuses_an_array_that_is_not_one_angle(position_only, theta):
    state = initial_state(position_only)
    with pytest.raises(ValueError, match="must be one measured angle"):
        estimate(position_only, state, theta)


@pytest.mark.parametrize("x", [0.5, np.float64(0.5), np.array(0.5)])
def test_state_observer_refuses_a_single_number_naming_the_position_only_design(x):
    """A 0-d array is a single number too: the message points to measurement='position'."""
    design = design_observer(MODEL, order=1, bandwidth=300.0)
    with pytest.raises(ValueError, match=r"got the single number .*measurement='position'"):
        estimate(design, initial_state(design), x)
