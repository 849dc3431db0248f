"""The closed loop on a MuJoCo-simulated servo: an independent physics check of hpdob.

Reference values are physics (inertia J + m L^2, gravity torque m g L sin(theta), the observer
error laws of docs/theory.md section 5) or hpdob's own integrator, never outputs of this code.
"""

from __future__ import annotations

import math
import pickle
import runpy
from pathlib import Path

import numpy as np
import pytest

mujoco = pytest.importorskip("mujoco")

from hpdob import (  # noqa: E402
    PD,
    Actuator,
    DisturbanceObserver,
    Encoder,
    MujocoServo,
    ServoModel,
    SimulationDivergedWarning,
    paper,
    simulate,
)
from hpdob.signals import SmoothStep, Step  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]

#: Cross-validation tolerance (relative to each metric, and to each trace's peak). MuJoCo's RK4
#: with u and tau_ext held over a step of h = Ts/8 = 125 us (the values hpdob's integrator uses)
#: solves the same linear ODE, whose only rate is b/J = 0.163 1/s: RK4's truncation error is
#: (b h/J)^5/5! ~ 3e-26 per step, so what is left is rounding. Even accumulated linearly over the
#: 80,000 steps of a 10 s run, a few ulp per step give 80,000 * 2 * 2.2e-16 ~ 4e-11 rad of theta,
#: 6e-9 of the smallest metric (7e-3 rad): 1e-8 bounds it. (Measured: <= 5e-13. A first-order
#: integrator misses by 3e-5 to 9e-4 at this step: test_first_order_integrator_misses.)
CROSS_VALIDATION_RTOL = 1e-8
TRACES = ("theta", "omega", "u", "tau_hat", "tau_dn")

#: The pendulum: a 20 g point mass on a 10 cm link on the canonical motor (m g L = 0.0196 N m,
#: of the size of the canonical disturbances; m L^2 = 2e-4 kg m^2, 65 % of the rotor's inertia).
LINK_MASS, LINK_LENGTH = 0.02, 0.1  # kg, m
G = 9.81  # m/s^2, MuJoCo's default gravity


def no_coulomb_scenario(**changes):
    """The canonical scenario with Coulomb friction removed from the plant."""
    kwargs = paper.scenario()
    kwargs["plant"] = paper.PLANT.replace(coulomb=0.0)
    kwargs.update(changes)
    return kwargs


def relative_gaps(result, reference) -> dict:
    got, want = result.metrics(), reference.metrics()
    gaps = {k: abs(got[k] - want[k]) / abs(want[k]) for k in want}
    for name in TRACES:
        a, b = getattr(result, name), getattr(reference, name)
        gaps[name] = float(np.max(np.abs(a - b)) / np.max(np.abs(b)))
    return gaps


def joint_inertia(servo: MujocoServo) -> float:
    """M[dof, dof] of the compiled model, by MuJoCo's own mass-matrix product."""
    handle = servo.open(1e-3)
    mujoco.mj_forward(handle.model, handle.data)
    unit, column = np.zeros(handle.model.nv), np.zeros(handle.model.nv)
    unit[handle.dof] = 1.0
    mujoco.mj_mulM(handle.model, handle.data, column, unit)
    return float(column[handle.dof])


# -- the built model ------------------------------------------------------------------------


