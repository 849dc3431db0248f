"""N-joint TOML scenarios run by ``hpdob simulate`` (the shipped examples, shortened), and bad
scenarios refused with one line naming the key."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from hpdob.cli import main
from hpdob.robots import ArmLoop, load_arm_scenario, simulate_arm

pytest.importorskip("mujoco")

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def shortened(name: str, tmp_path: Path, **replace) -> Path:
    text = (EXAMPLES / name).read_text()
    text = re.sub(r"^duration = .*$", "duration = 0.3", text, flags=re.M)
    text = re.sub(r"^start = 0.5 .*$", "start = 0.1", text, flags=re.M)
    for old, new in replace.items():
        text = text.replace(old, new)
    path = tmp_path / name
    path.write_text(text)
    return path


@pytest.mark.parametrize("name", ["panda_joint_observers.toml", "two_link_observers.toml"])
def test_simulate_runs_the_arm_examples(name, tmp_path, capsys):
    path = shortened(name, tmp_path)
    out = tmp_path / "out"
    assert main(["simulate", str(path), "--out", str(out), "--no-plot"]) == 0
    label = re.search(r'^label = "(.*)"', path.read_text(), flags=re.M).group(1)
    metrics = json.loads((out / "metrics.json").read_text())[label]
    loop, run = load_arm_scenario(path)
    start = run.pop("metrics_start")
    result = simulate_arm(loop, **run)  # the same run through the library
    joints = result.joint_names
    assert isinstance(loop, ArmLoop) and list(metrics) == list(joints)
    expected = result.metrics(start=start)
    for j, joint in enumerate(joints):
        assert metrics[joint]["rms_position_error"] == expected["rms_position_error"][j]
    header = (out / f"{label}.csv").read_text().splitlines()[0].split(",")
    assert header[0] == "t" and f"tau_dn[{joints[-1]}]" in header
    assert "wrote" in capsys.readouterr().out


def test_per_joint_observer_tables(tmp_path):
    loop, _ = load_arm_scenario(shortened("two_link_observers.toml", tmp_path))
    assert [s.n_states for s in loop.systems] == [1, 2]  # DOb on joint 1, HPDOb on joint 2


BALL = """<mujoco><worldbody><body><joint name="a" type="ball"/><geom size="0.1" mass="1"/>
<site name="tip"/></body></worldbody></mujoco>"""


@pytest.mark.parametrize(
    ("replace", "message"),
    [
        ({"[[observer]]            # joint 2\norder = 1\nbandwidth = 120.0\n": ""},
         "observers must have one entry per joint (2), got 1"),
        ({"m = [1.3, 0.9]": "m = [1.3, 0.9, 1.0]"}, "m must have one entry per joint (2), got 3"),
        ({"value = [0.0, 0.5]": "value = [0.5]"}, "force.value must have 2 entries"),
        ({'type = "joint_sines"': 'type = "step"'}, 'reference.type must be "joint_sines"'),
        ({"kp = 400.0": "kp = 400.0\nki = 1.0"}, "unknown key controller.ki = 1.0"),
        ({'type = "two-link-arm"': 'type = "mujoco-arm"'}, "unknown key plant.I"),
        ({"value = [0.0, 0.5]": "value = [0.0, 0.5]\n[metrics]\nstart = 0.5"},
         "metrics.start must be in [0, duration = 0.3) s, got 0.5"),
    ],
)  # fmt: skip
def test_bad_arm_scenarios_are_refused(replace, message, tmp_path, capsys):
    (tmp_path / "ball.xml").write_text(BALL)
    path = shortened("two_link_observers.toml", tmp_path, **replace)
    assert main(["simulate", str(path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "\n" not in err
    assert not (tmp_path / "o").exists()


def test_ball_joint_model_in_a_scenario_is_refused(tmp_path, capsys):
    (tmp_path / "ball.xml").write_text(BALL)
    path = tmp_path / "ball.toml"
    text = 'Ts = 1e-3\nduration = 0.1\n[plant]\ntype = "mujoco-arm"\npath = "ball.xml"\n'
    path.write_text(text + '[controller]\nkp = 1.0\nkd = 1.0\n[reference]\ntype = "joint_sines"\n')
    assert main(["simulate", str(path), "--out", str(tmp_path / "o")]) == 2
    assert "got joint 'a', a ball joint" in capsys.readouterr().err


TWO_OBSERVERS = "[[observer]]\norder = 0\nbandwidth = 100.0\n[[observer]]\n"


@pytest.mark.parametrize(
    ("replace", "message"),
    [
        ({"torque_limit = [87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0]":
          "torque_limit = [87.0, 87.0, 87.0, 87.0, 12.0, 12.0]"},
         "actuator.torque_limit must have one entry per joint (7), got 6"),
        ({'q0 = "ready"': "q0 = [0.0, 0.0]"},
         "q0 must have one entry per joint (7), got shape (2,)"),
        ({'tau0 = "gravity"': "tau0 = [0.0, 0.0, 0.0]"},
         "tau0 must have one entry per joint (7), got 3"),
        ({"[observer]         # one observer for every joint (or [[observer]] tables, one per "
          "joint)\n": TWO_OBSERVERS},
         "observers must have one entry per joint (7), got 2"),
        ({"[sensor]           # an 18-bit encoder on every joint\n":
          "[[sensor]]\ncounts_per_rev = 4096\n[[sensor]]\n"},
         "sensor must have one table per joint (7), got 2"),
        ({"[controller]       # one PD for every joint (or [[controller]] tables, one per joint)\n"
          "kp = 400.0         # 1/s^2\nkd = 40.0          # 1/s\n":
          "[[controller]]\nkp = 400.0\nkd = 40.0\n"},
         "controller must have one table per joint (7), got 1"),
        ({"amplitude = 0.5    # rad": "amplitude = [0.5, 0.5]"},
         "amplitude must have one entry per joint (7), got shape (2,)"),
    ],
)  # fmt: skip
def test_per_joint_lists_of_the_wrong_length_in_a_panda_scenario(replace, message, tmp_path,
                                                                 capsys):  # fmt: skip
    path = shortened("panda_joint_observers.toml", tmp_path, **replace)
    assert main(["simulate", str(path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "\n" not in err
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("name", ["panda_joint_observers.toml", "two_link_observers.toml"])
def test_load_scenario_reads_the_arm_examples(name, tmp_path):
    """hpdob.simulation.load_scenario selects the arm's loop from the registered plant type:
    an ArmScenario whose run is simulate_arm's on load_arm_scenario's loop, bit for bit."""
    import numpy as np

    from hpdob.robots import ArmScenario
    from hpdob.simulation import load_scenario

    path = shortened(name, tmp_path)
    scenario = load_scenario(path)
    assert isinstance(scenario, ArmScenario) and isinstance(scenario.loop, ArmLoop)
    loop, run = load_arm_scenario(path)
    assert scenario.metrics_start == run.pop("metrics_start")
    assert scenario.run["label"] == run["label"]
    by_hand = simulate_arm(loop, **run)
    np.testing.assert_array_equal(scenario.simulate().q, by_hand.q)
    with pytest.raises(TypeError, match="not simulate"):
        dict(scenario)  # a Scenario, not keyword arguments


def test_load_arm_scenario_refuses_a_single_axis_file():
    from hpdob import ParameterValueError

    message = r"not an N-joint scenario: \[plant\] type must be one of 'two-link-arm', 'mujoco-arm'"
    with pytest.raises(ParameterValueError, match=message):
        load_arm_scenario(EXAMPLES / "canonical_hpdob.toml")
