"""``spectral_radii`` against ``closed_loop_poles`` of each loop built and validated in full."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from hpdob import (
    PD,
    PID,
    Actuator,
    Encoder,
    ParameterTypeError,
    ParameterValueError,
    ServoLoop,
    ServoModel,
    TwoMassServo,
    closed_loop_poles,
    design_observer,
)
from hpdob.analysis import spectral_radii
from hpdob.analysis._linear_loop import delayed_state_matrix, loop_matrices, loop_spec
from hpdob.observers import design_kalman

NOMINAL = ServoModel(2.8e-4, 1e-4)
TS = 1e-3
MODEL = NOMINAL.discretize(TS)
PLANTS = [ServoModel(0.7 * 2.8e-4, 0.0), ServoModel(1.3 * 2.8e-4, 2e-4), NOMINAL]
DELAYS = [0, 1, 2, 3, 7, 20]


def _loops():
    yield ServoLoop(plant=NOMINAL, nominal=NOMINAL, Ts=TS, controller=PD(50.0, 5.0),
                    observer=design_observer(MODEL, order=1, bandwidth=300.0))  # fmt: skip
    yield ServoLoop(plant=NOMINAL, nominal=NOMINAL, Ts=TS,
                    controller=PD(50.0, 5.0, velocity="observer"),
                    observer=design_observer(MODEL, order=2, bandwidth=150.0,
                                             measurement="position"),
                    sensor=Encoder(16384, velocity="backward-difference"))  # fmt: skip
    yield ServoLoop(plant=NOMINAL, nominal=NOMINAL, Ts=TS, controller=PID(50.0, 100.0, 5.0),
                    observer=design_kalman(MODEL, order=1, position_noise_std=1e-4,
                                           process_noise_std=1e-2),
                    sensor=Encoder(4096))  # fmt: skip
    yield ServoLoop(plant=NOMINAL, nominal=NOMINAL, Ts=TS, controller=PD(50.0, 5.0),
                    observer=None)  # fmt: skip


@pytest.mark.parametrize("index", range(4))
def test_radii_are_those_of_each_loop_built_in_full(index):
    loop = list(_loops())[index]
    plants = [*PLANTS, TwoMassServo(1.4e-4, 1.4e-4, 20.0)]
    radii = spectral_radii(loop, plants, DELAYS)
    assert radii.shape == (len(DELAYS), len(plants))
    for i, d in enumerate(DELAYS):
        for j, plant in enumerate(plants):
            full = loop.replace(plant=plant, actuator=Actuator(delay_samples=d))
            assert radii[i, j] == np.abs(closed_loop_poles(full)).max()  # bit for bit


@pytest.mark.parametrize("index", range(4))
def test_delayed_state_matrix_is_loop_matrices_bit_for_bit(index):
    spec = loop_spec(list(_loops())[index])
    for plant in (*PLANTS, TwoMassServo(1.4e-4, 1.4e-4, 20.0)):
        one = dataclasses.replace(spec, plant=plant.discretize(TS), delay=1)
        template = loop_matrices(one)[0]
        for d in range(1, 25):
            expected = loop_matrices(dataclasses.replace(one, delay=d))[0]
            got = delayed_state_matrix(template, one, d)
            assert got.shape == expected.shape
            assert np.array_equal(got.view(np.uint64), expected.view(np.uint64))  # bits too


def test_bad_arguments_are_named():
    loop = next(_loops())
    with pytest.raises(ParameterValueError, match="delay_samples must be integers"):
        spectral_radii(loop, PLANTS, [-1])
    with pytest.raises(ParameterValueError, match="delay_samples must be integers"):
        spectral_radii(loop, PLANTS, [1.5])
    with pytest.raises(ParameterTypeError, match="plants must be linear plants"):
        spectral_radii(loop, ["motor"], [0])
    saturated = loop.replace(actuator=Actuator(torque_limit=0.4))
    with pytest.raises(ParameterValueError, match="torque_limit must be None"):
        spectral_radii(saturated, PLANTS, [0])


def test_an_rtob_that_follows_the_plant_is_that_of_each_plants_loop():
    """A force loop whose RTOB friction model is the plant's (friction = "plant"): each
    plant's radius is that of loop.replace(plant=...), whose RTOB subtracts that plant's
    viscous friction, not the base plant's."""
    from pathlib import Path

    from hpdob.simulation import load_scenario

    path = Path(__file__).resolve().parents[2] / "examples" / "force_step_stiff_wall.toml"
    loop = load_scenario(path).loop.replace(actuator=Actuator(delay_samples=1))
    plants = [loop.plant.replace(b=b) for b in (5e-5, 5e-4, 2e-3)]
    radii = spectral_radii(loop, plants, [0, 1])
    for i, d in enumerate([0, 1]):
        for j, plant in enumerate(plants):
            full = loop.replace(plant=plant, actuator=Actuator(delay_samples=d))
            assert full.design.viscous == plant.b  # b_n = 0
            assert radii[i, j] == np.abs(closed_loop_poles(full)).max()  # bit for bit
    fixed = loop.replace(observer=dataclasses.replace(loop.design, follows_plant=False))
    other = spectral_radii(fixed, plants, [0, 1])
    assert (other[:, 0] == radii[:, 0]).all() and (other[:, 1:] != radii[:, 1:]).all()


@pytest.mark.parametrize("index", range(4))
def test_stacked_delayed_state_matrices_are_each_ones_bit_for_bit(index):
    """A stack of one-sample matrices (tune's corners) delayed as one array."""
    spec = loop_spec(list(_loops())[index])
    ones = [dataclasses.replace(spec, plant=p.discretize(TS), delay=1) for p in PLANTS]
    stack = np.stack([loop_matrices(one)[0] for one in ones])
    state = NOMINAL.discretize(TS).A.shape[0] + int(spec.backward_difference)
    for d in (1, 2, 5, 21):
        got = delayed_state_matrix(stack, None, d, state=state)
        for k, one in enumerate(ones):
            expected = loop_matrices(dataclasses.replace(one, delay=d))[0]
            assert np.array_equal(got[k].view(np.uint64), expected.view(np.uint64))


@pytest.mark.parametrize("index", range(4))
def test_a_radii_scan_asked_batch_by_batch_is_spectral_radii(index):
    """tune's delay-margin scan: one RadiiScan asked delay by delay, in any order, gives
    spectral_radii's figures bit for bit (rigid plants stacked; with a two-mass plant among
    them the matrices differ in size and go one by one)."""
    from hpdob.analysis import RadiiScan

    loop = list(_loops())[index]
    for plants in (PLANTS, [*PLANTS, TwoMassServo(1.4e-4, 1.4e-4, 20.0)]):
        scan = RadiiScan(loop, plants)
        whole = spectral_radii(loop, plants, DELAYS)
        for i in (3, 0, 5, 1, 2, 4, 3):
            got = scan.radii([DELAYS[i]])
            assert np.array_equal(got[0].view(np.uint64), whole[i].view(np.uint64))
    with pytest.raises(ParameterValueError, match="delay_samples must be integers"):
        RadiiScan(loop, PLANTS).radii([1001])
