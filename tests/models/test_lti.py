"""python-control in: servo models as ``tf``/``ss``, estimators designed elsewhere.

``ServoModel.from_lti`` is checked on systems written from J and b (and against the ZOH sampling
python-control computes, ``control.c2d``); ``LinearObserver.from_statespace`` against every
family's analytic reset matrix ``N``, against pyadrc's ESO (an independent implementation,
stepped with its own recursion) and against an estimator placed with ``control.place``.
"""

from __future__ import annotations

import control
import numpy as np
import pytest

from hpdob import (
    PD,
    DisturbanceObserver,
    LinearObserver,
    Observer,
    ParameterTypeError,
    ParameterValueError,
    ServoLoop,
    ServoModel,
    design_observer,
    estimate_disturbance,
    simulate,
)
from hpdob.models import DiscreteServoModel
from hpdob.observers import design_eso, design_kalman
from hpdob.signals import Sine, Step

TS = 1e-3
# Powers of two: J and b read back from the transfer function's coefficients exactly.
J, B = 2.0**-12, 2.0**-14
s = control.tf("s")


# -- ServoModel.from_lti ------------------------------------------------------------------------
@pytest.mark.parametrize(
    "sys",
    [
        1 / (J * s**2 + B * s),
        control.ss(1 / (J * s**2 + B * s)),
        control.ss([[0.0, 1.0], [0.0, -B / J]], [[0.0], [1.0 / J]], [[1.0, 0.0]], [[0.0]]),
    ],
    ids=["tf", "tf-as-ss", "ss"],
)
def test_from_lti_reads_J_and_b(sys):
    model = ServoModel.from_lti(sys)
    assert pytest.approx(J, rel=1e-14) == model.J
    assert model.b == pytest.approx(B, rel=1e-14)


def test_from_lti_torque_gain_and_friction():
    k = 0.05  # N m/A: the system is from a current [A] to the angle
    model = ServoModel.from_lti(k / (J * s**2), torque_gain=k, coulomb=0.01)
    assert (model.J, model.b, model.coulomb) == (pytest.approx(J, rel=1e-15), 0.0, 0.01)


@pytest.mark.parametrize(
    ("sys", "message"),
    [
        (1 / (s**2 + s + 1), r"poles off the origin that are not real"),
        ((s + 2) / (s**2 + s), r"it has a zero at s = \[-2.0\]"),
        (1 / (s + 1) ** 2, r"no pole at the origin"),
        (1 / (s * (s - 1)), r"right half-plane"),
        (1 / s, r"it has 1 poles, a servo has two"),
        (1 / s**3, r"it has 3 poles"),
        (-1 / s**2, r"gain -1.0 must be positive"),
        (control.c2d(1 / s**2, TS), r"must be a continuous system \(dt = 0\), got a discrete"),
        (control.tf([[[1.0], [1.0]]], [[[1.0, 0, 0], [1.0, 0, 0]]]), r"one input .* 2 inputs"),
    ],
)
def test_from_lti_names_what_is_not_a_servo(sys, message):
    with pytest.raises(ParameterValueError, match=message) as info:
        ServoModel.from_lti(sys)
    assert "\n" not in str(info.value)


def test_from_lti_rejects_other_types():
    with pytest.raises(ParameterTypeError, match="python-control TransferFunction or StateSpace"):
        ServoModel.from_lti("1/s^2")


def test_discrete_from_lti_matches_python_control_c2d():
    sysd = control.c2d(1 / (J * s**2 + B * s), TS)  # python-control's own ZOH sampling
    model = DiscreteServoModel.from_lti(sysd)
    reference = ServoModel(J, B).discretize(TS)
    assert model.Ts == TS
    assert pytest.approx(J, rel=1e-9) == model.J
    assert model.b == pytest.approx(B, rel=1e-6)
    np.testing.assert_allclose(model.A, reference.A, rtol=1e-9)
    np.testing.assert_allclose(model.B, reference.B, rtol=1e-9)
    with pytest.raises(ParameterValueError, match="not the zero-order-hold sampling"):
        DiscreteServoModel.from_lti(control.c2d(1 / (J * s**2), TS, method="tustin"))