def test_built_model_has_the_requested_physics():
    servo = MujocoServo(3.06e-4, 5e-5, coulomb=0.01, link_mass=LINK_MASS, link_length=LINK_LENGTH)
    assert joint_inertia(servo) == pytest.approx(3.06e-4 + LINK_MASS * LINK_LENGTH**2, rel=1e-14)
    assert servo.inertia == pytest.approx(5.06e-4, rel=1e-15)
    handle = servo.open(1e-3)
    assert handle.model.dof_damping[handle.dof] == 5e-5
    assert handle.model.dof_frictionloss[handle.dof] == 0.01
    assert mujoco.mjtIntegrator(handle.model.opt.integrator).name == "mjINT_RK4"
    angles = np.array([-2.0, -0.3, 0.0, 0.5, math.pi / 2, 2.5])
    expected = LINK_MASS * G * LINK_LENGTH * np.sin(angles)  # hanging down at theta = 0
    np.testing.assert_allclose(servo.bias_torque(angles), expected, rtol=1e-13, atol=1e-17)
    assert servo.bias_torque(math.pi / 2).shape == (1,)
    with pytest.raises(ValueError, match=r"^theta must be a 1-D array of finite joint angles"):
        servo.bias_torque([0.0, math.nan])
    with pytest.raises(TypeError, match=r"^theta must be a finite joint angle \[rad\], got 'up'"):
        servo.bias_torque("up")
    rotor = MujocoServo(3.06e-4)
    assert joint_inertia(rotor) == pytest.approx(3.06e-4, rel=1e-14)
    np.testing.assert_array_equal(rotor.bias_torque(angles), 0.0)


def test_open_times_and_pickles():
    servo = MujocoServo(3.06e-4, link_mass=0.01, link_length=0.05, timestep=1e-4)
    assert servo.open(2.5e-4).model.opt.timestep == 2.5e-4
    again = pickle.loads(pickle.dumps(servo))  # dask ships plants to workers
    assert again == servo and hash(again) == hash(servo) and repr(again) == repr(servo)
    assert servo.replace(link_mass=0.02) != servo


# -- 1. cross-validation against hpdob's own integrator ------------------------------------


@pytest.mark.parametrize("name", ["DOb-100", "HPDOb-100"])
def test_cross_validation_canonical(name):
    """No link, no Coulomb friction: MuJoCo (RK4, h = Ts/8) reproduces hpdob's integrator."""
    kwargs = no_coulomb_scenario(observer=paper.observer(name).design)
    reference = simulate(**kwargs)
    plant = kwargs["plant"]
    result = simulate(**{**kwargs, "plant": MujocoServo(plant.J, plant.b)})
    assert not result.diverged and len(result) == len(reference)
    for key, gap in relative_gaps(result, reference).items():
        assert gap <= CROSS_VALIDATION_RTOL, (key, gap)
    # the run is non-trivial: the observer rejected the load (a PD alone sits 3.6 rad off)
    assert reference.metrics()["rms_position_error_regulation"] < 0.1


def test_first_order_integrator_misses():
    """MuJoCo's (semi-implicit) Euler misses hpdob's result by far more than the tolerance, and
    by half as much when its step halves (first order): the tolerance can fail, and it is RK4
    that makes it tight."""
    kwargs = no_coulomb_scenario(observer=paper.observer("DOb-100").design, duration=5.0)
    gaps = []
    for substeps in (4, 8):
        reference = simulate(**kwargs, substeps=substeps)
        euler = MujocoServo(kwargs["plant"].J, kwargs["plant"].b, integrator="Euler")
        result = simulate(**{**kwargs, "plant": euler}, substeps=substeps)
        gaps.append(relative_gaps(result, reference)["theta"])
    assert gaps[1] > 1e3 * CROSS_VALIDATION_RTOL
    assert 1.8 < gaps[0] / gaps[1] < 2.2


def test_same_sample_loop_with_encoder_noise_delay_and_limit():
    """The Python loop around MuJoCo has the kernel's sensor, limit and delay semantics."""
    kwargs = no_coulomb_scenario(
        duration=3.0,
        sensor=Encoder(4096, noise_std=1e-4, seed=5),
        actuator=Actuator(torque_limit=0.055, delay_samples=2),
        observer=paper.observer("DOb-100").design,
        substeps=4,
    )
    reference = simulate(**kwargs)
    result = simulate(**{**kwargs, "plant": MujocoServo(kwargs["plant"].J, kwargs["plant"].b)})
    assert np.max(np.abs(result.u)) == pytest.approx(0.055)  # the limit is active
    np.testing.assert_array_equal(result.theta_measured[:50], reference.theta_measured[:50])
    for key in ("theta", "u", "tau_hat", "tau_dn", "omega_measured"):
        scale = np.max(np.abs(getattr(reference, key)))
        np.testing.assert_allclose(
            getattr(result, key), getattr(reference, key), rtol=0, atol=1e-8 * scale, err_msg=key
        )


