"""Tests of TOML scenario files and ``hpdob simulate``."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from hpdob import ParameterValueError, ServoModel, paper, simulate
from hpdob.cli import main
from hpdob.simulation import load_scenario
from hpdob.simulation._scenario import (
    load_metric_windows,
    load_sweep,
    metric_windows,
    scenario_from_dict,
    tomllib,
)

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = sorted(  # scenario files (sweep specs, with a [sweep] table, are tested in test_sweep;
    # N-joint arm scenarios in tests/robots/test_arm_scenarios.py)
    p
    for p in (ROOT / "examples").glob("*.toml")
    if "[sweep]" not in p.read_text() and not re.search(r'type = "[a-z-]*arm"', p.read_text())
)
CANONICAL_TOML = ROOT / "examples" / "canonical_hpdob.toml"


def base():
    return tomllib.loads(CANONICAL_TOML.read_text())


def test_canonical_example_is_the_canonical_run():
    scenario = load_scenario(CANONICAL_TOML)
    from_file = simulate(scenario.loop, **scenario.run)
    built_in = paper.run("HPDOb-100")
    np.testing.assert_array_equal(from_file.theta, built_in.theta)
    np.testing.assert_array_equal(from_file.tau_hat, built_in.tau_hat)


def test_position_only_example_is_the_built_in_run():
    from_file = load_scenario(ROOT / "examples" / "virtual_experiment_position.toml").simulate()
    built_in = paper.run("virtual-experiment-position")
    np.testing.assert_array_equal(from_file.theta, built_in.theta)
    np.testing.assert_array_equal(from_file.tau_hat, built_in.tau_hat)
    np.testing.assert_array_equal(from_file.omega_hat, built_in.omega_hat)


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.name)
def test_examples_run_from_the_command_line(path, tmp_path, capsys):
    if 'type = "mujoco"' in path.read_text():
        pytest.importorskip("mujoco")  # the optional extra
    code = main(["simulate", str(path), "--out", str(tmp_path)])
    out = capsys.readouterr().out
    assert code == 0
    assert "rms_estimation_error" in out
    label = load_scenario(path).run["label"]
    assert (tmp_path / f"{label}.csv").exists()
    assert (tmp_path / f"{label}.png").stat().st_size > 10_000
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    contact = set()  # against a wall: the impact too (docs/force-control.md)
    if "[plant.environment]" in path.read_text() or re.search(r"^wall = ", path.read_text(), re.M):
        contact = {f"contact_{name}" for name in ("first_contact", "impact_peak", "overshoot",
                                                   "overshoot_ratio")}  # fmt: skip
    # a force, impedance or switching controller: the RTOB's error and, with a force reference,
    # the force error; a force controller's r is tau_ref [N m], so no position errors
    kind = re.search(r'^\[controller\][^\n]*\ntype = "([a-z-]+)"', path.read_text(), re.M)
    kind = kind.group(1) if kind else None
    # (over the whole run and, "_steady", from 0.5 s after the first contact on)
    errors = {"force_rms_reaction_error", "force_rms_force_error"}
    steady = {f"{name}_steady" for name in errors} | {"force_steady_start"}
    force = {"force": errors | steady, "position-force": errors | steady,
             "impedance": {"force_rms_reaction_error", "force_rms_reaction_error_steady",
                           "force_steady_start"}}.get(kind, set())  # fmt: skip
    position = set() if kind == "force" else {"rms_position_error_regulation",
                                              "rms_position_error_tracking"}  # fmt: skip
    assert set(metrics[label]) == {"rms_estimation_error", *position, *contact, *force}


FORCE = ROOT / "examples" / "force_step_stiff_wall.toml"


def test_force_scenario_is_the_loop_built_in_python():
    """[controller] type = "force" with [reaction_observer] friction = "plant" is the loop
    written in Python (ForceControl, reaction_torque_observer(friction=plant)), bit for bit."""
    from hpdob import Encoder, Environment, ServoLoop, ServoModel, design_observer
    from hpdob.controllers import ForceControl
    from hpdob.observers import reaction_torque_observer
    from hpdob.signals import Step

    scenario = load_scenario(FORCE)
    from_file = scenario.simulate()
    plant = ServoModel(3.06e-4, 5e-5, coulomb=0.01, coulomb_velocity=0.01,
                       environment=Environment(10.0))  # fmt: skip
    nominal = ServoModel(2.8e-4)
    dob = design_observer(nominal.discretize(1e-3), order=1, bandwidth=100.0)
    observer = reaction_torque_observer(dob, friction=plant, velocity_filter=100.0)
    loop = ServoLoop(plant=plant, nominal=nominal, Ts=1e-3, observer=observer,
                     controller=ForceControl(1000.0, kv=40.0), sensor=Encoder(16384),
                     actuator=scenario.loop.actuator)  # fmt: skip
    built = simulate(loop, reference=Step(0.1, 0.05), duration=1.0, x0=(-0.01, 0.0))
    np.testing.assert_array_equal(from_file.tau_reac, built.tau_reac)
    np.testing.assert_array_equal(from_file.tau_contact, built.tau_contact)
    assert abs(from_file.tau_contact[-1] - 0.05) < 0.01 * 0.05


def test_mujoco_wall_scenario_and_no_environment_on_mujoco():
    """[plant] type = "mujoco" with wall = 0.0: the RTOB against MuJoCo's contact torque; an
    [plant.environment] on that plant is refused in one line naming the key."""
    pytest.importorskip("mujoco")
    path = ROOT / "examples" / "mujoco_wall.toml"
    result = load_scenario(path).simulate()
    assert result.in_contact[-100:].all()
    tail = slice(-100, None)
    assert np.max(np.abs(result.tau_reac[tail] / result.tau_contact[tail] - 1.0)) < 1e-3
    data = tomllib.loads(path.read_text())
    data["plant"]["environment"] = {"stiffness": 10.0}
    with pytest.raises(ParameterValueError,
                       match=r"^plant.environment: a MuJoCo plant cannot carry an Environment; "
                             r"give it a wall the link presses \(plant.wall \[rad\] with "
                             r"plant.link_length\)$"):  # fmt: skip
        scenario_from_dict(data)


def test_force_scenarios_refuse_bad_inputs():
    data = tomllib.loads(FORCE.read_text())

    def refused(change, match, error=ParameterValueError):
        edited = json.loads(json.dumps(data))
        change(edited)
        with pytest.raises(error, match=match):
            scenario_from_dict(edited)

    refused(lambda d: d.pop("reaction_observer"),
            r"^controller.type = 'force' reads the reaction-torque estimate tau_reac: the "
            r"scenario needs an \[observer\] and a \[reaction_observer\] table$")  # fmt: skip
    refused(lambda d: d.pop("observer"), r"^reaction_observer needs an \[observer\] table")
    refused(lambda d: d["plant"]["environment"].update(stiffness=-1.0),
            r"^plant.environment.stiffness must be a positive finite contact stiffness "
            r"\[N m/rad\], got -1.0$")  # fmt: skip
    refused(
        lambda d: d["reaction_observer"].update(friction="model"),
        r"^reaction_observer.friction must be 'plant'",
    )
    # given with friction = "plant" a number would be replaced by the plant's: refused
    refused(lambda d: d["reaction_observer"].update(coulomb_velocity=0.02),
            r"^reaction_observer.coulomb_velocity = 0.02 cannot be given with friction = "
            r"'plant' \(the \[plant\] table's b, coulomb and coulomb_velocity\): change them in "
            r"\[plant\], or leave friction out and give the numbers$")  # fmt: skip
    refused(
        lambda d: d["reaction_observer"].update(viscous=1e-5),
        r"^reaction_observer.viscous = 1e-05 cannot be given with friction = 'plant'",
    )
    refused(lambda d: (d["reaction_observer"].pop("friction"),
                       d["reaction_observer"].update(coulomb=-1.0)),
            r"^reaction_observer.coulomb must be a non-negative finite Coulomb torque")  # fmt: skip
    refused(
        lambda d: d["reaction_observer"].update(order=1, bandwidth=-5.0),
        r"^reaction_observer.bandwidth must be",
    )
    refused(
        lambda d: d["reaction_observer"].update(order=1, bandwidth=50.0, poles=[0.9, 0.9]),
        r"^reaction_observer",
    )
    refused(lambda d: d["controller"].update(kf=-1.0), r"^controller.kf must be a positive")
    refused(lambda d: d["controller"].update(type="position-force", kp=1.0, kd=1.0,
                                             tau_ref=0.05),
            r"^missing required key controller.threshold")  # fmt: skip
    # friction = "plant" reads a rigid plant's model: a two-mass plant has two (docs)
    refused(lambda d: d.update(plant={"type": "two-mass", "J_motor": 2e-4, "J_load": 1e-4,
                                      "stiffness": 100.0, "environment": {"stiffness": 10.0}}),
            r"^reaction_observer.friction = 'plant' needs a rigid \[plant\] \(a ServoModel\), "
            r"got TwoMassServo$")  # fmt: skip


def edit(change):
    data = base()
    change(data)
    return data


@pytest.mark.parametrize(
    ("change", "pattern"),
    [
        (
            lambda d: d["plant"].update(J=-1.0),
            r"^plant\.J must be a positive finite inertia .*got -1.0",
        ),
        (
            lambda d: d["plant"].update(inertia=1.0),
            r"^unknown key plant\.inertia = 1.0; valid keys of plant: J, b",
        ),
        (lambda d: d["nominal"].pop("J"), r"^missing required key nominal\.J"),
        (lambda d: d["controller"].update(kd="fast"), r"^controller\.kd must be .*got 'fast'"),
        (
            lambda d: d["observer"].update(bandwidth=-5.0),
            r"^observer\.bandwidth must be a positive .*got -5.0",
        ),
        (
            lambda d: d["observer"].update(poles=[0.9, 0.9]),
            r"^observer: give exactly one of poles .* got both$",
        ),
        (lambda d: d["observer"].pop("order"), r"^missing required key observer\.order"),
        (
            lambda d: d["observer"].update(order=-2),
            r"^observer\.order must be a non-negative integer.*got -2",
        ),
        (
            lambda d: d.update(Ts=0.0),
            r"^Ts must be a positive finite sampling period \[s\], got 0.0",
        ),
        # top-level scalars are checked when the file is read, not when it is run
        (
            lambda d: d.update(duration=-1.0),
            r"^duration must be a positive finite duration \[s\], got -1.0",
        ),
        (lambda d: d.update(duration=0), r"^duration must be a positive finite .*got 0"),
        (lambda d: d.update(duration=float("nan")), r"^duration must be .*got nan"),
        (lambda d: d.update(duration="2 s"), r"^duration must be .*got '2 s' of type str"),
        (
            lambda d: d.update(substeps=0),
            r"^substeps must be a positive integer number of sub-steps per sample, got 0",
        ),
        (lambda d: d.update(substeps=2.5), r"^substeps must be a positive integer.*got 2.5"),
        (lambda d: d.update(x0=[0.1]), r"^x0 must be an initial state .*expected shape \(2,\)"),
        (lambda d: d.update(x0="zero"), r"^x0 must be an initial state .*got 'zero'"),
        (lambda d: d.update(label=3), r"^label must be a str, got 3"),
        (lambda d: d.pop("reference"), r"^missing required key reference"),
        (lambda d: d.update(colour="red"), r"^unknown key colour = 'red'"),
        (
            lambda d: d["reference"][0].update(type="sinus"),
            r"^reference\[0\]\.type must be one of .*got 'sinus'",
        ),
        (
            lambda d: d["disturbance"][1].update(frequency=0.0),
            r"^disturbance\[1\]\.frequency must be a positive .*got 0.0",
        ),
        (
            lambda d: d["disturbance"][0].update(when=1.0),
            r"^unknown key disturbance\[0\]\.when = 1.0",
        ),
        (
            lambda d: d.update(sensor={"type": "laser"}),
            r"^sensor\.type must be 'encoder' or 'ideal'.*got 'laser'",
        ),
        (
            lambda d: d.update(sensor={"counts_per_rev": 0}),
            r"^sensor\.counts_per_rev must be a positive integer.*got 0",
        ),
        (
            lambda d: d.update(actuator={"delay_samples": -1}),
            r"^actuator\.delay_samples must be .*got -1",
        ),
        (
            lambda d: d["observer"].update(poles=["0.9+x"]),
            r"^observer\.poles\[0\] must be a number .*got '0.9\+x'",
        ),
        (lambda d: d.update(plant=3.0), r"^plant must be a table, got 3.0"),
        (lambda d: d.update(metrics=[1.0, 2.0]), r"^metrics must be a table, got \[1.0, 2.0\]"),
        (
            lambda d: d.update(metrics={"settling": [0.0, 1.0]}),
            r"^unknown key metrics.settling = \[0.0, 1.0\]; valid keys of metrics: regulation, "
            r"tracking",
        ),
        (
            lambda d: d.update(metrics={"tracking": [5.0, 4.0]}),
            r"^metrics.tracking must have start < stop \[s\], got \[5.0, 4.0\]",
        ),
        (
            lambda d: d.update(metrics={"regulation": "1-4"}),
            r"^metrics.regulation must be a \(start, stop\) pair of times \[s\], got '1-4'",
        ),
    ],
)
def test_errors_name_the_key_and_value(change, pattern):
    with pytest.raises((TypeError, ValueError), match=pattern):
        scenario_from_dict(edit(change))


def test_sweep_spec_duration_is_checked_at_load(tmp_path):
    # before: accepted, and every scenario of the sweep became an invalid row at run time
    example = ROOT / "examples" / "sweep_bandwidth.toml"
    spec = tmp_path / "spec.toml"
    spec.write_text(example.read_text().replace("duration = 10.0", "duration = -10.0"))
    with pytest.raises(ValueError, match=r"^duration must be a positive finite .*got -10.0"):
        load_sweep(spec)


def test_complex_poles_as_strings():
    data = base()
    data["observer"] = {"order": 1, "poles": ["0.9+0.05j", "0.9-0.05j"]}
    obs = scenario_from_dict(data)["observer"]
    np.testing.assert_allclose(obs.poles, [0.9 + 0.05j, 0.9 - 0.05j])


def test_scenario_is_a_loop_and_run_settings_not_keywords():
    scenario = load_scenario(CANONICAL_TOML)
    assert scenario.loop.observer == {"order": 1, "bandwidth": 100.0, "gain_direction": [1.0, 1.0]}
    assert scenario.loop.design.order == 1 and scenario.run["label"] == "HPDOb-100"
    # a redesign on another nominal model follows the spec
    moved = scenario.loop.replace(nominal=ServoModel(3e-4))
    assert moved.design.model.J == 3e-4
    with pytest.raises(TypeError, match=r"simulate\(scenario\.loop, \*\*scenario\.run\)"):
        simulate(**scenario)
    with pytest.raises(TypeError, match=r"scenario\.run\['label'\]"):
        scenario["label"]


def test_bad_files(tmp_path):
    with pytest.raises(ValueError, match="cannot read scenario file"):
        load_scenario(tmp_path / "missing.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("Ts = = 1\n")
    with pytest.raises(ValueError, match="is not valid TOML"):
        load_scenario(bad)


def test_cli_error_is_one_line(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text(CANONICAL_TOML.read_text().replace("J = 3.06e-4", "J = -3.06e-4"))
    assert main(["simulate", str(bad), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert "plant.J must be a positive finite inertia [kg m^2], got -0.000306" in err


def test_metric_windows_default_to_the_canonical_ones():
    windows = metric_windows(base())
    assert windows == {"regulation": (1.2, 4.0), "tracking": (4.0, float("inf"))}
    windows = metric_windows({"metrics": {"tracking": [0.1, 0.6]}})
    assert windows == {"regulation": (1.2, 4.0), "tracking": (0.1, 0.6)}


def test_metric_windows_are_used_by_hpdob_simulate(tmp_path, capsys):
    # The example holds 2 rad after a move in 0.1-0.6 s and lasts 4 s: with the canonical
    # windows its tracking metric would be empty (NaN).
    path = ROOT / "examples" / "encoder_noise_order2.toml"
    windows = load_metric_windows(path)
    assert windows == {"regulation": (0.6, 4.0), "tracking": (0.1, 0.6)}
    assert main(["simulate", str(path), "--out", str(tmp_path), "--no-plot"]) == 0
    capsys.readouterr()
    written = json.loads((tmp_path / "metrics.json").read_text())["order2-encoder"]
    result = load_scenario(path).simulate()
    expected = result.metrics(regulation=(0.6, 4.0), tracking=(0.1, 0.6))
    assert written == pytest.approx(expected, rel=1e-12)
    assert all(np.isfinite(list(written.values())))