def test_models_accepted_wherever_a_model_is_taken():
    sysd = control.c2d(1 / (J * s**2 + B * s), TS)
    model = ServoModel(J, B).discretize(TS)
    noise = {"position_noise_std": 1e-4, "process_noise_std": 1.0}
    for design, kwargs in ((design_observer, {"order": 1, "bandwidth": 100.0}),
                           (design_eso, {"bandwidth": 100.0}), (design_kalman, noise)):  # fmt: skip
        mine, theirs = design(sysd, **kwargs).system.F, design(model, **kwargs).system.F
        np.testing.assert_allclose(mine, theirs, rtol=1e-6, atol=1e-9)
    assert DisturbanceObserver(sysd, order=1, bandwidth=100.0).design.model.Ts == TS
    with pytest.raises(ParameterTypeError, match=r"discretise the continuous model first"):
        design_observer(1 / (J * s**2), order=1, bandwidth=100.0)
    with pytest.raises(ParameterTypeError, match="model must be a DiscreteServoModel or a"):
        design_eso("motor", bandwidth=100.0)


def test_servo_loop_and_simulate_take_transfer_functions():
    tf = 1 / (J * s**2 + B * s)
    observer = design_observer(ServoModel(J, B).discretize(TS), order=1, bandwidth=100.0)
    run = {"reference": Step(0.0, 0.1), "duration": 0.2, "disturbance": Step(0.1, 1e-3)}
    mine = simulate(ServoLoop(plant=tf, nominal=tf, Ts=TS, controller=PD(50, 5),
                              observer=observer), **run)  # fmt: skip
    theirs = simulate(ServoLoop(plant=ServoModel(J, B), nominal=ServoModel(J, B), Ts=TS,
                                controller=PD(50, 5), observer=observer), **run)  # fmt: skip
    np.testing.assert_array_equal(mine.tau_hat, theirs.tau_hat)  # J, b exact: the same run
    legacy = simulate(plant=tf, nominal=tf, Ts=TS, controller=PD(50, 5), observer=observer, **run)
    np.testing.assert_array_equal(legacy.theta, theirs.theta)


def test_observer_on_the_sampled_tf_fits_the_loop_on_the_tf():
    """Read back from python-control, J and b carry round-off (1e-13 here): the loop's check
    that the observer was designed on its nominal model holds to 1e-9, not to the last bit,
    and still refuses a model that differs."""
    tf = 1 / (3.06e-4 * s**2 + 5e-5 * s)
    observer = DisturbanceObserver(control.c2d(tf, TS), order=1, bandwidth=100.0)
    loop = ServoLoop(plant=tf, nominal=tf, Ts=TS, controller=PD(50, 5), observer=observer.design)
    assert pytest.approx(observer.design.model.J, rel=1e-12) == loop.nominal.J
    with pytest.raises(ParameterValueError, match=r"must be designed on nominal\.discretize"):
        ServoLoop(plant=tf, nominal=ServoModel(3.06e-4 * (1 + 1e-6), 5e-5), Ts=TS,
                  controller=PD(50, 5), observer=observer.design)  # fmt: skip


# -- LinearObserver.from_statespace -----------------------------------------------------------
MODEL = ServoModel(J, B).discretize(TS)
FAMILIES = {
    "DOb": lambda: design_observer(MODEL, order=0, bandwidth=100.0),
    "order-2": lambda: design_observer(MODEL, order=2, bandwidth=100.0),
    "position": lambda: design_observer(MODEL, order=1, bandwidth=100.0, measurement="position"),
    "ESO-current": lambda: design_eso(MODEL, bandwidth=200.0),
    "ESO-predictive": lambda: design_eso(MODEL, bandwidth=200.0, form="predictive"),
    "Kalman": lambda: design_kalman(MODEL, position_noise_std=1e-4, process_noise_std=1.0),
}


@pytest.mark.parametrize("family", FAMILIES)
def test_derived_reset_matches_every_family(family):
    """N derived from the matrices alone equals each family's own, written from its model."""
    system = FAMILIES[family]().system
    back = LinearObserver.from_statespace(system.to_statespace(), model=MODEL)
    assert (back.measures, back.outputs) == (system.measures, system.outputs)
    np.testing.assert_allclose(back.N, system.N, rtol=1e-9, atol=1e-9)
    np.testing.assert_array_equal(back.F, system.F)