def test_mujoco_timestep_sets_the_steps_per_sample():
    kwargs = no_coulomb_scenario(duration=0.5, observer=paper.observer("HPDOb-100").design)
    J, b = kwargs["plant"].J, kwargs["plant"].b
    own = simulate(**{**kwargs, "plant": MujocoServo(J, b, timestep=paper.TS / 16)})
    by_substeps = simulate(**{**kwargs, "plant": MujocoServo(J, b)}, substeps=16)
    np.testing.assert_array_equal(own.theta, by_substeps.theta)
    with pytest.raises(ValueError, match=r"^Ts must be an integer multiple of .* timestep 0.0003"):
        simulate(**{**kwargs, "plant": MujocoServo(J, b, timestep=3e-4)})
    with pytest.raises(ValueError, match=r"^substeps must be None or Ts/timestep = 16 .* got 8"):
        simulate(**{**kwargs, "plant": MujocoServo(J, b, timestep=paper.TS / 16)}, substeps=8)


# -- 2. pendulum: gravity as a position-dependent load -------------------------------------


@pytest.fixture(scope="module")
def pendulum_runs():
    """DOb and HPDOb at 100 rad/s on the pendulum; the nominal model is the rigid body (J + m L^2,
    b), so the nominal disturbance is exactly the gravity torque."""
    plant = MujocoServo(paper.PLANT.J, paper.PLANT.b, link_mass=LINK_MASS, link_length=LINK_LENGTH)
    nominal = ServoModel(plant.inertia, paper.PLANT.b)
    runs = {}
    for order in (0, 1):
        obs = DisturbanceObserver(nominal.discretize(paper.TS), order=order, bandwidth=100.0)
        runs[order] = simulate(
            plant=plant,
            nominal=nominal,
            Ts=paper.TS,
            duration=6.0,
            controller=paper.CONTROLLER,
            observer=obs.design,
            reference=paper.REFERENCE,
        )
    gravity = {order: plant.bias_torque(run.theta) for order, run in runs.items()}
    return plant, runs, gravity


def test_pendulum_ground_truth_is_mujocos_gravity_torque(pendulum_runs):
    plant, runs, _ = pendulum_runs
    for run in runs.values():
        assert not run.diverged
        gravity = plant.bias_torque(run.theta)
        assert np.max(np.abs(gravity)) > 0.9 * LINK_MASS * G * LINK_LENGTH  # swings to ~2 rad
        np.testing.assert_allclose(run.tau_dn, gravity, rtol=0, atol=1e-12 * np.max(gravity))


def test_pendulum_hpdob_beats_dob_at_equal_bandwidth(pendulum_runs):
    _, runs, gravity = pendulum_runs
    rms = {o: np.sqrt(np.mean((run.tau_hat - gravity[o]) ** 2)) for o, run in runs.items()}
    # the laws below predict a ratio of about Ts/(2T) + T |tau''|/|tau'| ~ 0.05-0.15 here
    # (measured 0.067)
    assert rms[1] < 0.5 * rms[0]


#: Observer lag constant T = Ts/(1 - lambda) of the 100 rad/s designs (poles at exp(-100 Ts)).
LAG = paper.TS / (1 - math.exp(-100.0 * paper.TS))


def test_pendulum_dob_lags_the_gravity_torque_as_theory_says(pendulum_runs):
    """Order 0 (docs/theory.md section 5): e_{k+1} = lambda e_k + delta tau_{k+1}, so a ramp
    leaves tau_k - tau_hat_k = tau' T. The observer's tau_k is the disturbance averaged over the
    sample, half a sample later than the torque at t_k that the ground truth takes: against it,
    tau_hat - tau = -tau' (T - Ts/2). The residual of that law must be < 15 % of the error
    (measured 6.5 %)."""
    _, runs, gravity = pendulum_runs
    rate = np.gradient(gravity[0], paper.TS)
    error = runs[0].tau_hat - gravity[0]
    residual = error + rate * (LAG - paper.TS / 2)
    assert np.sqrt(np.mean(residual**2)) < 0.15 * np.sqrt(np.mean(error**2))
    assert np.max(np.abs(error)) <= 1.1 * np.max(np.abs(rate)) * (LAG - paper.TS / 2)


