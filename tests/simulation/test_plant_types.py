"""The registry of ``[plant] type`` values: load_scenario and ``hpdob simulate`` find every plant
type there (the single-axis ones of hpdob.simulation, the arms hpdob.robots registers)."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from hpdob import MujocoServo, ParameterTypeError, ParameterValueError, ServoModel, simulate
from hpdob.cli import main
from hpdob.simulation import (
    PlantType,
    get_plant_type,
    load_scenario,
    plant_types,
    register_plant_type,
    unregister_plant_type,
)
from hpdob.simulation._scenario import scenario_from_dict, tomllib

ROOT = Path(__file__).resolve().parents[2]
CANONICAL = ROOT / "examples" / "canonical_hpdob.toml"


def test_the_shipped_plant_types():
    assert list(plant_types()) == ["rigid", "two-mass", "mujoco", "two-link-arm", "mujoco-arm"]
    assert [n for n, t in plant_types().items() if t.scenario is not None] == [
        "two-link-arm", "mujoco-arm"
    ]  # fmt: skip


def test_the_arm_types_register_when_a_lookup_needs_them():
    """A fresh interpreter that never imports hpdob.robots still finds "mujoco-arm" (the lookup
    imports the providers), and importing hpdob.simulation alone does not import robots."""
    code = (
        "import sys; from hpdob.simulation import get_plant_type; "
        "assert 'hpdob.robots' not in sys.modules; "
        "print(get_plant_type('mujoco-arm').description); "
        "assert 'hpdob.robots' in sys.modules"
    )
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                          timeout=120, check=False)  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    assert "MujocoArm" in done.stdout


def test_an_unknown_type_is_refused_naming_every_registered_one():
    with pytest.raises(ParameterValueError) as info:
        get_plant_type("three-link")
    message = str(info.value)
    assert message.startswith("plant.type must be one of 'rigid', 'two-mass', 'mujoco', ")
    assert "'mujoco-arm'; got 'three-link'" in message


def test_a_registered_type_is_read_by_load_scenario(tmp_path):
    def heavy(fields, where, base):
        return ServoModel(J=2.0 * fields["J"], b=fields.get("b", 0.0))

    register_plant_type(PlantType("heavy", heavy, description="twice the inertia"))
    try:
        with pytest.raises(ParameterValueError, match="'heavy' is registered already"):
            register_plant_type(PlantType("heavy", heavy))
        text = re.sub(r"^\[plant\].*$", '[plant]\ntype = "heavy"', CANONICAL.read_text(),
                      count=1, flags=re.M)  # fmt: skip
        (tmp_path / "heavy.toml").write_text(text)
        scenario = load_scenario(tmp_path / "heavy.toml")
        canonical = load_scenario(CANONICAL).loop.plant
        doubled = scenario.loop.plant.J
        assert doubled == pytest.approx(2.0 * canonical.J, rel=1e-15)
    finally:
        unregister_plant_type("heavy")
    assert "heavy" not in plant_types()
    with pytest.raises(ParameterValueError, match="name must be a registered plant type"):
        unregister_plant_type("heavy")
    with pytest.raises(ParameterTypeError, match="plant_type must be a PlantType, got dict"):
        register_plant_type({"name": "x"})
    with pytest.raises(ParameterTypeError, match="build must be callable"):
        PlantType("x", None)


def test_an_arm_type_is_refused_by_the_single_axis_reader():
    data = tomllib.loads(CANONICAL.read_text())
    data["plant"] = {"type": "mujoco-arm", "model": "panda"}
    with pytest.raises(ParameterValueError, match="is run by its own loop, not simulate"):
        scenario_from_dict(data)


MUJOCO_SCENARIO = """label = "mujoco-servo"
Ts = 1e-3
duration = 0.2
[plant]
type = "mujoco"
J = 3.06e-4
b = 5e-5
link_mass = 0.02
link_length = 0.1
[nominal]
J = 5.06e-4
[controller]
kp = 400.0
kd = 40.0
[observer]
order = 1
bandwidth = 100.0
[[reference]]
type = "step"
time = 0.01
amplitude = 0.1
"""


def test_a_mujoco_servo_scenario(tmp_path, monkeypatch):
    """``[plant] type = "mujoco"``: a MujocoServo from the table, the same run as built in
    code; ``hpdob simulate`` runs it."""
    pytest.importorskip("mujoco")
    monkeypatch.chdir(tmp_path)  # MuJoCo may write MUJOCO_LOG.TXT into the working directory
    path = tmp_path / "servo.toml"
    path.write_text(MUJOCO_SCENARIO)
    scenario = load_scenario(path)
    plant = scenario.loop.plant
    assert isinstance(plant, MujocoServo)
    assert plant.inertia == pytest.approx(3.06e-4 + 0.02 * 0.1**2, rel=1e-12)
    from_file = scenario.simulate()
    by_hand = simulate(scenario.loop.replace(plant=MujocoServo(3.06e-4, 5e-5, link_mass=0.02,
                                                               link_length=0.1)),
                       **scenario.run)  # fmt: skip
    np.testing.assert_array_equal(from_file.theta, by_hand.theta)
    assert main(["simulate", str(path), "--out", str(tmp_path / "out"), "--no-plot"]) == 0
    assert (tmp_path / "out" / "mujoco-servo.csv").exists()
    path.write_text(MUJOCO_SCENARIO.replace("b = 5e-5", "b = 5e-5\nstiffness = 1.0"))
    with pytest.raises(ParameterValueError, match=re.escape("unknown key plant.stiffness")):
        load_scenario(path)
