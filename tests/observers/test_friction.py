"""The RTOB's Coulomb term (issue 21 section 2): tau_reac = tau^R - Delta_b omega - c tanh(w/v),
a documented nonlinear composition after the linear observer, one definition for the Python
runtime, the compiled kernel and the exported C (tests/controllers/test_force.py checks the C)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from force_step import force_step_run  # tests/force_step.py
from hpdob import (
    LinearObserver,
    Observer,
    ParameterTypeError,
    ParameterValueError,
    ServoModel,
    design_observer,
    paper,
)
from hpdob.export import fixed_point_design
from hpdob.observers import CoulombFriction, coulomb_torque, outputs, reaction_torque_observer

TS = paper.TS
MODEL = paper.NOMINAL.discretize(TS)
PLANT = paper.PLANT  # c = 0.01 N m, v = 0.01 rad/s, b = 5e-5 N m s/rad
DELTA_B = PLANT.b - paper.NOMINAL.b


def test_coulomb_torque_is_the_plants_shape():
    omega = np.linspace(-0.05, 0.05, 11)
    expected = PLANT.coulomb_torque(omega)
    got = [coulomb_torque(PLANT.coulomb, PLANT.coulomb_velocity, float(w)) for w in omega]
    np.testing.assert_allclose(got, expected, rtol=1e-15, atol=0)  # numpy's tanh: to an ulp
    assert coulomb_torque(0.01, 0.01, 0.0) == 0.0


def test_friction_model_from_a_plant_model():
    dob = design_observer(MODEL, order=1, bandwidth=100.0)
    both = reaction_torque_observer(dob, friction=PLANT)
    given = reaction_torque_observer(dob, viscous=DELTA_B, coulomb=0.01, coulomb_velocity=0.01)
    assert both.coulomb == given.coulomb == CoulombFriction(0.01, 0.01, "omega")
    np.testing.assert_array_equal(both.E, given.E)
    # the viscous part is the linear row: E's omega entry of tau_reac is the DOb's minus Delta_b
    assert both.E[1, 1] == dob.system.E[0, 1] - DELTA_B


def test_tau_reac_is_the_literal_equation():
    """simulate's tau_reac against the equation written out independently: the DOb's own
    estimate (the Python runtime of the DOb alone) minus Delta_b omega_m minus
    c tanh(w_k / v), w the measured velocity low-passed by hand (w_k = a w_{k-1} + (1-a) omega_k,
    a = exp(-100 Ts), w_{-1} = omega_0)."""
    dob = design_observer(MODEL, order=1, bandwidth=100.0)
    both = reaction_torque_observer(dob, friction=PLANT, velocity_filter=100.0)
    assert both.outputs == ("tau_hat", "omega_hat", "tau_reac") and both.n_states == 3
    result = force_step_run(both)
    alone = Observer.of(dob)
    alone.reset((-0.01, 0.0))
    a, w = math.exp(-100.0 * TS), 0.0
    expected, filtered = [], []
    for th, om, u in zip(result.theta_measured, result.omega_measured, result.u, strict=True):
        w = a * w + (1.0 - a) * om
        filtered.append(w)
        expected.append(alone.estimate((th, om)) - DELTA_B * om - 0.01 * math.tanh(w / 0.01))
        alone.update((th, om), u)
    np.testing.assert_allclose(result.omega_hat, filtered, rtol=0, atol=1e-12)
    np.testing.assert_allclose(result.tau_reac, expected, rtol=0, atol=1e-12)
    # not vacuous: the Coulomb term is large while the axis moves
    coulomb = np.asarray(result.tau_hat) - DELTA_B * result.omega_measured - result.tau_reac
    assert np.max(np.abs(coulomb)) > 0.009


@pytest.mark.parametrize("velocity_filter", [None, 100.0])
def test_kernel_and_python_runtime_agree_bit_for_bit(velocity_filter):
    """The compiled kernel's tau_reac is the Python runtime's (hpdob.observers.outputs on the
    same measurements and commands) to the last bit: one definition of the Coulomb term."""
    dob = design_observer(MODEL, order=1, bandwidth=100.0)
    both = reaction_torque_observer(dob, friction=PLANT, velocity_filter=velocity_filter)
    result = force_step_run(both, duration=0.3)
    runtime = Observer.of(both)
    runtime.reset((-0.01, 0.0))
    state = runtime.state
    tau_reac = []
    for th, om in zip(result.theta_measured, result.omega_measured, strict=True):
        y = outputs(both, tuple(map(float, state)), (float(th), float(om)))
        tau_reac.append(y[-1])
        runtime.update((th, om), float(result.u[len(tau_reac) - 1]))
        state = runtime.state
    np.testing.assert_array_equal(result.tau_reac, tau_reac)


def test_position_only_observer_reads_its_velocity_estimate():
    pos = design_observer(MODEL, order=1, bandwidth=100.0, measurement="position")
    both = reaction_torque_observer(pos, coulomb=0.01)
    assert both.coulomb.velocity == "omega_hat"
    state = Observer.of(both)
    state.reset((0.0, 0.5))  # converged at 0.5 rad/s: omega_hat = 0.5
    y = outputs(both, tuple(map(float, state.state)), 0.0)
    assert y[1] == pytest.approx(0.5, abs=1e-12)
    assert y[2] == pytest.approx(y[0] - 0.01 * math.tanh(0.5 / 0.01), abs=1e-15)


def test_bad_inputs_are_refused():
    dob = design_observer(MODEL, order=1, bandwidth=100.0)
    pos = design_observer(MODEL, order=1, bandwidth=100.0, measurement="position")
    with pytest.raises(ParameterValueError, match=r"^coulomb must be a non-negative"):
        reaction_torque_observer(dob, coulomb=-0.01)
    with pytest.raises(ParameterValueError, match=r"^coulomb_velocity must be a positive"):
        reaction_torque_observer(dob, coulomb=0.01, coulomb_velocity=0.0)
    with pytest.raises(ParameterValueError, match=r"^friction is given, so viscous"):
        reaction_torque_observer(dob, friction=PLANT, viscous=1e-5)
    with pytest.raises(ParameterTypeError, match=r"^friction must be a ServoModel"):
        reaction_torque_observer(dob, friction=0.01)
    damped = design_observer(ServoModel(2.8e-4, 1e-4).discretize(TS), order=1, bandwidth=100.0)
    with pytest.raises(ParameterValueError, match=r"^friction.b = 0.0 must be at least"):
        reaction_torque_observer(damped, friction=ServoModel(3e-4))
    with pytest.raises(ParameterValueError, match=r"^velocity_filter = 100.0 filters"):
        reaction_torque_observer(dob, velocity_filter=100.0)
    with pytest.raises(ParameterValueError, match=r"^velocity_filter = 100.0 needs a measured"):
        reaction_torque_observer(pos, coulomb=0.01, velocity_filter=100.0)
    with pytest.raises(ParameterValueError, match=r"^velocity_filter must be a positive"):
        reaction_torque_observer(dob, coulomb=0.01, velocity_filter=-1.0)
    linear = dob.system
    with pytest.raises(ParameterValueError, match=r"^coulomb needs a tau_reac output"):
        LinearObserver(F=linear.F, G=linear.G, H=linear.H, E=linear.E, N=linear.N, Ts=TS,
                       coulomb=CoulombFriction(0.01, 0.01))  # fmt: skip
    with pytest.raises(ParameterTypeError, match=r"^coulomb must be a CoulombFriction"):
        LinearObserver(F=linear.F, G=linear.G, H=linear.H, E=linear.E, N=linear.N, Ts=TS,
                       coulomb=0.01)  # fmt: skip
    with pytest.raises(ParameterValueError, match=r"^velocity must be one of"):
        CoulombFriction(0.01, 0.01, "speed")
    # fixed point has no tanh: refused, not silently dropped
    both = reaction_torque_observer(dob, coulomb=0.01)
    with pytest.raises(ParameterValueError, match=r"has a Coulomb term \(tanh\)"):
        fixed_point_design(both, counts_per_rev=16384, omega_max=100.0, u_max=1.0, tau_max=1.0)


def test_friction_model_from_identify():
    """The friction model from identify (issue 21: "from identify results"): an analytic, noise
    free motion of the paper's motor (u = J a + b omega + c sign(omega)) identified, and
    ``friction=fit.model()`` subtracts b - b_n and c with the fit's velocity scale."""
    from hpdob import identify

    t = np.arange(20000) * TS
    w1, w2 = 2 * np.pi * 0.5, 2 * np.pi * 3.0
    q = 0.3 * np.sin(w1 * t) + 0.05 * np.sin(w2 * t + 0.3)
    qd = 0.3 * w1 * np.cos(w1 * t) + 0.05 * w2 * np.cos(w2 * t + 0.3)
    qdd = -0.3 * w1**2 * np.sin(w1 * t) - 0.05 * w2**2 * np.sin(w2 * t + 0.3)
    u = PLANT.J * qdd + PLANT.b * qd + PLANT.coulomb * np.sign(qd)
    fit = identify(t, q, u, method="idim-ls", diagnostics=False)
    dob = design_observer(MODEL, order=1, bandwidth=100.0)
    both = reaction_torque_observer(dob, friction=fit.model())
    assert both.coulomb.c == fit.coulomb == pytest.approx(PLANT.coulomb, rel=1e-3)
    assert both.coulomb.v == fit.model().coulomb_velocity
    assert dob.system.E[0, 1] - both.E[1, 1] == pytest.approx(PLANT.b - paper.NOMINAL.b, rel=1e-2)