def test_pendulum_hpdob_tracks_the_gravity_torque(pendulum_runs):
    """Order 1: a ramp is tracked exactly; the error is driven by the second difference,
    -tau'' T^2 in steady state, plus the half-sample offset +tau' Ts/2 of the ground truth (see
    above). The residual of that law must be < 20 % of the error (measured 9.7 %), and the error
    stays below the law's bound max|tau'| Ts/2 + max|tau''| T^2 (2.9e-5 N m; measured 2.1e-5 N m,
    0.11 % of m g L)."""
    _, runs, gravity = pendulum_runs
    rate = np.gradient(gravity[1], paper.TS)
    curvature = np.gradient(rate, paper.TS)
    error = runs[1].tau_hat - gravity[1]
    residual = error - (rate * paper.TS / 2 - curvature * LAG**2)
    assert np.sqrt(np.mean(residual**2)) < 0.2 * np.sqrt(np.mean(error**2))
    bound = np.max(np.abs(rate)) * paper.TS / 2 + np.max(np.abs(curvature)) * LAG**2
    assert np.max(np.abs(error)) <= bound
    assert np.max(np.abs(error)) <= 2e-3 * LINK_MASS * G * LINK_LENGTH


# -- 3. MuJoCo's dry friction (frictionloss) -----------------------------------------------


@pytest.mark.parametrize("name", ["DOb-100", "HPDOb-100"])
def test_frictionloss_observers_converge(name):
    """Step to 1 rad, then a 0.05 N m load step at 1.5 s, on MuJoCo's frictionloss (0.01 N m).

    Converge: after the load transient the estimation error stays below 10 % of the friction
    level (measured <= 5e-4 N m); the position error stays within 2 % of the step over the last
    second (a PD alone would sit 3.6 rad off) and does not grow (the HPDOb settles into a small
    stick-slip cycle, docs/mujoco.md)."""
    kwargs = paper.scenario()
    kwargs.update(
        plant=MujocoServo(paper.PLANT.J, paper.PLANT.b, coulomb=paper.PLANT.coulomb),
        reference=SmoothStep(0.2, 1.2, 1.0),
        disturbance=Step(1.5005, 0.05),
        duration=6.0,
        observer=paper.observer(name).design,
    )
    result = simulate(**kwargs)
    t, error, position_error = result.t, result.estimation_error, result.theta - result.r
    assert not result.diverged
    assert np.max(np.abs(error[t >= 2.5])) < 0.1 * paper.PLANT.coulomb
    last = np.max(np.abs(position_error[t >= 5.0]))
    assert last < 0.02
    assert last <= np.max(np.abs(position_error[(t >= 2.5) & (t < 3.5)]))


@pytest.mark.parametrize("name", ["DOb-100", "HPDOb-100"])
def test_frictionloss_against_tanh_model(name):
    """Canonical scenario: MuJoCo's frictionloss vs hpdob's tanh (same level 0.01 N m). They
    differ only near zero velocity, so the metrics agree within 25 % (measured <= 11 %)."""
    kwargs = paper.scenario()
    tanh = simulate(**kwargs, observer=paper.observer(name).design)
    plant = MujocoServo(paper.PLANT.J, paper.PLANT.b, coulomb=paper.PLANT.coulomb)
    friction = simulate(**{**kwargs, "plant": plant}, observer=paper.observer(name).design)
    for key, value in friction.metrics().items():
        assert abs(value / tanh.metrics()[key] - 1) < 0.25, key


# -- divergence -------------------------------------------------------------------------------


