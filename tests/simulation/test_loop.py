"""ServoLoop: the closed loop as a value, taken first by simulate and every analysis view."""

from __future__ import annotations

from pathlib import Path

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
    compare_observers,
    gang_of_four,
    loop_margins,
    loop_transfer,
    noise_gains,
    noise_tradeoff,
    paper,
    robust_stability_map,
    simulate,
    tune,
)
from hpdob.simulation import LOOP_KEYS

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
    return ServoLoop(**KW, observer=paper.observer("HPDOb-100").design)


def _sensitivity(*args, **kwargs):
    return gang_of_four(*args, **kwargs).S


@pytest.mark.parametrize("function", [closed_loop_poles, noise_gains, loop_margins, _sensitivity])
def test_loop_first_equals_keywords(loop, function):
    by_loop = function(loop)
    by_keywords = function(**KW, observer=paper.observer("HPDOb-100").design)
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
    b = simulate(**KW, observer=paper.observer("HPDOb-100").design, **run)
    assert np.array_equal(a.tau_hat, b.tau_hat) and np.array_equal(a.theta, b.theta)


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
                ).design
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
    kwargs = {**KW, "observer": paper.observer("DOb-100").design, **change}
    with pytest.raises(error, match=pattern):
        ServoLoop(**kwargs)


def test_linear_views_refuse_what_is_not_linear(loop):
    with pytest.raises(ValueError, match=r"actuator\.torque_limit must be None for the linear"):
        closed_loop(loop.replace(actuator=Actuator(torque_limit=0.4)))


# -- the one alias rule of the loop functions (issue 20, section 3; LOOP_KEYS) ---------------

#: function -> the parts it sets itself (so refuses as keywords); every other part of LOOP_KEYS
#: is taken as a keyword instead of a loop. The rule as LOOP_KEYS' documentation states it.
SETS = {
    simulate: (),
    closed_loop: (),
    closed_loop_poles: (),
    gang_of_four: (),
    loop_transfer: (),
    loop_margins: (),
    noise_gains: (),
    robust_stability_map: ("plant", "actuator"),  # the map's plant; its delay: delay_samples
    tune: ("plant", "observer"),
    compare_observers: ("observer",),
    noise_tradeoff: ("plant", "observer", "sensor", "actuator"),
}
#: what each needs besides the loop (cheap settings where it runs)
EXTRA = {
    simulate: {"duration": 0.05, "reference": paper.REFERENCE},
    robust_stability_map: {"J_ratio": [0.5, 1.0], "bandwidth": [100.0]},
    tune: {"J_range": (0.9, 1.1), "families": ["position"]},
    compare_observers: {"sensors": ("ideal",), "duration": 0.05,
                        "candidates": {"DOb": {"type": "dob", "order": 0}}},
    noise_tradeoff: {"frequency": 2.0, "bandwidths": [100.0]},
}  # fmt: skip


def _parts(function) -> dict:
    parts = {**KW, "observer": {"order": 1, "bandwidth": 100.0}}
    if function is robust_stability_map:
        parts["observer"] = {"order": 1}  # the family; the map sets the bandwidth
    return {k: v for k, v in parts.items() if k not in SETS[function]}


def test_the_rule_is_stated_once_and_every_loop_function_points_at_it():
    from hpdob.simulation import _loop

    rule = _loop.__doc__ or ""
    source = Path(_loop.__file__).read_text().splitlines()
    stated = " ".join(line.lstrip("#: ") for line in source if line.startswith("#:"))
    for function in SETS:
        assert f"``{function.__name__}``" in stated + rule, function.__name__
        assert "LOOP_KEYS" in function.__doc__, function.__name__  # a pointer, not a copy
        assert "accepted instead, as before" not in function.__doc__
    assert set(LOOP_KEYS) == {"plant", "nominal", "Ts", "controller", "observer", "sensor",
                              "actuator"}  # fmt: skip


