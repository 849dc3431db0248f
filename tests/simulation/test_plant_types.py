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
    import hpdob.robots  # noqa: F401  # registers the arm types (registration from above)

    assert list(plant_types())[:3] == ["rigid", "two-mass", "mujoco"]
    assert {"two-link-arm", "mujoco-arm"} <= set(plant_types())
    assert [n for n, t in plant_types().items() if t.scenario is not None] == [
        "two-link-arm", "mujoco-arm"
    ]  # fmt: skip


def _run_python(code: str, *path) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([*map(str, path), str(ROOT / "src")])}
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                          timeout=120, check=False)  # fmt: skip


def _distribution(where: Path, name: str, entry_points: dict) -> Path:
    """An installed distribution's metadata (what ``pip install`` writes), found on sys.path."""
    info = where / f"{name}-0.1.0.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: 0.1.0\n")
    lines = [f"[{group}]\n" + "".join(f"{k} = {v}\n" for k, v in eps.items())
             for group, eps in entry_points.items()]  # fmt: skip
    (info / "entry_points.txt").write_text("\n".join(lines))
    return where


def test_an_arm_file_loads_after_import_hpdob_alone(tmp_path):
    """Issue 20: hpdob.simulation names no package above it; the arm types reach a fresh
    interpreter through the entry points pyproject.toml declares (here the metadata an install
    of this checkout writes, ahead of the shared environment's on sys.path)."""
    declared = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["entry-points"]
    assert declared["hpdob.plant_types"] == {"robots": "hpdob.robots"}
    site = _distribution(tmp_path / "site", "hpdob", declared)
    code = (
        "import sys, hpdob; from hpdob.simulation import load_scenario; "
        "assert 'hpdob.robots' not in sys.modules; "
        f"s = load_scenario({str(ROOT / 'examples' / 'two_link_observers.toml')!r}); "
        "assert 'hpdob.robots' in sys.modules; print(type(s).__name__, type(s.loop).__name__)"
    )
    done = _run_python(code, site)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.split() == ["ArmScenario", "ArmLoop"]
    assert not re.search(r"importlib\.import_module|PROVIDERS", (ROOT / "src" / "hpdob" /
                         "simulation" / "_plant_types.py").read_text())  # fmt: skip


def test_a_plugin_registers_a_plant_type_through_an_entry_point(tmp_path):
    """A package of the user's declares a PlantType in the group hpdob.plant_types."""
    site = _distribution(tmp_path / "site", "heavy_plugin",
                         {"hpdob.plant_types": {"heavy": "heavy_plugin:HEAVY"}})  # fmt: skip
    (site / "heavy_plugin.py").write_text(
        "from hpdob import ServoModel\nfrom hpdob.simulation import PlantType\n"
        "HEAVY = PlantType('heavy', lambda t, where, base: ServoModel(J=2 * t['J']))\n"
    )
    text = re.sub(r"^\[plant\].*$", '[plant]\ntype = "heavy"', CANONICAL.read_text(),
                  count=1, flags=re.M)  # fmt: skip
    (tmp_path / "heavy.toml").write_text(text)
    code = (
        "from hpdob.simulation import load_scenario; "
        f"print(load_scenario({str(tmp_path / 'heavy.toml')!r}).loop.plant.J / "
        f"load_scenario({str(CANONICAL)!r}).loop.plant.J)"
    )
    done = _run_python(code, site)
    assert done.returncode == 0, done.stderr[-2000:]
    assert float(done.stdout) == 2.0


def test_without_the_entry_points_the_message_says_to_import_hpdob_robots():
    """A source tree on PYTHONPATH whose install metadata is stale: the lookup cannot find the
    arm types, and says how to get them."""
    code = (
        "import importlib.metadata as m; m.entry_points = lambda **kw: []; "
        "from hpdob.simulation import get_plant_type\n"
        "try:\n    get_plant_type('two-link-arm')\n"
        "except ValueError as err:\n    print(err)\n"
        "import hpdob.robots\nprint(get_plant_type('two-link-arm').name)"
    )
    done = _run_python(code)
    assert done.returncode == 0, done.stderr[-2000:]
    message, name = done.stdout.strip().splitlines()
    assert message == (
        "plant.type must be one of 'rigid', 'two-mass', 'mujoco'; got 'two-link-arm' (the arm "
        "types register when hpdob.robots is imported: import hpdob.robots)"
    )
    assert name == "two-link-arm"


def test_an_unknown_type_is_refused_naming_every_registered_one():
    import hpdob.robots  # noqa: F401  # registers the arm types

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


def test_the_entry_points_are_read_once_per_process(monkeypatch):
    """Every scenario looks its plant type up; the installed distributions are scanned on the
    first lookup only (a scan costs milliseconds and leaves cyclic garbage)."""
    import importlib.metadata

    from hpdob._plugins import installed_entry_points
    from hpdob.simulation import _plant_types, plant_types

    scans = []

    def entry_points(**kwargs):
        scans.append(kwargs)
        return []

    monkeypatch.setattr(importlib.metadata, "entry_points", entry_points)
    installed_entry_points.cache_clear()
    try:
        assert plant_types() == plant_types()
    finally:  # the real entry points for the next caller
        installed_entry_points.cache_clear()
    assert scans == [{"group": _plant_types.ENTRY_POINT_GROUP}]