def test_mujoco_instability_ends_the_run(monkeypatch, tmp_path):
    """A torque so large that MuJoCo flags the acceleration (and would reset its state)."""
    monkeypatch.chdir(tmp_path)  # MuJoCo writes its warning to ./MUJOCO_LOG.TXT
    kwargs = no_coulomb_scenario(duration=1.0, controller=PD(1e15, 0.0), x0=(1.0, 0.0))
    kwargs["plant"] = MujocoServo(paper.PLANT.J)
    with pytest.warns(SimulationDivergedWarning, match="MuJoCo flagged it unstable"):
        result = simulate(**kwargs)
    assert result.diverged and len(result) == 1


def test_divergence_limit_ends_the_run(monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)  # in case MuJoCo logs a warning
    kwargs = no_coulomb_scenario(duration=5.0, controller=PD(5e6, 0.0), x0=(1e-3, 0.0))
    kwargs["plant"] = MujocoServo(paper.PLANT.J)
    with pytest.warns(SimulationDivergedWarning, match="diverged"):
        result = simulate(**kwargs)
    assert result.diverged and 1 < len(result) < 5000
    assert np.all(np.isfinite(result.theta))


# -- 4. wrapping a user's model, and validation ------------------------------------------------

USER_MODEL = """<mujoco model="arm">
  <compiler angle="radian" inertiafromgeom="false"/>
  <option integrator="RK4"/>
  <worldbody>
    <body name="base">
      <joint name="shoulder" type="hinge" axis="0 1 0" armature="3e-4" damping="5e-5"/>
      <inertial pos="0 0 0" mass="0.1" diaginertia="1e-6 1e-6 1e-6"/>
      <body name="slider" pos="0 0 -0.1">
        <joint name="rail" type="slide" axis="1 0 0"/>
        <inertial pos="0 0 0" mass="0.1" diaginertia="1e-6 1e-6 1e-6"/>
      </body>
    </body>
  </worldbody>
  <actuator>
    <motor name="drive" joint="shoulder" gear="{gear}"/>
    <position name="servo" joint="shoulder" kp="1"/>
    <motor name="rail_motor" joint="rail"/>
  </actuator>
</mujoco>
"""


def test_from_xml_reproduces_the_built_model(tmp_path):
    servo = MujocoServo(3.06e-4, 5e-5, link_mass=LINK_MASS, link_length=LINK_LENGTH)
    path = tmp_path / "servo.xml"
    path.write_text(servo.xml)
    wrapped = MujocoServo.from_xml(path)  # one hinge, one motor: names may be omitted
    assert (wrapped.joint, wrapped.actuator, wrapped.integrator) == ("hinge", "motor", "RK4")
    assert pytest.approx(servo.inertia, rel=1e-14) == wrapped.J  # inertia at qpos0
    assert (wrapped.b, wrapped.coulomb, wrapped.link_mass) == (5e-5, 0.0, None)
    nominal = ServoModel(servo.inertia, 5e-5)
    kwargs = {
        "nominal": nominal,
        "Ts": paper.TS,
        "duration": 1.0,
        "controller": paper.CONTROLLER,
        "reference": paper.REFERENCE,
        "observer": DisturbanceObserver(
            nominal.discretize(paper.TS), order=1, bandwidth=100.0
        ).design,
    }
    built = simulate(plant=servo, **kwargs)
    from_file = simulate(plant=wrapped, **kwargs)
    from_text = simulate(plant=MujocoServo.from_xml(servo.xml, joint="hinge"), **kwargs)
    for run in (from_file, from_text):
        np.testing.assert_array_equal(run.theta, built.theta)
        np.testing.assert_array_equal(run.tau_dn, built.tau_dn)


def test_from_xml_scales_ctrl_by_the_motor_gear():
    """u is a joint torque whatever the gear: gear 2 and gear 1 give the same run."""
    runs = []
    for gear in (1, 2):
        plant = MujocoServo.from_xml(
            USER_MODEL.format(gear=gear), joint="shoulder", actuator="drive"
        )
        runs.append(simulate(**no_coulomb_scenario(plant=plant, duration=1.5)))
    np.testing.assert_allclose(runs[1].theta, runs[0].theta, rtol=1e-12, atol=1e-15)
    assert np.max(np.abs(runs[0].theta)) > 0.01  # it moved