@pytest.mark.parametrize("function", list(SETS), ids=lambda f: f.__name__)
def test_a_loop_and_keyword_parts_together_are_refused(function):
    loop = ServoLoop(**KW, observer={"order": 1, "bandwidth": 100.0})
    given = {"Ts": paper.TS}
    with pytest.raises(TypeError, match=rf"{function.__name__}\(\) takes a ServoLoop or .*not "
                       r"both; got a loop and Ts"):  # fmt: skip
        function(loop, **given, **EXTRA.get(function, {}))


@pytest.mark.parametrize(
    ("function", "part"), [(f, p) for f, parts in SETS.items() for p in parts],
    ids=lambda x: getattr(x, "__name__", x),
)  # fmt: skip
def test_a_part_the_function_sets_is_refused_by_name(function, part):
    with pytest.raises(TypeError, match=rf"unexpected keyword argument '{part}'"):
        function(**_parts(function), **{part: KW.get(part, paper.PLANT)},
                 **EXTRA.get(function, {}))  # fmt: skip


@pytest.mark.parametrize(
    "function",
    [simulate, closed_loop_poles, loop_margins, noise_gains, robust_stability_map,
     compare_observers, noise_tradeoff],
    ids=lambda f: f.__name__,
)  # fmt: skip
def test_the_keyword_parts_mean_the_loop(function):
    parts = _parts(function)
    loop = ServoLoop(**{**KW, "observer": {"order": 1, "bandwidth": 100.0}})
    by_loop = function(loop, **EXTRA.get(function, {}))
    if function is robust_stability_map:  # the loop's actuator: its delay only
        parts["delay_samples"] = KW["actuator"].delay_samples
    by_keywords = function(**parts, **EXTRA.get(function, {}))
    for name in ("theta", "spectral_radius", "u_noise_gain"):
        if hasattr(by_loop, name) and getattr(by_loop, name) is not None:
            np.testing.assert_array_equal(getattr(by_loop, name), getattr(by_keywords, name))
            return
    if hasattr(by_loop, "rows"):
        assert by_loop.rows == by_keywords.rows
    elif isinstance(by_loop, np.ndarray):
        np.testing.assert_array_equal(by_loop, by_keywords)
    else:
        assert by_loop == by_keywords


FORCE = Path(__file__).resolve().parents[2] / "examples" / "force_step_stiff_wall.toml"


def test_a_loop_gives_an_rtob_that_follows_the_plant_its_plants_friction():
    """[reaction_observer] friction = "plant": the loop's RTOB subtracts the loop's plant's
    friction, in a loop replaced with another plant too; numbers given as numbers stay."""
    import dataclasses

    from hpdob import TwoMassServo
    from hpdob.observers import reaction_torque_observer
    from hpdob.simulation import load_scenario

    loop = load_scenario(FORCE).loop
    assert loop.design.follows_plant and loop.design.coulomb == 0.01
    other = loop.plant.replace(b=1e-4, coulomb=0.02, coulomb_velocity=0.005)
    moved = loop.replace(plant=other)
    assert moved.observer is moved.design and moved.design.follows_plant
    numbers = (moved.design.viscous, moved.design.coulomb, moved.design.coulomb_velocity)
    assert numbers == (1e-4, 0.02, 0.005)  # viscous = b - b_n, b_n = 0
    expected = reaction_torque_observer(loop.design.dob, friction=other, velocity_filter=100.0)
    for matrix in "FGHEN":
        np.testing.assert_array_equal(getattr(moved.system, matrix), getattr(expected, matrix))
    assert moved.system.coulomb == expected.coulomb
    assert loop.design.coulomb == 0.01  # the original loop as it was
    assert moved.replace(plant=loop.plant).design.friction == loop.design.friction
    fixed = loop.replace(observer=dataclasses.replace(loop.design, follows_plant=False))
    assert fixed.replace(plant=other).design.coulomb == 0.01
    with pytest.raises(TypeError, match=r"^plant must be a rigid ServoModel for a reaction-"
                       r"torque observer whose friction model is the plant's"):  # fmt: skip
        loop.replace(plant=TwoMassServo(2e-4, 1e-4, 100.0))
    assert loop.design.coulomb == 0.01 and loop.plant.coulomb == 0.01
