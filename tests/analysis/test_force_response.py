"""tau_env/tau_ref of the force loop in contact (issue 21 section 4): DC gain, -3 dB bandwidth
against the ideal-observer second-order model and python-control, zeros at the observer's
poles, the frequency response against a simulated sine."""

from __future__ import annotations

import numpy as np
import pytest

from hpdob import Actuator, Environment, ParameterValueError, ServoLoop, paper, simulate
from hpdob.analysis import force_response
from hpdob.controllers import ForceControl
from hpdob.models import InContact
from hpdob.observers import design_observer, reaction_torque_observer

PLANT = paper.PLANT.replace(coulomb=0.0)
NOMINAL = paper.NOMINAL


def _loop(k_e=10.0, *, ratio=None, order=1, g=100.0, kf=1000.0, kv=40.0, Ts=1e-3,
          sensor=paper.VIRTUAL_SENSOR, delay=1):  # fmt: skip
    nominal = NOMINAL if ratio is None else NOMINAL.replace(J=ratio * PLANT.J)
    dob = design_observer(nominal.discretize(Ts), order=order, bandwidth=g)
    return ServoLoop(plant=PLANT.replace(environment=Environment(k_e)), nominal=nominal, Ts=Ts,
                     controller=ForceControl(kf, kv=kv), sensor=sensor,
                     observer=reaction_torque_observer(dob, viscous=PLANT.b - nominal.b),
                     actuator=Actuator(torque_limit=0.444, delay_samples=delay))  # fmt: skip


@pytest.mark.parametrize("ratio", [0.5, 1.0, 1.5])
def test_bandwidth_is_the_ideal_observer_second_order_model(ratio):
    """Ideal DOb (theta_ddot = a_ref), RTOB reading tau_env + (J - J_n) theta_ddot:
    tau_env/tau_ref = K_f k_e / ((1 + K_f (J - J_n)) s^2 + K_v s + K_f k_e). A fast observer
    (3000 rad/s, no delay, ideal sensor) on a 1 N m/rad wall: the -3 dB bandwidth of that
    model (python-control's bandwidth) within 1 % (0.3 % measured)."""
    import control

    response = force_response(_loop(1.0, ratio=ratio, g=3000.0, sensor=None, delay=0))
    effective = 1.0 + 1000.0 * PLANT.J * (1.0 - ratio)
    model = control.tf([1000.0 * 1.0], [effective, 40.0, 1000.0 * 1.0])
    assert response.bandwidth == pytest.approx(float(control.bandwidth(model)), rel=0.01)
    assert response.dc_gain == pytest.approx(1.0, abs=1e-9)


def test_bandwidth_is_minus_3_db_in_python_control():
    """python-control's frequency response of the returned system at the bandwidth is
    1/sqrt(2) of its DC gain (its own evaluation), and above it below, below it above."""
    import control

    response = force_response(_loop())
    w = response.bandwidth
    magnitude = control.frequency_response(response.system, [0.99 * w, w, 1.01 * w]).magnitude
    dc = float(control.dcgain(response.system))
    np.testing.assert_allclose(magnitude.ravel()[1] / dc, 1 / np.sqrt(2.0), rtol=1e-9)
    assert magnitude.ravel()[0] / dc > 1 / np.sqrt(2.0) > magnitude.ravel()[2] / dc
    assert response.system.dt == pytest.approx(1e-3)


@pytest.mark.parametrize(("order", "ratio"), [(0, 0.5), (1, 1.0), (1, 3.0), (2, 2.0)])
def test_zeros_at_the_observer_poles_whatever_the_nominal_inertia(order, ratio):
    """tau_env/tau_ref has the shared DOb/RTOB's m + 1 poles exp(-g Ts) among its zeros, at
    every J_n/J: the nominal inertia moves the force loop's poles, not these zeros."""
    response = force_response(_loop(ratio=ratio, order=order))
    target = np.exp(-100.0 * 1e-3)
    near = np.abs(response.zeros - target) < 1e-4
    assert near.sum() == order + 1, response.zeros


def test_over_estimated_nominal_inertia_widens_the_force_bandwidth():
    """Less effective inertia 1 + K_f (J - J_n): bandwidth grows with J_n/J towards the
    stability boundary, where the resonance peak grows without bound."""
    bandwidths = [force_response(_loop(ratio=r)).bandwidth for r in (0.25, 0.5, 1.0, 2.0, 3.0)]
    assert np.all(np.diff(bandwidths) > 0)
    assert force_response(_loop(ratio=4.0)).peak > 10 * force_response(_loop(ratio=1.0)).peak


def test_response_is_the_simulated_sine_amplitude():
    """Independent check of |T| at one frequency: the linear loop in contact simulated (the
    compiled kernel, InContact, no torque limit, unquantised backward difference) under
    tau_ref = 0.01 sin(w t); the steady amplitude of tau_env is |T(e^{j w Ts})| 0.01 within
    1 % (the held reference vs a sine: the ZOH's own half-sample shift is inside that)."""
    from hpdob import Encoder

    sensor = Encoder(2**52, velocity="backward-difference")
    loop = _loop(sensor=sensor)
    response = force_response(loop)
    w = response.bandwidth
    linear = loop.replace(plant=InContact(loop.plant), actuator=Actuator(delay_samples=1))
    result = simulate(linear, reference=lambda t: (0.01 * np.sin(w * t), 0 * t, 0 * t),
                      duration=3.0)  # fmt: skip
    tau_env = loop.plant.environment.stiffness * result.theta[-1000:]
    amplitude = 0.5 * (tau_env.max() - tau_env.min())
    assert amplitude == pytest.approx(0.01 / np.sqrt(2.0), rel=0.01)


def test_bad_inputs():
    with pytest.raises(ParameterValueError, match=r"^loop.plant must be in contact"):
        force_response(_loop().replace(plant=PLANT))
    with pytest.raises(ParameterValueError, match=r"asymptotically stable for a force response"):
        force_response(_loop(1000.0))


def test_a_scenario_whose_rtob_friction_is_the_plants_is_analysed_in_contact():
    """[reaction_observer] friction = "plant": the analysis puts the plant in contact
    (InContact), whose friction is its plant's, so the view equals that of the same numbers
    given as numbers (issue 21: the composition follows the plant)."""
    import dataclasses
    from pathlib import Path

    from hpdob.simulation import load_scenario

    path = Path(__file__).resolve().parents[2] / "examples" / "force_step_stiff_wall.toml"
    loop = load_scenario(path).loop
    fixed = loop.replace(observer=dataclasses.replace(loop.design, follows_plant=False))
    follows, numbers = force_response(loop), force_response(fixed)
    np.testing.assert_array_equal(follows.poles, numbers.poles)
    assert (follows.dc_gain, follows.bandwidth) == (numbers.dc_gain, numbers.bandwidth)
    held = loop.replace(plant=InContact(loop.plant.replace(b=1e-4)))
    assert held.design.viscous == 1e-4 and held.design.coulomb == loop.plant.coulomb
