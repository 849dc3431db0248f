"""The observer protocol: tests that kill the mutants benchmarks/mutation.py found surviving."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hpdob import PD, ParameterValueError, ServoLoop, ServoModel, design_observer
from hpdob.observers import LinearObserver, outputs, reaction_torque_observer


def test_from_statespace_is_the_inverse_of_to_statespace():
    """LinearObserver.from_statespace (a class method: F, G, H, E = A, B, C, D, Ts = dt) reads
    back what to_statespace wrote, with the measured and output signals' names."""
    model = ServoModel(2.8e-4, 5e-5).discretize(1e-3)
    system = design_observer(model, order=1, bandwidth=100.0).system
    back = LinearObserver.from_statespace(system.to_statespace(), model=model)
    assert isinstance(back, LinearObserver) and back.Ts == system.Ts
    assert (back.measures, back.outputs) == (system.measures, system.outputs)
    for name in "FGHE":
        np.testing.assert_array_equal(getattr(back, name), getattr(system, name), err_msg=name)


@pytest.mark.parametrize("measurement", ["state", "position"])
def test_the_coulomb_term_leaves_one_value_per_output(measurement):
    """An RTOB with a Coulomb term (tau_reac last, after tau_hat [, omega_hat]): its outputs
    are the linear rows H s + E v, with c tanh(w / v) subtracted from tau_reac only, w the
    measured velocity (state DOb) or omega_hat (position-only DOb); one value per output."""
    model = ServoModel(2.8e-4).discretize(1e-3)
    dob = design_observer(model, order=1, bandwidth=100.0, measurement=measurement)
    rtob = reaction_torque_observer(dob, coulomb=0.01, coulomb_velocity=0.02)
    state = tuple(np.random.default_rng(3).normal(size=rtob.n_states).tolist())
    x = (0.1, 0.015) if measurement == "state" else 0.1
    v = np.atleast_1d(np.asarray(x, dtype=float))
    linear = rtob.H @ np.array(state) + rtob.E[:, :-1] @ v  # E[:, -1] (from u) is zero
    names = rtob.outputs
    w = v[1] if measurement == "state" else linear[names.index("omega_hat")]
    expected = linear.copy()
    expected[names.index("tau_reac")] -= 0.01 * math.tanh(w / 0.02)
    got = outputs(rtob, state, x)
    assert len(got) == len(names) == (2 if measurement == "state" else 3)
    np.testing.assert_allclose(got, expected, rtol=1e-13, atol=1e-18)


def test_a_design_on_a_damped_nominal_model_runs_in_its_loop():
    """The loop checks the design's J and b Ts / J against the nominal model's: a design on
    nominal.discretize(Ts) with b_n != 0 is accepted, one on another b_n refused."""
    nominal = ServoModel(2.8e-4, 5e-5)
    design = design_observer(nominal.discretize(1e-3), order=1, bandwidth=100.0)
    loop = ServoLoop(plant=nominal, nominal=nominal, Ts=1e-3, controller=PD(50.0, 5.0),
                     observer=design)  # fmt: skip
    assert loop.system is design.system
    with pytest.raises(ParameterValueError, match=r"must be designed on nominal\.discretize"):
        ServoLoop(plant=nominal, nominal=ServoModel(2.8e-4, 1e-4), Ts=1e-3,
                  controller=PD(50.0, 5.0), observer=design)  # fmt: skip


@pytest.mark.parametrize("measurement", ["state", "position"])
def test_the_system_says_what_it_measures(measurement):
    model = ServoModel(2.8e-4).discretize(1e-3)
    system = design_observer(model, order=1, bandwidth=100.0, measurement=measurement).system
    assert system.measurement == measurement
    assert system.measures == (("theta", "omega") if measurement == "state" else ("theta",))
