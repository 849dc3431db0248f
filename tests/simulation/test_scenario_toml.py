"""scenario_toml writes a reaction-torque observer composition ([observer] and
[reaction_observer]), a plant's wall ([plant.environment]), a MuJoCo servo, x0 and substeps:
each example with a [reaction_observer] reads back into an equal loop that runs bit for bit
(issue 21)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hpdob import Environment, ServoLoop, ServoModel, design_observer, paper, simulate
from hpdob.controllers import ForceControl
from hpdob.observers import (
    LinearObserver,
    ReactionObserverDesign,
    design_eso,
    design_reaction_observer,
    spec_of,
)
from hpdob.signals import Step
from hpdob.simulation import load_scenario, scenario_toml

EXAMPLES = sorted(p for p in (Path(__file__).resolve().parents[2] / "examples").glob("*.toml")
                  if "[reaction_observer]" in p.read_text())  # fmt: skip
MODEL = paper.NOMINAL.discretize(paper.TS)


def _same_loop(a: ServoLoop, b: ServoLoop) -> None:
    for part in ("plant", "nominal", "Ts", "controller", "sensor", "actuator"):
        assert getattr(a, part) == getattr(b, part), part
    assert type(a.design) is type(b.design) is ReactionObserverDesign
    assert a.design.friction == b.design.friction
    assert a.design.follows_plant == b.design.follows_plant
    for part in ("dob", "reaction"):
        mine, theirs = getattr(a.design, part), getattr(b.design, part)
        assert (mine is None) == (theirs is None)
        if mine is not None:
            assert spec_of(mine) == spec_of(theirs)
    sa, sb = a.system, b.system
    for matrix in "FGHEN":
        np.testing.assert_array_equal(getattr(sa, matrix), getattr(sb, matrix))
    assert (sa.outputs, sa.measures, sa.coulomb) == (sb.outputs, sb.measures, sb.coulomb)


def _round_trip(loop, run, tmp_path):
    text = scenario_toml(loop, **run)
    path = tmp_path / "written.toml"
    path.write_text(text)
    again = load_scenario(path)
    assert scenario_toml(again.loop, **again.run) == text  # the file is the same written again
    return again, text


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.name)
def test_every_force_example_reads_back_into_an_equal_loop(path, tmp_path):
    if 'type = "mujoco"' in path.read_text():
        pytest.importorskip("mujoco")  # the optional extra
    scenario = load_scenario(path)
    again, text = _round_trip(scenario.loop, scenario.run, tmp_path)
    assert "[reaction_observer]" in text
    _same_loop(scenario.loop, again.loop)
    assert dict(again.run).keys() == dict(scenario.run).keys()  # x0 and the label too
    short = {**scenario.run, "duration": 0.3}
    runs = [simulate(loop, **short) for loop in (scenario.loop, again.loop)]
    for name in ("theta", "u", "tau_reac", "tau_contact"):
        np.testing.assert_array_equal(getattr(runs[1], name), getattr(runs[0], name))


def test_a_composition_with_its_own_rtob_and_poles_reads_back(tmp_path):
    """A separate RTOB of another family ([reaction_observer] with type = "eso"), and one given
    by complex poles (written as strings, read back as [observer]'s are)."""
    plant = paper.PLANT.replace(environment=Environment(10.0, damping=0.01, position=0.002))
    dob = design_observer(MODEL, order=1, bandwidth=100.0, measurement="position")
    for rtob in (design_eso(MODEL, bandwidth=150.0, extended_order=1),
                 design_observer(MODEL, order=1, poles=[0.9 + 0.05j, 0.9 - 0.05j, 0.92, 0.93],
                                 measurement="position")):  # fmt: skip
        composition = design_reaction_observer(dob, rtob, friction=paper.PLANT)
        loop = ServoLoop(plant=plant, nominal=paper.NOMINAL, Ts=paper.TS, observer=composition,
                         controller=ForceControl(800.0, kv=30.0),
                         sensor=paper.VIRTUAL_SENSOR)  # fmt: skip
        run = {"reference": Step(0.1, 0.05), "duration": 0.3, "x0": (-0.01, 0.0),
               "substeps": 16, "label": "written"}  # fmt: skip
        again, text = _round_trip(loop, run, tmp_path)
        assert "substeps = 16" in text and "x0 = [-0.01, 0.0]" in text
        assert "[plant.environment]" in text
        _same_loop(loop, again.loop)
        np.testing.assert_array_equal(simulate(again.loop, **again.run).tau_reac,
                                      simulate(loop, **run).tau_reac)  # fmt: skip
        assert again.run["substeps"] == 16 and again.run["x0"] == (-0.01, 0.0)


def test_a_composition_of_a_handmade_observer_is_refused():
    system = design_observer(MODEL, order=1, bandwidth=100.0).system
    handmade = LinearObserver(F=system.F, G=system.G, H=system.H, E=system.E, N=system.N,
                              Ts=paper.TS, model=MODEL)  # fmt: skip
    loop = ServoLoop(plant=ServoModel(3.06e-4, environment=Environment(10.0)),
                     nominal=paper.NOMINAL, Ts=paper.TS, controller=ForceControl(1000.0),
                     observer=design_reaction_observer(design_observer(MODEL, order=1,
                                                                       bandwidth=100.0),
                                                       handmade))  # fmt: skip
    with pytest.raises(TypeError, match=r"^loop\.observer\.reaction must be of a known family"):
        scenario_toml(loop, reference=Step(0.1, 0.05), duration=1.0)


def test_a_reaction_torque_observer_linear_observer_is_refused_naming_the_design():
    """reaction_torque_observer() gives a LinearObserver: its DOb, RTOB and friction model are
    not recoverable, so the file is refused in one line that names design_reaction_observer;
    the same arguments through design_reaction_observer write back."""
    from hpdob.observers import reaction_torque_observer

    dob = design_observer(MODEL, order=1, bandwidth=100.0)

    def loop(observer):
        return ServoLoop(plant=ServoModel(3.06e-4, environment=Environment(10.0)),
                         nominal=paper.NOMINAL, Ts=paper.TS, controller=ForceControl(1000.0),
                         observer=observer)  # fmt: skip

    refused = r"^loop\.observer is a reaction-torque observer built by reaction_torque_observer"
    with pytest.raises(TypeError, match=refused + r"\(\).*design_reaction_observer\(\)") as err:
        scenario_toml(loop(reaction_torque_observer(dob, viscous=5e-5)),
                      reference=Step(0.1, 0.05), duration=1.0)  # fmt: skip
    assert "\n" not in str(err.value)
    text = scenario_toml(loop(design_reaction_observer(dob, viscous=5e-5)),
                         reference=Step(0.1, 0.05), duration=1.0)  # fmt: skip
    assert "[reaction_observer]" in text


FORCE = Path(__file__).resolve().parents[2] / "examples" / "force_step_stiff_wall.toml"


def test_a_friction_model_that_follows_the_plant_is_written_as_friction_plant(tmp_path):
    """The loop of another plant than the file's: friction = "plant" is written (not the
    numbers), and the file runs that loop bit for bit; numbers given as numbers are written as
    numbers and stay when the plant changes."""
    import dataclasses

    scenario = load_scenario(FORCE)
    run = {**scenario.run, "duration": 0.3}
    loop = scenario.loop.replace(plant=scenario.loop.plant.replace(coulomb=0.02))
    again, text = _round_trip(loop, run, tmp_path)
    assert '[reaction_observer]\nfriction = "plant"\nvelocity_filter = 100.0\n' in text
    assert again.loop.design.follows_plant and again.loop.design.coulomb == 0.02
    _same_loop(loop, again.loop)
    np.testing.assert_array_equal(simulate(loop, **run).tau_reac, again.simulate().tau_reac)
    fixed = loop.replace(observer=dataclasses.replace(loop.design, follows_plant=False))
    again, text = _round_trip(fixed, run, tmp_path)
    assert "[reaction_observer]\nviscous = 5e-05\ncoulomb = 0.02\nvelocity_filter" in text
    assert 'friction = "plant"' not in text and not again.loop.design.follows_plant
    assert again.loop.replace(plant=scenario.loop.plant).design.coulomb == 0.02
