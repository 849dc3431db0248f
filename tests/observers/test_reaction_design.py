"""ReactionObserverDesign / design_reaction_observer: the RTOB composition as a design that
keeps its parts (issue 21: scenario files and sweeps of a composition)."""

from __future__ import annotations

import dataclasses
import pickle

import numpy as np
import pytest

from hpdob import ParameterTypeError, ParameterValueError, ServoModel, design_observer, paper
from hpdob.observers import (
    ReactionObserverDesign,
    design_eso,
    design_reaction_observer,
    reaction_torque_observer,
)

MODEL = paper.NOMINAL.discretize(paper.TS)
DOB = design_observer(MODEL, order=1, bandwidth=100.0)


def _same(a, b):
    for matrix in "FGHEN":
        np.testing.assert_array_equal(getattr(a, matrix), getattr(b, matrix))
    assert (a.outputs, a.measures, a.coulomb, a.model) == (b.outputs, b.measures, b.coulomb,
                                                           b.model)  # fmt: skip


@pytest.mark.parametrize("options", [{}, {"viscous": 5e-5},
                                     {"viscous": 5e-5, "coulomb": 0.01, "coulomb_velocity": 0.02},
                                     {"coulomb": 0.01, "velocity_filter": 100.0}])  # fmt: skip
@pytest.mark.parametrize("reaction", [None, design_observer(MODEL, order=0, bandwidth=200.0)])
def test_the_design_is_the_composition(options, reaction):
    design = design_reaction_observer(DOB, reaction, **options)
    _same(design.system, reaction_torque_observer(DOB, reaction, **options))
    assert design.dob is DOB and design.reaction is reaction and design.model == MODEL
    assert design.Ts == paper.TS
    assert design.friction == options


def test_friction_from_a_plant_model_is_read_into_numbers():
    plant = ServoModel(3.06e-4, 7e-5, coulomb=0.01, coulomb_velocity=0.005)
    design = design_reaction_observer(DOB, friction=plant, velocity_filter=50.0)
    assert design.friction == {"viscous": 7e-5, "coulomb": 0.01, "coulomb_velocity": 0.005,
                               "velocity_filter": 50.0}  # fmt: skip
    _same(design.system, reaction_torque_observer(DOB, friction=plant, velocity_filter=50.0))
    assert ReactionObserverDesign(DOB, **design.friction).friction == design.friction


def test_replace_pickle_and_numpy_values():
    design = design_reaction_observer(DOB, viscous=np.float64(5e-5), coulomb=np.float32(0.01))
    assert type(design.viscous) is float and type(design.coulomb) is float
    again = dataclasses.replace(design, viscous=1e-4)  # validated and composed again
    assert again.viscous == 1e-4 and again.system is not design.system
    _same(pickle.loads(pickle.dumps(design)).system, design.system)


def test_bad_compositions_are_refused_with_the_parameter_named():
    with pytest.raises(ParameterValueError, match=r"^viscous must be a non-negative"):
        design_reaction_observer(DOB, viscous=-1.0)
    with pytest.raises(ParameterValueError, match=r"^friction is given, so viscous and coulomb"):
        design_reaction_observer(DOB, viscous=1e-5, friction=paper.PLANT)
    with pytest.raises(ParameterValueError, match=r"^velocity_filter = 100.0 filters the Coulomb"):
        design_reaction_observer(DOB, velocity_filter=100.0)
    with pytest.raises(ParameterValueError, match=r"^reaction must be designed on dob's nominal"):
        design_reaction_observer(DOB, design_observer(paper.PLANT.discretize(paper.TS),
                                                      order=0, bandwidth=100.0))  # fmt: skip
    with pytest.raises(ParameterValueError, match=r"^reaction must measure what dob measures"):
        design_reaction_observer(DOB, design_eso(MODEL, bandwidth=100.0))
    with pytest.raises(ParameterTypeError, match=r"^dob must be"):
        design_reaction_observer("dob")
    with pytest.raises(ParameterValueError, match=r"^dob already has a tau_reac output"):
        design_reaction_observer(design_reaction_observer(DOB))


def test_a_design_that_follows_the_plant_reads_another_plants_friction():
    """follows_plant: the friction model is the plant's; with_plant_friction(other) is the
    composition of reaction_torque_observer(friction=other), the parts and the velocity filter
    kept (itself for the plant it was read from)."""
    plant = ServoModel(3.06e-4, 7e-5, coulomb=0.01, coulomb_velocity=0.005)
    design = design_reaction_observer(DOB, friction=plant, velocity_filter=50.0,
                                      follows_plant=True)  # fmt: skip
    assert design.follows_plant and design.with_plant_friction(plant) is design
    other = plant.replace(b=9e-5, coulomb=0.02, coulomb_velocity=0.02)
    moved = design.with_plant_friction(other)
    _same(moved.system, reaction_torque_observer(DOB, friction=other, velocity_filter=50.0))
    assert moved.follows_plant and moved.dob is DOB and moved.reaction is None
    assert moved.friction == {"viscous": 9e-5 - MODEL.b, "coulomb": 0.02,
                              "coulomb_velocity": 0.02, "velocity_filter": 50.0}  # fmt: skip
    assert pickle.loads(pickle.dumps(moved)).follows_plant
    # numbers given as numbers are fixed (the default): a loop leaves them as they are
    assert not design_reaction_observer(DOB, friction=plant).follows_plant


def test_following_the_plant_refuses_what_has_no_one_friction_model():
    from hpdob import TwoMassServo

    plant = ServoModel(3.06e-4, 2e-4, coulomb=0.01)
    with pytest.raises(ParameterTypeError, match=r"^follows_plant must be True or False, "
                       r"got 'yes' of type str$"):  # fmt: skip
        design_reaction_observer(DOB, friction=plant, follows_plant="yes")
    refused = r"^follows_plant = True reads the friction model from the plant: give the loop's "
    with pytest.raises(ParameterValueError, match=refused + r"plant as friction=plant"):
        design_reaction_observer(DOB, follows_plant=True)
    design = design_reaction_observer(DOB, friction=plant, follows_plant=True)
    with pytest.raises(ParameterTypeError, match=r"^plant must be a rigid ServoModel for a "
                       r"reaction-torque observer whose friction model is the plant's "
                       r"\(follows_plant=True; .*got TwoMassServo$"):  # fmt: skip
        design.with_plant_friction(TwoMassServo(2e-4, 1e-4, 100.0))
    viscous = design_observer(ServoModel(2.8e-4, 1e-4).discretize(paper.TS), order=1,
                              bandwidth=100.0)  # fmt: skip
    design = design_reaction_observer(viscous, friction=plant, follows_plant=True)
    assert design.viscous == pytest.approx(1e-4)  # b - b_n
    below = r"^plant.b = 5e-05 must be at least the nominal b_n = 0.0001: the reaction-torque "
    with pytest.raises(ParameterValueError, match=below + r"observer's friction"):
        design.with_plant_friction(plant.replace(b=5e-5))
    assert design.viscous == pytest.approx(1e-4)
