"""ServoLoop: the closed loop as a value, taken first by simulate and every analysis view."""

from __future__ import annotations

import numpy as np
import pytest

from hpdob import (
    PD,
    Actuator,
    DisturbanceObserver,
    Encoder,
    ServoLoop,
    ServoModel,
    closed_loop,
    closed_loop_poles,
    gang_of_four,
    loop_margins,
    loop_transfer,
    noise_gains,
    paper,
    simulate,
)

KW = {
    "plant": ServoModel(3.06e-4, 5e-5),
    "nominal": paper.NOMINAL,
    "Ts": paper.TS,
    "controller": paper.CONTROLLER,
    "sensor": Encoder(16384),
    "actuator": Actuator(delay_samples=1),
}


@pytest.fixture
def loop():
    return ServoLoop(**KW, observer=paper.observer("HPDOb-100"))


def _sensitivity(*args, **kwargs):
    return gang_of_four(*args, **kwargs).S


@pytest.mark.parametrize("function", [closed_loop_poles, noise_gains, loop_margins, _sensitivity])
def test_loop_first_equals_keywords(loop, function):
    by_loop = function(loop)
    by_keywords = function(**KW, observer=paper.observer("HPDOb-100"))
    if isinstance(by_loop, np.ndarray):
        assert np.array_equal(by_loop, by_keywords)
    elif hasattr(by_loop, "A"):
        assert np.array_equal(by_loop.A, by_keywords.A)
    else:
        assert by_loop == by_keywords


def test_closed_loop_and_transfer_take_the_loop(loop):
    assert np.array_equal(closed_loop(loop).A, closed_loop(**KW, observer=loop.observer).A)
    assert np.array_equal(loop_transfer(loop).A, loop_transfer(**KW, observer=loop.observer).A)


def test_simulate_takes_the_loop(loop):
    run = {"reference": paper.REFERENCE, "disturbance": paper.DISTURBANCE, "duration": 1.0}
    a = simulate(loop, **run)
    b = simulate(**KW, observer=paper.observer("HPDOb-100"), **run)
    assert np.array_equal(a.tau_hat, b.tau_hat) and np.array_equal(a.theta, b.theta)


def test_a_runtime_observers_state_is_taken_when_the_loop_is_built():
    obs = paper.observer("DOb-100")
    loop = ServoLoop(**{**KW, "actuator": None}, observer=obs)
    before = loop.observer_state
    obs.update((0.5, 3.0), 0.2)  # the object moves on; the loop (a value) does not
    assert loop.observer_state == before
    assert loop.replace(controller=PD(40, 4)).observer_state == before
    fresh = loop.replace(observer=obs)
    assert fresh.observer_state == tuple(obs.state.tolist()) != before


def test_replace_validates_and_names_unknown_arguments(loop):
    assert loop.replace(sensor=None).sensor is None
    with pytest.raises(TypeError, match=r"unknown argument\(s\) \['gain'\]; valid: plant"):
        loop.replace(gain=2)
    with pytest.raises(ValueError, match="Ts must be a positive finite sampling period"):
        loop.replace(Ts=-1.0)


def test_loop_or_keywords_not_both(loop):
    with pytest.raises(TypeError, match=r"closed_loop_poles\(\) takes a ServoLoop or .* not both"):
        closed_loop_poles(loop, Ts=1e-3)
    with pytest.raises(TypeError, match=r"needs a ServoLoop .* \(missing: nominal, Ts\)"):
        closed_loop(plant=KW["plant"], controller=KW["controller"])
    with pytest.raises(TypeError, match="takes a ServoLoop as its first argument, got dict"):
        noise_gains(KW)
    # A plant given positionally (the pre-loop habit) says how to pass it.
    rest = {k: v for k, v in KW.items() if k != "plant"}
    with pytest.raises(TypeError, match=r"got ServoModel; pass a plant as plant=\.\.\."):
        closed_loop_poles(KW["plant"], **rest)
    # Something else first, with the parts as keywords: the same error, not "got a loop and".
    with pytest.raises(TypeError, match=r"got dict; pass the loop's parts as keyword arguments"):
        closed_loop_poles({}, **KW)


@pytest.mark.parametrize(
    ("change", "error", "pattern"),
    [
        ({"plant": "motor"}, TypeError, r"^plant must be a ServoModel, a TwoMassServo or a Mujo"),
        ({"nominal": None}, TypeError, r"^nominal must be a ServoModel"),
        ({"Ts": 0.0}, ValueError, r"^Ts must be a positive finite sampling period \[s\], got 0.0"),
        ({"controller": (50, 5)}, TypeError, r"^controller must be a PD"),
        ({"observer": "dob"}, TypeError, r"^observer must be a DisturbanceObserver, an Obse"),
        ({"sensor": 16384}, TypeError, r"^sensor must be an Encoder or None"),
        ({"actuator": 0.4}, TypeError, r"^actuator must be an Actuator or None"),
        (
            {
                "observer": DisturbanceObserver(
                    ServoModel(3e-4).discretize(1e-3), order=0, bandwidth=50.0
                )
            },
            ValueError,
            r"^observer must be designed on nominal.discretize\(Ts\)",
        ),
        (
            {"controller": PD(50, 5, velocity="observer")},
            ValueError,
            r"velocity = 'observer' needs an observer with a velocity estimate",
        ),
    ],
)
def test_validated_once_with_named_parameters(change, error, pattern):
    kwargs = {**KW, "observer": paper.observer("DOb-100"), **change}
    with pytest.raises(error, match=pattern):
        ServoLoop(**kwargs)


def test_linear_views_refuse_what_is_not_linear(loop):
    with pytest.raises(ValueError, match=r"actuator\.torque_limit must be None for the linear"):
        closed_loop(loop.replace(actuator=Actuator(torque_limit=0.4)))
