"""MuJoCo arms: any MJCF of hinges and motors, the shipped Franka Panda, bad models refused."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from hpdob import PD, Actuator, ParameterTypeError, ParameterValueError
from hpdob.robots import (
    PANDA_READY,
    PANDA_TORQUE_LIMITS,
    ArmLoop,
    JointSines,
    MujocoArm,
    TwoLinkArm,
    panda,
    simulate_arm,
)

pytest.importorskip("mujoco")

ARM = TwoLinkArm(m=(1.3, 0.9), l=(0.5, 0.4), lc=(0.22, 0.17), I=(0.021, 0.013), J=(0.05, 0.03),
                 b=(0.1, 0.05))  # fmt: skip


def test_loop_on_mujoco_matches_the_built_in_arm():
    """The same loop on the two-link arm's MJCF in MuJoCo (RK4) and on the written-out
    dynamics (RK4): the loop's Python path and its compiled path agree."""
    mj = MujocoArm.from_xml(ARM.to_mjcf(integrator="RK4"))
    ref = JointSines(center=(0.1, -0.2), amplitude=(0.8, 0.6), frequency=(0.9, 1.2))
    results = [
        simulate_arm(
            ArmLoop(
                plant,
                1e-3,
                PD(400.0, 40.0),
                observers={"order": 1, "bandwidth": 100.0},
                nominal=ARM,
                q0=(0.1, -0.2),
            ),
            duration=0.5,
            reference=ref,
            substeps=8,
            tau0="gravity",
        )
        for plant in (ARM, mj)
    ]
    for name in ("q", "u", "tau_hat", "tau_dn"):
        a, b = getattr(results[0], name), getattr(results[1], name)
        assert np.abs(a - b).max() <= 1e-9 * np.abs(a).max(), name


def test_panda_loads_offline_with_its_published_parameters():
    arm = panda()
    assert arm.n_joints == 7 and arm.end_effector == "flange"
    assert arm.joint_names == tuple(f"joint{i}" for i in range(1, 8))
    M = arm.mass_matrix(PANDA_READY)
    assert np.allclose(M, M.T, atol=1e-12) and np.all(np.linalg.eigvalsh(M) > 0)
    _, model, _ = arm.compile()
    # the link masses of Gaz et al. (franka_ros inertial.yaml), links 0-7
    masses = [0.629769, 4.970684, 0.646926, 3.228604, 3.587895, 1.225946, 1.666555, 0.735522]
    assert np.allclose(model.body_mass[1:], masses, rtol=0, atol=1e-12)
    # Franka's DH: at q = 0 the flange is at x = 0.088, z = 0.333 + 0.316 + 0.384 - 0.107
    assert np.allclose(arm.end_effector_position(np.zeros(7)), [0.088, 0.0, 0.926], atol=1e-12)
    assert PANDA_TORQUE_LIMITS == (87.0,) * 4 + (12.0,) * 3


def test_payload_and_inertia_scale_change_the_model_as_stated():
    q = np.array(PANDA_READY)
    nominal, heavy, scaled = panda(), panda(payload=1.0), panda(inertia_scale=1.2)
    jac = nominal.jacobian(q)
    # a 1 kg point mass at the flange adds J^T (0, 0, m g) to the gravity torque
    extra = heavy.gravity_torque(q) - nominal.gravity_torque(q)
    assert np.allclose(extra, jac.T @ np.array([0.0, 0.0, 9.81]), atol=1e-9)
    assert np.allclose(scaled.mass_matrix(q), 1.2 * nominal.mass_matrix(q), rtol=1e-12, atol=0)
    assert np.allclose(scaled.gravity_torque(q), 1.2 * nominal.gravity_torque(q), rtol=1e-12)


def test_coriolis_transpose_of_a_mujoco_arm():
    arm = panda()
    rng = np.random.default_rng(4)
    q, qd = np.array(PANDA_READY) + rng.uniform(-0.3, 0.3, 7), rng.uniform(-2, 2, 7)
    h = 1e-6
    Mdot = (arm.mass_matrix(q + h * qd) - arm.mass_matrix(q - h * qd)) / (2 * h)
    total = arm.coriolis(q, qd) + arm.coriolis_transpose(q, qd)
    assert np.allclose(total, Mdot @ qd, atol=1e-6)


def test_panda_loop_runs_with_per_joint_limits():
    arm, q0 = panda(payload=1.0), np.array(PANDA_READY)
    loop = ArmLoop(arm, 1e-3, PD(400.0, 40.0), observers={"order": 0, "bandwidth": 100.0},
                   nominal=panda(), q0=q0,
                   actuator=[Actuator(torque_limit=t) for t in PANDA_TORQUE_LIMITS])  # fmt: skip
    res = simulate_arm(loop, duration=0.3, reference=JointSines(q0, 0.5, 1.4), tau0="gravity")
    assert not res.diverged
    assert np.all(np.abs(res.u) <= np.array(PANDA_TORQUE_LIMITS))
    assert np.all(np.array(res.metrics(start=0.1)["rms_position_error"]) < 0.02)


TWO = """<mujoco><worldbody><body><joint name="a" type="{kind}" axis="0 1 0"/>
<geom size="0.1" mass="1"/><body pos="0 0 -1"><joint name="b" type="hinge" axis="0 1 0"/>
<geom size="0.1" mass="1"/>{site}</body></body></worldbody>{tendon}
<actuator><motor joint="a"/>{second}</actuator></mujoco>"""
TIP = '<site name="tip"/>'
TWO_SITES = '<site name="tip"/><site name="tool"/>'
TENDON = '<tendon><fixed name="t"><joint joint="a" coef="1"/></fixed></tendon>'