@pytest.mark.parametrize(
    ("kwargs", "pattern"),
    [
        ({"joint": "elbow"}, r"^joint must be the name of a hinge joint .* got 'elbow'; "
                             r"hinge joints: 'shoulder'"),
        ({"joint": "rail"}, r"^joint must be a hinge joint .* got 'rail', a slide joint; "
                            r"hinge joints: 'shoulder'"),
        ({"joint": "shoulder", "actuator": "wrist"},
         r"^actuator must be the name of an actuator .* got 'wrist'; actuators driving joint "
         r"'shoulder': 'drive', 'servo'; all actuators: 'drive', 'servo', 'rail_motor'"),
        ({"joint": "shoulder", "actuator": "rail_motor"},
         r"^actuator must drive joint 'shoulder' directly, got 'rail_motor'.*'drive', 'servo'"),
        ({"joint": "shoulder", "actuator": "servo"},
         r"^actuator must be a torque source \(a <motor>.*got 'servo' with gain type "
         r"mjGAIN_FIXED, bias type mjBIAS_AFFINE"),
        ({"joint": "shoulder"}, r"^actuator must name the motor of joint 'shoulder': 2 actuators "
                                r"drive it \('drive', 'servo'\)"),
        ({"joint": 3}, r"^joint must be a joint name \(str\), got int"),
        ({"joint": "shoulder", "actuator": "drive", "timestep": -1e-3},
         r"^timestep must be a positive finite MuJoCo time step \[s\] or None, got -0.001"),
    ],
)  # fmt: skip
def test_from_xml_names_what_is_wrong(kwargs, pattern):
    with pytest.raises((ValueError, TypeError), match=pattern):
        MujocoServo.from_xml(USER_MODEL.format(gear=1), **kwargs)


def test_from_xml_bad_sources(tmp_path):
    with pytest.raises(ValueError, match=r"^MuJoCo could not compile the MJCF XML string: .*"):
        MujocoServo.from_xml("<mujoco><worldbody><body></mujoco>")
    with pytest.raises(ValueError, match=r"^path_or_string must be .* got '.*nope.xml', which is"):
        MujocoServo.from_xml(tmp_path / "nope.xml")
    with pytest.raises(TypeError, match=r"^path_or_string must be MJCF XML text or a file path"):
        MujocoServo.from_xml(42)
    two = USER_MODEL.format(gear=1).replace('type="slide" axis="1 0 0"', 'type="hinge"')
    with pytest.raises(
        ValueError, match=r"^joint must name .* 2 hinge joints \('shoulder', 'rail'"
    ):
        MujocoServo.from_xml(two)
    empty = "<mujoco><worldbody/></mujoco>"
    with pytest.raises(ValueError, match=r"^joint must name .* 0 hinge joints \(none\)"):
        MujocoServo.from_xml(empty)


@pytest.mark.parametrize(
    ("kwargs", "exc", "pattern"),
    [
        ({"J": -1.0}, ValueError, r"^J must be a positive finite inertia \[kg m\^2\], got -1.0"),
        ({"J": "big"}, TypeError, r"^J must be a positive finite inertia .* got 'big' of type str"),
        ({"b": -5e-5}, ValueError, r"^b must be a non-negative finite viscous .* got -5e-05"),
        ({"coulomb": math.nan}, ValueError, r"^coulomb must be a non-negative .* got nan"),
        ({"link_mass": -0.1}, ValueError, r"^link_mass must be a non-negative finite mass \[kg\]"),
        ({"link_length": math.inf}, ValueError, r"^link_length must be .* \[m\], got inf"),
        ({"timestep": 0.0}, ValueError, r"^timestep must be a positive finite .* got 0.0"),
        ({"integrator": "RK45"}, ValueError,
         r"^integrator must be one of 'RK4', 'Euler', 'implicit', 'implicitfast'; got 'RK45'"),
    ],
)  # fmt: skip
def test_constructor_validation(kwargs, exc, pattern):
    arguments = {"J": 3.06e-4, **kwargs}
    with pytest.raises(exc, match=pattern):
        MujocoServo(arguments.pop("J"), **arguments)