def test_derived_reset_says_when_it_cannot():
    integrator = control.ss([[1.0]], [[0.0, 0.0, 1.0]], [[1.0]], [[0.0, 0.0, 0.0]], TS)
    with pytest.raises(ParameterValueError, match="F has an eigenvalue at 1"):
        LinearObserver.from_statespace(integrator, measures=("theta", "omega"))
    low_pass = control.ss([[0.5]], [[0.0, 0.0, 0.5]], [[2.0]], [[0.0, 0.0, 0.0]], TS)
    with pytest.raises(ParameterValueError, match="do not converge to it"):
        LinearObserver.from_statespace(low_pass, measures=("theta", "omega"))
    given = LinearObserver.from_statespace(low_pass, measures=("theta", "omega"), N=[[0, 0, 0]])
    assert given.N.tolist() == [[0.0, 0.0, 0.0]]
    with pytest.raises(ParameterValueError, match="measures must be given"):
        LinearObserver.from_statespace(control.ss(low_pass, inputs=3))
    with pytest.raises(ParameterValueError, match="must be a discrete system"):
        LinearObserver.from_statespace(control.ss([[-1.0]], [[0, 0, 1.0]], [[1.0]], [[0, 0, 0]]))


def _pyadrc_observer():
    import pyadrc

    adrc = pyadrc.StateSpace(order=2, delta=TS, b0=1 / J, w_cl=20.0, k_eso=10.0)
    # pyadrc's current ESO x_k = oA x_{k-1} + oB u_{k-1} + L y_k in the loop's order (state:
    # the prediction s_k = oA x_{k-1} + oB u_{k-1}), tau_hat = -J f_hat (y'' = f + u/J, b = 0)
    oA, oB, L = adrc.oA, adrc.oB[:, 0], adrc.L[:, 0]
    c = np.array([0.0, 0.0, -J])
    sys = control.ss(oA, np.column_stack([oA @ L, oB]), c[None, :], [[c @ L, 0.0]], TS)
    return adrc, sys


def test_pyadrc_eso_through_simulate():
    adrc, sys = _pyadrc_observer()
    nominal = ServoModel(J)
    observer = LinearObserver.from_statespace(sys, measures=("theta",),
                                              model=nominal.discretize(TS))  # fmt: skip
    loop = ServoLoop(plant=ServoModel(1.2 * J, 1e-5), nominal=nominal, Ts=TS,
                     controller=PD(200.0, 30.0), observer=observer)  # fmt: skip
    result = simulate(loop, reference=Sine(0.2, 2.0), duration=0.5,
                      disturbance=Step(0.2, 2e-3))  # fmt: skip
    # bit for bit: the runtime observer stepped on the recorded measurement and torque
    runtime = Observer(observer)
    mine = []
    for theta, u in zip(result.theta_measured.tolist(), result.u.tolist(), strict=True):
        mine.append(runtime.estimate(theta))
        runtime.update(theta, u)
    np.testing.assert_array_equal(result.tau_hat, mine)
    # pyadrc's own recursion on the same signals (it takes u_{k-1}): the same estimate to
    # round-off (its sums are associated differently)
    theirs, u_prev = [], 0.0
    for theta, u in zip(result.theta_measured.tolist(), result.u.tolist(), strict=True):
        adrc._update_eso(theta, u_prev)
        theirs.append(-J * adrc.eso_states[2, 0])
        u_prev = u
    scale = np.max(np.abs(theirs))
    np.testing.assert_allclose(result.tau_hat, theirs, rtol=0, atol=1e-9 * scale)


def test_place_design_from_python_control():
    """A predictive estimator of [theta, omega, tau] placed with control.place."""
    A = np.zeros((3, 3))
    A[:2, :2], A[:2, 2], A[2, 2] = MODEL.A, -MODEL.D, 1.0
    Bu = np.append(MODEL.B, 0.0)
    C = np.array([[1.0, 0.0, 0.0]])
    poles = np.exp(-TS * np.array([150.0, 200.0, 250.0]))
    L = control.place(A.T, C.T, poles).T
    F = A - L @ C
    sys = control.ss(F, np.column_stack([L, Bu]), [[0, 0, 1.0], [0, 1.0, 0]], np.zeros((2, 2)),
                     TS, inputs=["theta", "u"], outputs=["tau_hat", "omega_hat"])  # fmt: skip
    observer = LinearObserver.from_statespace(sys, model=MODEL)
    assert observer.measures == ("theta",)
    np.testing.assert_allclose(observer.N, np.eye(3), atol=1e-9)  # converged: the true state
    np.testing.assert_allclose(np.sort(np.linalg.eigvals(observer.F).real), np.sort(poles))
    # holding still against 0.02 N m: the estimate converges to it, from the labelled ss too
    theta, u = np.zeros(400), np.full(400, 0.02)
    for source in (observer, sys):
        result = estimate_disturbance(source, theta=theta, u=u)
        assert result.tau_hat[-1] == pytest.approx(0.02, rel=1e-9)
