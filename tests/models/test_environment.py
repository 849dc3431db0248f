"""The contact environment (issue 21 section 1): a unilateral spring-damper on the rigid servo
and on the load of a two-mass drive, integrated inside the sub-steps, with ground truth."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg

from hpdob import (
    PD,
    Environment,
    ParameterTypeError,
    ParameterValueError,
    ServoLoop,
    ServoModel,
    TwoMassServo,
    simulate,
    sweep,
)
from hpdob.simulation import load_scenario

J, B, TS = 3.06e-4, 5e-5, 1e-3  # the paper's motor (Table I) and sampling period


def _zero(t):
    return 0 * t, 0 * t, 0 * t


def _open_loop(plant):
    """No feedback at all: the controller commands 0, so only the disturbance drives the axis."""
    return ServoLoop(plant=plant, nominal=ServoModel(J, B), Ts=TS,
                     controller=PD(0.0, 0.0, feedforward=False))  # fmt: skip


def _push(torque):
    """An external torque ``-torque``: eq. (1) subtracts tau_ext, so this pushes with +torque."""
    return lambda t: np.full_like(t, -torque)


def test_torque_is_unilateral():
    wall = Environment(10.0, damping=0.5, position=0.1)
    theta = np.array([0.05, 0.1, 0.11, 0.11, 0.11])
    omega = np.array([1.0, 1.0, 0.0, -0.1, -1.0])
    # k(th - th_e) + c om: out of contact; on the surface (not beyond); pushing; pushing;
    # the sum pulls (0.1 - 0.5 < 0): released, not sticky
    expected = [0.0, 0.0, 0.1, 0.1 - 0.05, 0.0]
    np.testing.assert_allclose(wall.torque(theta, omega), expected, rtol=0, atol=1e-15)


def test_bad_inputs_name_the_parameter():
    with pytest.raises(ParameterValueError, match=r"^stiffness must be a positive .*-1\.0"):
        Environment(-1.0)
    with pytest.raises(ParameterValueError, match=r"^damping must be a non-negative"):
        Environment(1.0, damping=-0.1)
    with pytest.raises(ParameterTypeError, match=r"^environment must be an Environment"):
        ServoModel(J, environment="wall")
    plant = ServoModel(J)
    # a sweep path needs a base plant that has an environment; refused before any run
    base = {"loop": _open_loop(plant), "reference": _zero, "duration": 0.01}
    with pytest.raises(ParameterValueError, match=r"plant.environment.stiffness.*no environment"):
        sweep(base, grid={"plant.environment.stiffness": [1.0, 2.0]})


def test_plant_that_cannot_carry_one():
    mujoco = pytest.importorskip("mujoco")  # noqa: F841 -- MujocoServo needs it
    from hpdob import MujocoServo

    message = r"^environment: a MujocoServo cannot carry an Environment, got Environment; give"
    with pytest.raises(ParameterTypeError, match=message):
        MujocoServo(J=J, b=B).replace(environment=Environment(10.0))
    with pytest.raises(ParameterTypeError, match=message):  # was a plain "unexpected keyword"
        MujocoServo(J=J, b=B, environment=Environment(10.0))


@pytest.mark.parametrize("k_e", [10.0, 0.1])
def test_static_deflection_rigid(k_e):
    """Analytic: a constant torque tau into the wall settles at theta_e + tau/k_e."""
    tau, theta_e = 0.05, 0.01
    plant = ServoModel(J, B, environment=Environment(k_e, damping=0.02, position=theta_e))
    duration = 1.0 if k_e > 1 else 8.0
    result = simulate(_open_loop(plant), reference=_zero, disturbance=_push(tau),
                      duration=duration)  # fmt: skip
    assert result.theta[-1] == pytest.approx(theta_e + tau / k_e, rel=1e-6)
    assert result.tau_contact[-1] == pytest.approx(tau, rel=1e-6)
    assert result.in_contact[-1] == 1.0 and result.in_contact[0] == 0.0


def test_static_deflection_two_mass_load():
    """The wall is on the load: the load settles at theta_e + tau/k_e, the motor with it."""
    tau, theta_e, k_e = 0.05, 0.01, 10.0
    plant = TwoMassServo(J_motor=J, J_load=J, stiffness=20.0, damping=0.01, b_motor=B, b_load=B,
                         environment=Environment(k_e, damping=0.02, position=theta_e))  # fmt: skip
    result = simulate(_open_loop(plant), reference=_zero, disturbance=_push(tau), duration=2.0)
    assert result.theta_load[-1] == pytest.approx(theta_e + tau / k_e, rel=1e-6)
    assert result.theta[-1] == pytest.approx(theta_e + tau / k_e, rel=1e-6)  # spring relaxed
    assert result.tau_contact[-1] == pytest.approx(tau, rel=1e-6)


def test_linear_case_is_the_exact_zoh_of_plant_and_spring():
    """Kept in contact all run, the wall is a linear spring-damper: the simulation is the exact
    ZOH of J theta'' = -b omega - k_e (theta - theta_e) - c_e omega + tau (scipy expm)."""
    k_e, c_e, theta_e, tau = 10.0, 0.01, 0.01, 0.05
    plant = ServoModel(J, B, environment=Environment(k_e, damping=c_e, position=theta_e))
    x0 = (0.018, 0.0)  # oscillates in [0.012, 0.018] about 0.015: never leaves the wall
    result = simulate(_open_loop(plant), reference=_zero, disturbance=_push(tau), duration=0.2,
                      x0=x0)  # fmt: skip
    assert result.in_contact.all()
    M = np.zeros((3, 3))
    M[0, 1] = 1.0
    M[1, 0], M[1, 1] = -k_e / J, -(B + c_e) / J
    M[1, 2] = (tau + k_e * theta_e) / J  # the constant input, as a third state equal to 1
    step = scipy.linalg.expm(M * TS)
    x = np.array([*x0, 1.0])
    exact = []
    for _ in range(len(result.t)):
        exact.append(x[0])
        x = step @ x
    # midpoint sub-steps (h = Ts/8, w_n h = 0.023): second order, error << the 3e-3 rad swing
    np.testing.assert_allclose(result.theta, exact, rtol=0, atol=2e-7)
    np.testing.assert_allclose(result.tau_contact, k_e * (np.array(exact) - theta_e) + c_e
                               * result.omega, rtol=0, atol=5e-6)  # fmt: skip


#: Stated tolerance: halving the default sub-step (8 -> 16 per sample) changes the contact
#: torque at every sample by less than 1 % of its peak, impacts included.
SUBSTEP_TOLERANCE = 0.01


@pytest.mark.parametrize("k_e", [10.0, 0.1])
def test_contact_torque_converges_in_the_substep(k_e):
    """An impact at speed (onset inside a sub-step) under PD control, then release and re-contact
    (the wall at 0.5 rad, the reference 0.6 rad then back to 0)."""
    wall = Environment(k_e, damping=0.01, position=0.5)
    loop = ServoLoop(plant=ServoModel(J, B, coulomb=0.01, environment=wall),
                     nominal=ServoModel(J, B), Ts=TS, controller=PD(400.0, 40.0))  # fmt: skip

    def reference(t):
        r = np.where((t > 0.01) & (t < 0.3), 0.6, 0.0)
        return r, 0 * t, 0 * t

    runs = {S: simulate(loop, reference=reference, duration=0.5, substeps=S) for S in (8, 16, 32)}
    peak = np.max(runs[32].tau_contact)
    assert peak > 1e-3 and runs[32].in_contact.any() and not runs[32].in_contact[-1]
    change = {S: np.max(np.abs(runs[S].tau_contact - runs[2 * S].tau_contact)) for S in (8, 16)}
    assert change[8] < SUBSTEP_TOLERANCE * peak
    assert change[16] < change[8]  # converging


@pytest.mark.parametrize("kind", ["rigid", "two-mass"])
def test_default_substeps_follow_the_wall_stiffness(kind):
    """At 1000 N m/rad (contact resonance sqrt(k_e/J) = 1808 rad/s) 8 sub-steps changed the
    contact torque by 2.4 % (rigid) / 4.7 % (two-mass) when halved; the default now follows
    the stiffness (h sqrt(k_e/J) <= 0.06, 32 per sample) and halving it changes < 1 %."""
    wall = Environment(1000.0, damping=0.01, position=0.5)
    if kind == "rigid":
        plant = ServoModel(J, B, coulomb=0.01, environment=wall)
    else:
        plant = TwoMassServo(J_motor=J, J_load=J, stiffness=20.0, damping=0.01, b_motor=B,
                             b_load=B, environment=wall)  # fmt: skip
    S = plant.default_substeps(TS)
    assert S == 32 and TS * np.sqrt(1000.0 / J) <= S * 0.06
    assert plant.replace(environment=None).default_substeps(TS) == 8  # free axis unchanged
    loop = ServoLoop(plant=plant, nominal=ServoModel(J, B), Ts=TS, controller=PD(400.0, 40.0))

    def reference(t):
        r = np.where((t > 0.01) & (t < 0.3), 0.6, 0.0)
        return r, 0 * t, 0 * t

    default = simulate(loop, reference=reference, duration=0.5)
    halved = simulate(loop, reference=reference, duration=0.5, substeps=2 * S)
    peak = np.max(halved.tau_contact)
    assert peak > 1e-2 and halved.in_contact.any()
    assert np.max(np.abs(default.tau_contact - halved.tau_contact)) < SUBSTEP_TOLERANCE * peak


def test_too_stiff_a_wall_is_refused():
    plant = ServoModel(J, B, environment=Environment(1e30))
    with pytest.raises(ParameterValueError, match=r"^environment stiffness is too stiff"):
        plant.default_substeps(TS)


def test_toml_and_sweep(tmp_path):
    text = """
