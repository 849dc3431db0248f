"""One loop description (issue 20, section 3): a ServoLoop holds values only -- a spec that
designs itself on the nominal model, or a fixed design -- and the initial observer state is
an argument of the run."""

from __future__ import annotations

import numpy as np
import pytest

from hpdob import PD, DisturbanceObserver, ServoLoop, ServoModel, design_observer, simulate
from hpdob.observers import design_eso, initial_state
from hpdob.signals import SmoothStep, Step

TS = 1e-3
PLANT, NOMINAL = ServoModel(3.06e-4, 5e-5), ServoModel(2.8e-4)
RUN = {"duration": 1.0, "reference": SmoothStep(0.1, 0.5, 1.0), "disturbance": Step(0.6, 0.05)}


def loop(observer):
    return ServoLoop(plant=PLANT, nominal=NOMINAL, Ts=TS, controller=PD(50, 5),
                     observer=observer)  # fmt: skip


def test_a_spec_designs_itself_on_the_nominal_model_and_again_on_replace():
    spec = {"type": "eso", "bandwidth": 150.0, "extended_order": 1}
    servo = loop(spec)
    assert servo.observer == spec and servo.observer is not spec  # a copy
    expected = design_eso(NOMINAL.discretize(TS), bandwidth=150.0, extended_order=1)
    np.testing.assert_array_equal(servo.system.F, expected.system.F)
    assert servo.observer_spec == spec
    moved = servo.replace(nominal=ServoModel(3e-4, 1e-4), Ts=2e-3)
    assert (moved.design.model.J, moved.design.model.b, moved.design.Ts) == (3e-4, 1e-4, 2e-3)
    result = simulate(servo, **RUN)
    assert np.array_equal(result.tau_hat, simulate(loop(expected), **RUN).tau_hat)


def test_a_bad_spec_is_named():
    with pytest.raises(ValueError, match=r"observer\.bogus"):
        loop({"order": 1, "bandwidth": 100.0, "bogus": 1})
    with pytest.raises(ValueError, match=r"observer\.type must be one of"):
        loop({"type": "nope"})


def test_a_runtime_observer_is_held_as_its_design_and_its_state():
    model = NOMINAL.discretize(TS)
    runtime = DisturbanceObserver(model, order=1, bandwidth=100.0)
    runtime.reset(x0=(0.0, 0.0), tau0=0.02)
    servo = loop(runtime)
    assert servo.observer is runtime.design  # a value, not the mutable object
    assert servo.observer_state == tuple(runtime.state.tolist())
    runtime.reset(x0=(0.0, 0.0), tau0=0.0)  # changing the object does not change the loop
    assert servo.observer_state != tuple(runtime.state.tolist())


def test_the_initial_observer_state_is_an_argument_of_the_run():
    design = design_observer(NOMINAL.discretize(TS), order=1, bandwidth=100.0)
    state = initial_state(design, x0=(0.0, 0.0), tau0=0.02)
    runtime = DisturbanceObserver(NOMINAL.discretize(TS), order=1, bandwidth=100.0)
    runtime.reset(x0=(0.0, 0.0), tau0=0.02)
    by_argument = simulate(loop(design), **RUN, observer_state=state)
    by_object = simulate(loop(runtime), **RUN)
    assert np.array_equal(by_argument.tau_hat, by_object.tau_hat)
    assert by_argument.tau_hat[0] == pytest.approx(0.02)
    assert simulate(loop(design), **RUN).tau_hat[0] == 0.0
    with pytest.raises(ValueError, match=r"observer_state must be 2 finite floats"):
        simulate(loop(design), **RUN, observer_state=(0.0, 1.0, 2.0))
    with pytest.raises(ValueError, match=r"observer_state needs a loop with an observer"):
        simulate(loop(None), **RUN, observer_state=state)
