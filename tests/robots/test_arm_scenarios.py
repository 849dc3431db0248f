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
         "observer must have one table per joint (2), got 1"),
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


NO_ACTUATOR = """<mujoco><worldbody><body><joint name="a" type="hinge"/><geom size="0.1" mass="1"/>
<site name="tip"/></body></worldbody></mujoco>"""


@pytest.mark.parametrize("table", ["plant", "nominal"])
@pytest.mark.parametrize(
    ("xml", "message"),
    [(BALL, "path must be an MJCF whose joints are all hinges (1 rotational dof each), got "
            "joint 'a', a ball joint"),
     (NO_ACTUATOR, "path must drive every joint by exactly one <motor>, got 0 on joint 'a'")],
)  # fmt: skip
def test_a_bad_mjcf_in_a_scenario_is_refused_naming_its_table(table, xml, message, tmp_path,
                                                               capsys):  # fmt: skip
    """The MJCF's refusal names the TOML key (plant.path or nominal.path), not MujocoArm's
    path_or_string."""
    (tmp_path / "bad.xml").write_text(xml)
    (tmp_path / "good.xml").write_text(ARM_XML)
    path = tmp_path / "bad.toml"
    other = "nominal" if table == "plant" else "plant"
    text = (f'Ts = 1e-3\nduration = 0.1\n[{table}]\ntype = "mujoco-arm"\npath = "bad.xml"\n'
            f'[{other}]\ntype = "mujoco-arm"\npath = "good.xml"\n')  # fmt: skip
    path.write_text(text + '[controller]\nkp = 1.0\nkd = 1.0\n[reference]\ntype = "joint_sines"\n')
    assert main(["simulate", str(path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert f"error: {table}.{message}" in err and "path_or_string" not in err and "\n" not in err


ARM_XML = """<mujoco><worldbody><body><joint name="a" type="hinge" axis="0 1 0"/>
<geom size="0.1" mass="1"/><body pos="0 0 -0.3"><joint name="b" type="hinge" axis="0 1 0"/>
<geom size="0.1" mass="1"/><site name="tip"/></body></body></worldbody>
<actuator><motor joint="a"/><motor joint="b"/></actuator></mujoco>"""

# Every key a two-joint scenario can have (a two-link plant, a MuJoCo nominal model).
FULL = {
    "label": "x", "Ts": 1e-3, "duration": 0.3, "substeps": 4, "q0": [0.0, 0.0],
    "tau0": [0.0, 0.0],
    "plant": {"type": "two-link-arm", "m": [1.3, 0.9], "l": [0.5, 0.4], "lc": [0.22, 0.17],
              "I": [0.021, 0.013], "J": [0.05, 0.03], "b": [0.1, 0.05], "gravity": 9.81},
    "nominal": {"type": "mujoco-arm", "path": "arm.xml", "payload": 0.1, "inertia_scale": 1.0,
                "integrator": "RK4", "end_effector": "tip"},
    "controller": {"type": "pd", "kp": 400.0, "kd": 40.0},
    "observer": [{"order": 0, "bandwidth": 80.0}, {"order": 1, "bandwidth": 120.0}],
    "sensor": {"counts_per_rev": 4096, "velocity": "exact", "noise_std": 0.0, "seed": 1},
    "actuator": {"torque_limit": [10.0, 10.0], "delay_samples": 0},
    "reference": {"type": "joint_sines", "amplitude": 0.5, "frequency": 1.0},
    "force": {"start": 0.1, "value": [0.0, 0.5]},
    "metrics": {"start": 0.1},
}  # fmt: skip
REQUIRED = {("Ts",), ("duration",), ("plant",), ("controller",), ("reference",),
            ("plant", "type"), ("plant", "m"), ("plant", "l"), ("plant", "lc"), ("plant", "I"),
            ("nominal", "type"), ("nominal", "path"), ("controller", "kp"), ("controller", "kd"),
            ("observer", 0, "order"), ("observer", 0, "bandwidth"), ("observer", 1, "order"),
            ("observer", 1, "bandwidth"), ("sensor", "counts_per_rev")}  # fmt: skip


def _keys(table, prefix=()):
    for key, value in table.items():
        yield (*prefix, key)
        if isinstance(value, dict):
            yield from _keys(value, (*prefix, key))
        elif isinstance(value, list) and isinstance(value[0], dict):
            for i, entry in enumerate(value):
                yield from _keys(entry, (*prefix, key, i))


KEYS = list(_keys(FULL))


def _written(key):
    """The key as the error names it: ``observer[0].order``, ``plant.m``."""
    text = str(key[0])
    for part in key[1:]:
        text += f"[{part}]" if isinstance(part, int) else f".{part}"
    return text


def _scenario(tmp_path, key, value):
    import copy

    from hpdob.robots._scenario import arm_scenario_from_dict

    (tmp_path / "arm.xml").write_text(ARM_XML)
    data = copy.deepcopy(FULL)
    parent = data
    for part in key[:-1]:
        parent = parent[part]
    if value is KeyError:
        del parent[key[-1]]
    else:
        parent[key[-1]] = value
    return arm_scenario_from_dict(data, tmp_path)


def test_the_full_scenario_is_valid(tmp_path):
    loop, run = _scenario(tmp_path, ("label",), "x")
    assert loop.n_joints == 2 and run["substeps"] == 4


@pytest.mark.parametrize("key", KEYS, ids=_written)
def test_a_missing_key_is_refused_naming_it_or_takes_its_default(key, tmp_path):
    """No missing key gives an internal error: a required one is refused with one line naming
    it (``plant.m``), an optional one takes its default."""
    from hpdob import ParameterTypeError, ParameterValueError

    if key not in REQUIRED:
        _scenario(tmp_path, key, KeyError)
        return
    with pytest.raises((ParameterTypeError, ParameterValueError)) as info:
        _scenario(tmp_path, key, KeyError)
    message = str(info.value)
    table, name = _written(key[:-1]) if len(key) > 1 else "", str(key[-1])
    assert "\n" not in message and name in message and table in message, message
    if len(key) > 1 and not isinstance(key[-2], int):
        assert _written(key) in message or f"{table} must give" in message, message


@pytest.mark.parametrize("value", ["x", True, [1.0], {}], ids=["str", "bool", "list", "table"])
@pytest.mark.parametrize("key", KEYS, ids=_written)
def test_a_wrong_type_is_refused_naming_the_key(key, value, tmp_path):
    """A wrong type anywhere is accepted (a label "x") or refused with one line naming the
    key as the file writes it (``plant.m[1]``, ``observer[0].order``, ``sensor.counts_per_rev``),
    never an internal error."""
    from hpdob import ParameterTypeError, ParameterValueError

    try:
        _scenario(tmp_path, key, value)
    except (ParameterTypeError, ParameterValueError) as err:
        message = str(err)
        assert "\n" not in message and message.startswith(
            (_written(key), f"missing required key {_written(key)}", f"unknown key {_written(key)}")
        ), message


def test_errors_inside_a_table_name_the_table(tmp_path):
    from hpdob import ParameterValueError

    cases = [
        (("plant", "m"), [1.3, -0.9], "plant.m[1] must be"),
        (("nominal", "payload"), -1.0, "nominal.payload must be a non-negative finite mass"),
        (("sensor", "counts_per_rev"), 0, "sensor.counts_per_rev must be"),
        (("actuator", "torque_limit"), [10.0, -1.0], "actuator.torque_limit[1] must be"),
        (("observer",), {"order": -1, "bandwidth": 80.0}, "observer.order must be"),
        (("observer", 1, "bandwidth"), -1.0, "observer[1].bandwidth must be"),
        (("plant",), {"type": "two-link-arm", "l": [0.5, 0.4], "lc": [0.2, 0.2],
                      "I": [0.02, 0.01]}, "missing required key plant.m"),
        (("nominal",), {"type": "mujoco-arm", "model": "panda", "end_effector": "hand"},
         "nominal.end_effector must be the Panda's site 'flange'"),
    ]  # fmt: skip
    for key, value, message in cases:
        with pytest.raises(ParameterValueError) as info:
            _scenario(tmp_path, key, value)
        assert str(info.value).startswith(message), (key, str(info.value))


TWO_OBSERVERS = "[[observer]]\norder = 0\nbandwidth = 100.0\n[[observer]]\n"


@pytest.mark.parametrize(
    ("replace", "message"),
    [
        ({"torque_limit = [87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0]":
          "torque_limit = [87.0, 87.0, 87.0, 87.0, 12.0, 12.0]"},
         "actuator.torque_limit must have one entry per joint (7), got 6"),
        ({'q0 = "ready"': "q0 = [0.0, 0.0]"},
         "q0 must have one entry per joint (7), got 2"),
        ({'tau0 = "gravity"': "tau0 = [0.0, 0.0, 0.0]"},
         "tau0 must have one entry per joint (7), got 3"),
        ({"[observer]         # one observer for every joint (or [[observer]] tables, one per "
          "joint)\n": TWO_OBSERVERS},
         "observer must have one table per joint (7), got 2"),
        ({"[sensor]           # an 18-bit encoder on every joint\n":
          "[[sensor]]\ncounts_per_rev = 4096\n[[sensor]]\n"},
         "sensor must have one table per joint (7), got 2"),
        ({"[controller]       # one PD for every joint (or [[controller]] tables, one per joint)\n"
          "kp = 400.0         # 1/s^2\nkd = 40.0          # 1/s\n":
          "[[controller]]\nkp = 400.0\nkd = 40.0\n"},
         "controller must have one table per joint (7), got 1"),
        ({"amplitude = 0.5    # rad": "amplitude = [0.5, 0.5]"},
         "reference.amplitude must have one entry per joint (7), got 2"),
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