def two(kind="hinge", second='<motor joint="b"/>', site=TIP, tendon=""):
    return TWO.format(kind=kind, second=second, site=site, tendon=tendon)


@pytest.mark.parametrize(
    ("xml", "message"),
    [
        (two(kind="ball"),
         "joints are all hinges (1 rotational dof each), got joint 'a', a ball joint"),
        (two(kind="slide"), "got joint 'a', a slide joint"),
        (two(second=""), "path_or_string must drive every joint by exactly one <motor>, got 0 on "
                         "joint 'b' (none); actuators: '#0 (unnamed)'"),
        (two(second='<motor joint="b"/><motor joint="b"/>'), "got 2 on joint 'b'"),
        (two(second='<position joint="b" kp="10"/>'),
         "path_or_string must drive joint 'b' by a torque source (a <motor>"),
        (two(second='<motor joint="b"/><motor name="m" tendon="t"/>', tendon=TENDON),
         "path_or_string must drive only its hinges, each by one <motor>, got actuator 'm' on a "
         "tendon transmission"),
        # the joints and actuators are checked before the site: no site, or two, or a wrong one
        # in a model that is wrong anyway reports what is wrong with the model first
        (two(kind="ball", site=""), "got joint 'a', a ball joint"),
        (two(kind="slide", site=TWO_SITES), "got joint 'a', a slide joint"),
        (two(second="", site=""), "got 0 on joint 'b'"),
        (two(second='<position joint="b" kp="10"/>', site=TWO_SITES), "by a torque source"),
        (two(site=""), "end_effector must name the end-effector site: the model has 0 sites"),
        (two(site=TWO_SITES), "the model has 2 sites ('tip', 'tool')"),
    ],
)  # fmt: skip
def test_bad_models_are_refused_with_one_line(xml, message):
    with pytest.raises(ParameterValueError) as info:
        MujocoArm.from_xml(xml)
    assert message in str(info.value)
    assert "\n" not in str(info.value)


def test_the_site_is_checked_after_the_joints():
    with pytest.raises(ParameterValueError, match="a ball joint"):
        MujocoArm.from_xml(two(kind="ball"), end_effector="hand")
    with pytest.raises(ParameterValueError, match="got 0 on joint 'b'"):
        MujocoArm.from_xml(two(second=""), end_effector="hand")
    with pytest.raises(ParameterValueError, match="end_effector must be a site of the model, "
                                                  "got 'hand'; sites: 'tip'"):  # fmt: skip
        MujocoArm.from_xml(two(), end_effector="hand")
    with pytest.raises(ParameterTypeError, match="end_effector must be a site name"):
        MujocoArm.from_xml(two(), end_effector=3)


@pytest.mark.parametrize("engine", ["built-in", "mujoco"])
def test_an_unstable_loop_stops_as_diverged(engine, tmp_path, monkeypatch):
    from hpdob import SimulationDivergedWarning

    monkeypatch.chdir(tmp_path)  # MuJoCo writes MUJOCO_LOG.TXT into the working directory
    plant = ARM if engine == "built-in" else MujocoArm.from_xml(ARM.to_mjcf())
    loop = ArmLoop(plant, 1e-3, PD(4e6, 0.0), nominal=ARM)  # far beyond the sampled loop's limit
    with pytest.warns(SimulationDivergedWarning, match="diverged at t ="):
        res = simulate_arm(loop, duration=1.0, reference=JointSines((0.0, 0.0), 0.5, 1.0))
    assert res.diverged and len(res) < 1001
    assert np.all(np.isfinite(res.u))


def test_the_panda_model_ships_its_license_and_notice():
    """Apache-2.0 section 4(d): franka_ros's NOTICE travels with the inertial parameters taken
    from it, beside the model and its license, and the wheel includes all three."""
    from importlib import resources
    from pathlib import Path

    tomllib = pytest.importorskip("tomllib" if sys.version_info >= (3, 11) else "tomli")

    data = resources.files("hpdob.robots").joinpath("data")
    notice = data.joinpath("NOTICE-franka_ros.txt").read_text()
    assert "Copyright 2017 Franka Emika GmbH" in notice and "Apache License" in notice
    assert "Apache License" in data.joinpath("LICENSE-APACHE-2.0.txt").read_text()
    assert "NOTICE-franka_ros.txt" in data.joinpath("README.md").read_text()
    pyproject = Path(__file__).resolve().parents[2] / "pyproject.toml"
    shipped = tomllib.loads(pyproject.read_text())["tool"]["setuptools"]["package-data"]
    assert {"data/panda.xml", "data/LICENSE-APACHE-2.0.txt", "data/NOTICE-franka_ros.txt"} <= set(
        shipped["hpdob.robots"]
    )


def test_panda_default_integrator_is_the_documented_euler():
    import mujoco

    _, model, _ = panda().compile()
    assert model.opt.integrator == mujoco.mjtIntegrator.mjINT_EULER
    assert '``"Euler"``' in panda.__doc__ and 'RK4"``)' not in panda.__doc__
    _, model, _ = panda(integrator="RK4").compile()
    assert model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4
