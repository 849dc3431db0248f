"""The linear closed loop: against an independent python-control interconnection, against
``hpdob.simulate`` sample by sample, and against analytic poles and gains."""

from __future__ import annotations

import math

import control
import numpy as np
import pytest

from hpdob import (
    PD,
    Actuator,
    Encoder,
    ParameterTypeError,
    ParameterValueError,
    ServoModel,
    closed_loop,
    closed_loop_poles,
    design_observer,
    estimation_response,
    simulate,
)
from hpdob.signals import SmoothStep, trajectory

TS = 1e-3
NOMINAL = ServoModel(2.8e-4)
PLANT = ServoModel(3.06e-4, 5e-5)  # Coulomb friction 0: the linear part of the canonical plant
PDC = PD(50.0, 5.0)


def observer(order, bandwidth=100.0):
    return design_observer(NOMINAL.discretize(TS), order=order, bandwidth=bandwidth)


def reference_interconnection(plant, nominal, controller, design, delay):
    """The same loop assembled block by block with python-control only.

    The plant is discretised by ``control.sample_system`` (not hpdob's ZOH), the observer is
    ``design.to_statespace()``, the PD a static gain, the delay a one-state shift.
    """
    cont = control.ss(
        [[0.0, 1.0], [0.0, -plant.b / plant.J]],
        [[0.0, 0.0], [1.0 / plant.J, -1.0 / plant.J]],
        np.eye(2),
        np.zeros((2, 2)),
        inputs=["a", "tau_ext"],
        outputs=["theta", "omega"],
    )
    blocks = [
        control.sample_system(cont, TS, method="zoh", name="plant"),
        control.summing_junction(["theta", "n_theta"], "theta_m", dt=TS, name="s1"),
        control.summing_junction(["omega", "n_omega"], "omega_m", dt=TS, name="s2"),
    ]
    Jn = nominal.J
    gains = [Jn * controller.kp, Jn * controller.kd, Jn, -Jn * controller.kp, -Jn * controller.kd]
    pd_inputs = ["r", "r_dot", "r_ddot", "theta_m", "omega_m"]
    if design is not None:
        obs = design.to_statespace()
        blocks.append(
            control.ss(
                obs.A,
                obs.B,
                obs.C,
                obs.D,
                TS,
                inputs=["theta_m", "omega_m", "u"],
                outputs=["tau_hat"],
                name="obs",
            )
        )
        gains.append(1.0)
        pd_inputs.append("tau_hat")
    blocks.append(
        control.ss(
            np.zeros((0, 0)),
            np.zeros((0, len(gains))),
            np.zeros((1, 0)),
            [gains],
            TS,
            inputs=pd_inputs,
            outputs=["u"],
            name="pd",
        )
    )
    if delay:
        blocks.append(
            control.ss(
                [[0.0]], [[1.0]], [[1.0]], [[0.0]], TS, inputs="u", outputs="a", name="delay"
            )
        )
    else:
        blocks.append(control.ss([], [], [], [[1.0]], TS, inputs="u", outputs="a", name="wire"))
    outputs = ["theta", "omega", "u"] + (["tau_hat"] if design is not None else [])
    return control.interconnect(
        blocks,
        inplist=["r", "r_dot", "r_ddot", "tau_ext", "n_theta", "n_omega"],
        outlist=outputs,
    )


@pytest.mark.parametrize(("order", "delay"), [(None, 0), (0, 0), (1, 0), (2, 1), (3, 0)])
def test_matches_independent_interconnection(order, delay):
    design = None if order is None else observer(order)
    loop = closed_loop(
        plant=PLANT,
        nominal=NOMINAL,
        Ts=TS,
        controller=PDC,
        observer=design,
        actuator=Actuator(delay_samples=delay),
    )
    ref = reference_interconnection(PLANT, NOMINAL, PDC, design, delay)
    w = 2 * np.pi * np.array([0.5, 3.0, 40.0, 300.0])
    mine = loop.frequency_response(w).frdata
    theirs = ref.frequency_response(w).frdata
    rows = ref.noutputs
    np.testing.assert_allclose(mine[:rows], theirs, rtol=1e-7, atol=1e-9 * np.abs(theirs).max())
    assert np.poly(
        closed_loop_poles(
            plant=PLANT,
            nominal=NOMINAL,
            Ts=TS,
            controller=PDC,
            observer=design,
            actuator=Actuator(delay_samples=delay),
        )
    ) == pytest.approx(np.poly(ref.poles()), abs=1e-9)


@pytest.mark.parametrize("order", [0, 1, 2, 3])
def test_poles_on_nominal_plant_are_pd_and_observer_poles(order):
    """Separation: on the nominal plant, eig = eig(A - B K_pd) and eig(M) (docs/analysis.md)."""
    design = observer(order, bandwidth=150.0)
    model = NOMINAL.discretize(TS)
    K = NOMINAL.J * np.array([PDC.kp, PDC.kd])
    expected = np.polymul(np.poly(model.A - np.outer(model.B, K)), (1, -math.exp(-0.15)))
    for _ in range(order):
        expected = np.polymul(expected, (1, -math.exp(-0.15)))
    poles = closed_loop_poles(
        plant=NOMINAL, nominal=NOMINAL, Ts=TS, controller=PDC, observer=design
    )
    np.testing.assert_allclose(np.poly(poles).real, expected, atol=1e-12)
    assert np.all(np.diff(np.abs(poles)) <= 0)  # sorted by decreasing magnitude


