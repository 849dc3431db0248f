"""The reaction-torque observer: tests that kill the mutants benchmarks/mutation.py found
surviving."""

from __future__ import annotations

import numpy as np
import pytest

from hpdob import ServoModel, design_observer
from hpdob.observers import reaction_torque_observer

NOMINAL = ServoModel(2.8e-4, 0.0)  # the paper's nominal motor (sec. IV)


def test_reaction_observer_on_an_equal_sampling_period_built_apart_combines():
    """Sampling periods are compared by value: a DOb and a reaction observer designed on two
    models discretised at equal periods computed apart (5e-4 + 5e-4 == 1e-3 exactly) make one
    composition, whose tau_reac rows are the reaction observer's; another period is refused."""
    dob = design_observer(NOMINAL.discretize(1e-3), order=1, bandwidth=100.0)
    rtob = design_observer(NOMINAL.discretize(sum([5e-4, 5e-4])), order=0, bandwidth=60.0)
    both = reaction_torque_observer(dob, rtob)
    assert both.Ts == 1e-3 and both.outputs == ("tau_hat", "tau_reac")
    np.testing.assert_array_equal(both.H[1], np.concatenate([np.zeros(2), rtob.system.H[0]]))
    other = design_observer(NOMINAL.discretize(2e-3), order=0, bandwidth=60.0)
    with pytest.raises(ValueError, match=r"^reaction\.Ts = 0\.002 must equal dob\.Ts = 0\.001$"):
        reaction_torque_observer(dob, other)


def test_a_friction_model_below_the_nominal_viscous_friction_is_refused():
    """The RTOB subtracts the viscous friction beyond b_n: friction.b = b_n subtracts none
    (the DOb's own tau_reac row), friction.b < b_n is refused naming both."""
    nominal = ServoModel(2.8e-4, 5e-5)
    dob = design_observer(nominal.discretize(1e-3), order=1, bandwidth=100.0)
    same = reaction_torque_observer(dob, friction=ServoModel(3e-4, 5e-5))
    np.testing.assert_array_equal(same.E[1], dob.system.E[0])
    with pytest.raises(ValueError, match=r"friction\.b = 1e-05 must be at least the nominal b_n"):
        reaction_torque_observer(dob, friction=ServoModel(3e-4, 1e-5))