def test_replace_and_immutability():
    servo = MujocoServo(3.06e-4, 5e-5, coulomb=0.01)
    changed = servo.replace(J=4e-4, b=0.0, link_mass=0.02, link_length=0.1)
    assert (changed.J, changed.b, changed.coulomb) == (4e-4, 0.0, 0.01)
    assert changed.inertia == pytest.approx(6e-4, rel=1e-15)
    assert servo.J == 3.06e-4  # unchanged
    with pytest.raises(
        TypeError,
        match=r"unknown parameter\(s\) \['coulomb_velocity'\]; valid: "
        r"\['J', 'b', 'coulomb', 'integrator', 'link_length'",
    ):
        servo.replace(coulomb_velocity=0.01)  # fmt: skip
    with pytest.raises(ValueError, match=r"^J must be a positive"):
        servo.replace(J=0.0)
    with pytest.raises(AttributeError, match="immutable"):
        servo.J = 1.0
    wrapped = MujocoServo.from_xml(USER_MODEL.format(gear=1), joint="shoulder", actuator="drive")
    damped = wrapped.replace(b=1e-3, coulomb=0.0, timestep=1e-4)
    assert (damped.b, damped.coulomb, damped.timestep, wrapped.b) == (1e-3, 0.0, 1e-4, 5e-5)
    assert damped.open(1e-4).model.dof_damping[0] == 1e-3
    with pytest.raises(TypeError, match=r"\['J'\]; valid: \['b', 'coulomb', 'timestep'\]"):
        wrapped.replace(J=1.0)
    assert "joint='shoulder'" in repr(damped) and "b=0.001" in repr(damped)


def test_simulate_names_both_plant_types():
    kwargs = no_coulomb_scenario(plant="motor", duration=0.1)
    with pytest.raises(
        TypeError, match=r"^plant must be a ServoModel, a TwoMassServo or a MujocoServo .*, got str"
    ):
        simulate(**kwargs)


def test_missing_mujoco_says_how_to_install(monkeypatch):
    monkeypatch.setitem(__import__("sys").modules, "mujoco", None)  # import mujoco fails
    with pytest.raises(ImportError, match=r"pip install 'hpdob\[mujoco\]'"):
        MujocoServo(3.06e-4)


def test_sweep_over_a_mujoco_plant():
    pytest.importorskip("pandas")
    from hpdob import sweep

    base = {
        **no_coulomb_scenario(duration=1.0),
        "plant": MujocoServo(paper.PLANT.J, paper.PLANT.b),
        "observer": {"order": 1, "bandwidth": 100.0},
    }
    rows = sweep(
        base,
        grid={"plant.link_mass": [0.0, 0.02], "plant.link_length": [0.1], "observer.order": [0, 1]},
        scheduler=2,
        progress=False,
    )
    assert rows["stable"].all(), rows["error"].tolist()
    direct = simulate(
        **{
            **base,
            "plant": MujocoServo(paper.PLANT.J, paper.PLANT.b, link_mass=0.02, link_length=0.1),
            "observer": DisturbanceObserver(
                base["nominal"].discretize(paper.TS), order=1, bandwidth=100.0
            ).design,
        }
    )
    row = rows[(rows["plant.link_mass"] == 0.02) & (rows["observer.order"] == 1)].iloc[0]
    assert row["rms_estimation_error"] == direct.metrics()["rms_estimation_error"]
    # a ServoModel has no link: every row would fail, so the sweep is refused up front
    with pytest.raises(ValueError, match=r"'plant.link_mass' does not apply .* J, b, coulomb"):
        sweep({**base, "plant": paper.PLANT}, grid={"plant.link_mass": [0.02]}, progress=False)


def test_example_mujoco_pendulum_writes_a_figure(tmp_path, capsys):
    example = runpy.run_path(str(ROOT / "examples" / "mujoco_pendulum.py"), run_name="example")
    out = tmp_path / "pendulum.png"
    example["main"](["--duration", "1.5", "--out", str(out)])
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and out.stat().st_size > 20_000
    printed = capsys.readouterr().out
    assert "DOb " in printed and "HPDOb " in printed and str(out) in printed