Ts = 0.001
duration = 0.5
[plant]
J = 3.06e-4
b = 5e-5
[plant.environment]
stiffness = 10.0
damping = 0.02
position = 0.01
[nominal]
J = 3.06e-4
b = 5e-5
[controller]
kp = 0.0
kd = 0.0
feedforward = false
[[reference]]
type = "constant"
value = 0.0
[[disturbance]]
type = "constant"
value = -0.05
"""
    path = tmp_path / "wall.toml"
    path.write_text(text)
    scenario = load_scenario(path)
    assert scenario.loop.plant.environment == Environment(10.0, damping=0.02, position=0.01)
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace("stiffness = 10.0", "stiffness = -10.0"))
    with pytest.raises(ParameterValueError, match=r"^plant\.environment\.stiffness must be"):
        load_scenario(bad)
    loop = _open_loop(scenario.loop.plant)
    base = {"loop": loop, "reference": _zero, "disturbance": _push(0.05), "duration": 1.0}
    table = sweep(base, grid={"plant.environment.stiffness": [10.0, 5.0]})
    assert len(table) == 2
    for k_e in (10.0, 5.0):
        direct = simulate(loop.replace(plant=scenario.loop.plant.replace(
            environment=Environment(k_e, damping=0.02, position=0.01))), reference=_zero,
            disturbance=_push(0.05), duration=1.0)  # fmt: skip
        assert direct.theta[-1] == pytest.approx(0.01 + 0.05 / k_e, rel=1e-6)