@pytest.mark.parametrize("order", [0, 1, 3])
def test_estimate_answers_external_torque_with_q_on_nominal_plant(order):
    design = observer(order)
    loop = closed_loop(plant=NOMINAL, nominal=NOMINAL, Ts=TS, controller=PDC, observer=design)
    f = np.array([0.2, 2.0, 20.0, 200.0])
    resp = loop.frequency_response(2 * np.pi * f).frdata
    i, j = loop.output_labels.index("tau_hat"), loop.input_labels.index("tau_ext")
    np.testing.assert_allclose(resp[i, j], estimation_response(design, f), rtol=0, atol=1e-8)


def test_dc_gains():
    """Observer (integral action): theta/r = 1, theta/tau_ext = 0. PD alone: -1/(J_n kp)."""
    loop = closed_loop(plant=PLANT, nominal=NOMINAL, Ts=TS, controller=PDC, observer=observer(1))
    dc = loop.dcgain()
    assert dc[0, 0] == pytest.approx(1.0, abs=1e-9)
    assert dc[0, 3] == pytest.approx(0.0, abs=1e-9)
    assert dc[3, 3] == pytest.approx(1.0, abs=1e-9)  # the estimate converges to the load
    pd_only = closed_loop(plant=ServoModel(3.06e-4), nominal=NOMINAL, Ts=TS, controller=PDC)
    assert pd_only.dcgain()[0, 3] == pytest.approx(-1.0 / (NOMINAL.J * PDC.kp), rel=1e-9)
    assert loop.state_labels == ["theta", "omega", "z1", "z2"]


@pytest.mark.parametrize(
    ("order", "sensor", "delay"),
    [(1, None, 0), (2, Encoder(2**40, velocity="backward-difference"), 1), (None, None, 1)],
)
def test_matches_simulate_sample_by_sample(order, sensor, delay):
    """Linear plant (no Coulomb friction), a torque constant over each sample: simulate's
    continuous-time integration and the LTI loop give the same samples."""
    n = 1200
    t = np.arange(n) * TS
    reference = SmoothStep(0.1, 0.6, 1.0)
    load = 0.05 * (t >= 0.3) - 0.02 * (t >= 0.9)

    # simulate integrates on sub-step midpoints; these thresholds fall between samples 299/300
    # and 899/900, so the torque is constant over every sample.
    def disturbance(tt):
        return 0.05 * (tt >= 0.29995) - 0.02 * (tt >= 0.89995)

    design = None if order is None else observer(order)
    res = simulate(
        plant=PLANT,
        nominal=NOMINAL,
        Ts=TS,
        duration=n * TS,
        controller=PDC,
        observer=design,
        reference=reference,
        disturbance=disturbance,
        sensor=sensor,
        actuator=Actuator(delay_samples=delay),
        substeps=4,
    )
    loop = closed_loop(
        plant=PLANT,
        nominal=NOMINAL,
        Ts=TS,
        controller=PDC,
        observer=design,
        sensor=sensor,
        actuator=Actuator(delay_samples=delay),
    )
    r, rd, rdd = trajectory(reference)(t)
    U = np.vstack([r, rd, rdd, load, np.zeros(n), np.zeros(n)])
    out = control.forced_response(loop, T=t, U=U).outputs
    np.testing.assert_allclose(out[0], res.theta, rtol=0, atol=1e-9)
    np.testing.assert_allclose(out[1], res.omega, rtol=0, atol=1e-7)
    np.testing.assert_allclose(out[2], res.u, rtol=0, atol=1e-9)
    np.testing.assert_allclose(out[3], res.tau_hat, rtol=0, atol=1e-9)


def test_bad_arguments():
    kw = {"plant": PLANT, "nominal": NOMINAL, "Ts": TS, "controller": PDC}
    with pytest.raises(ParameterValueError, match=r"actuator.torque_limit must be None.*0\.444"):
        closed_loop(**kw, actuator=Actuator(torque_limit=0.444))
    wrong = design_observer(ServoModel(3e-4).discretize(TS), order=1, bandwidth=100.0)
    with pytest.raises(ParameterValueError, match="observer must be designed on nominal"):
        closed_loop_poles(**kw, observer=wrong)
    with pytest.raises(
        ParameterTypeError,
        match=r"plant must be a ServoModel, a TwoMassServo or a MujocoServo .*, got DiscreteServo",
    ):
        closed_loop(**{**kw, "plant": PLANT.discretize(TS)})
    with pytest.raises(ParameterTypeError, match="controller must be a PD"):
        closed_loop(**{**kw, "controller": (50, 5)})
    with pytest.raises(ParameterValueError, match=r"Ts must be a positive.*-0.001"):
        closed_loop_poles(**{**kw, "Ts": -1e-3})
    with pytest.raises(ParameterTypeError, match="observer must be a DisturbanceObserver, an Obs"):
        closed_loop(**kw, observer="HPDOb")
    with pytest.raises(ParameterTypeError, match="sensor must be an Encoder or None"):
        closed_loop(**kw, sensor="encoder")
    with pytest.raises(
        ParameterValueError, match=r"^actuator.delay_samples must be at most 1000 .*1001"
    ):
        closed_loop_poles(**kw, actuator=Actuator(delay_samples=1001))
