"""The plant bonded to its environment: tests that kill the mutants benchmarks/mutation.py
found surviving."""

from __future__ import annotations

import numpy as np
import pytest

from hpdob import (
    Actuator,
    Environment,
    ServoLoop,
    TwoMassServo,
    design_observer,
    paper,
    simulate,
)
from hpdob.controllers import ForceControl
from hpdob.models import InContact
from hpdob.observers import reaction_torque_observer

PLANT = paper.PLANT  # J = 3.06e-4, b = 5e-5 (the paper's motor)


@pytest.mark.parametrize("coulomb", [0.0, 0.01])
def test_in_contact_ground_truth_disturbance_is_the_unilateral_runs(coulomb):
    """The recorded disturbance tau_dn (eq. 3, from the motor's acceleration) of the plant
    bonded to a 10 N m/rad wall equals that of the unilateral wall on a run that stays pressed:
    the spring and damper torques are part of the motor's acceleration on both paths. With
    the paper's Coulomb friction (0.01 N m, tanh scale 0.01 rad/s) the friction is evaluated at
    each sub-step's exponential midpoint (its half-step matrices) on both paths too."""
    plant = PLANT.replace(coulomb=coulomb, environment=Environment(10.0, damping=1e-3))
    dob = design_observer(paper.NOMINAL.discretize(paper.TS), order=1, bandwidth=100.0)
    loop = {
        "nominal": paper.NOMINAL, "Ts": paper.TS, "controller": ForceControl(1000.0, kv=40.0),
        "observer": reaction_torque_observer(dob), "actuator": Actuator(delay_samples=1),
    }  # fmt: skip

    def step(t):
        return np.where(t >= 0.01, 0.05, 0.0), 0 * t, 0 * t

    runs = [
        simulate(ServoLoop(plant=p, **loop), reference=step, duration=0.5)
        for p in (plant, InContact(plant))
    ]
    assert runs[0].in_contact[20:].all()
    # the spring torque is about 10 * 5e-3 = 0.05 N m; midpoint vs exact sub-steps differ ~1e-6
    np.testing.assert_allclose(runs[1].tau_dn[20:], runs[0].tau_dn[20:], rtol=0, atol=1e-5)


def test_the_bonded_plant_measures_the_motors_angle_and_velocity():
    """C of the bonded model selects the motor's angle and velocity from its state (two rows,
    whatever the state size: 2 for the rigid motor, 4 for the two-mass drive)."""
    wall = Environment(10.0)
    for plant in (PLANT.replace(environment=wall),
                  TwoMassServo(3e-4, 6e-4, 5.0, environment=wall)):  # fmt: skip
        discrete = InContact(plant).discretize(1e-3)
        n = len(discrete.state_names)
        x = np.arange(1.0, n + 1.0)
        assert discrete.C.shape == (2, n)
        np.testing.assert_array_equal(discrete.C @ x, [1.0, 2.0])
