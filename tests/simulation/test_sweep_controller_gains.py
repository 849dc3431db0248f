"""The force, impedance and position-force controllers' parameters as sweep paths (issue 21):
``controller.kf`` and the others, each row the run ``hpdob simulate`` gives with that value in
the scenario file's ``[controller]`` table; a bad value is that row's error, a path the base's
controller does not have is refused up front naming the ones it has."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from hpdob import simulate, sweep
from hpdob._validation import ParameterValueError
from hpdob.cli import main
from hpdob.controllers import CONTROLLER_TYPES
from hpdob.simulation import load_scenario, read_toml, scenario_from_dict
from hpdob.simulation._force_run import force_run_metrics
from hpdob.simulation._sweep_spec import sweep_paths

ROOT = Path(__file__).resolve().parents[2]
FORCE = ROOT / "examples" / "force_step_stiff_wall.toml"
IMPEDANCE = ROOT / "examples" / "impedance_soft_wall.toml"
SWITCH = ROOT / "examples" / "position_force_switch.toml"


def _rms(x):
    return float(np.sqrt(np.mean(np.square(x))))


def _single(path, **controller):
    """The scenario file's run with ``[controller]`` entries replaced, as hpdob simulate runs
    it (the controller built by its constructor from the table, not by the sweep)."""
    data = read_toml(path)
    data["controller"] = {**data["controller"], **controller}
    return simulate(**scenario_from_dict(data))


def _assert_row_is_run(row, result, controller):
    expected = {**result.metrics(), **force_run_metrics(result, controller)}
    for name, value in expected.items():
        if name.startswith("rms_position") and math.isnan(row[name]):
            continue  # NaN for a force reference (test_sweep_force)
        assert row[name] == value, name  # the same loop, the same floats
    assert bool(row["stable"]) and not row["error"]


@pytest.mark.parametrize(
    ("path", "key", "values"),
    [
        (FORCE, "kf", [500.0, 1000.0, 2000.0]),
        (FORCE, "kv", [0.0, 40.0]),
        (SWITCH, "threshold", [0.01, 0.02]),
        (SWITCH, "tau_ref", [0.03, 0.05]),
    ],
)
def test_force_controller_rows_are_single_runs(path, key, values):
    rows = sweep(load_scenario(path), grid={f"controller.{key}": values}, progress=False)
    assert list(rows[f"controller.{key}"]) == values
    for value, (_, row) in zip(values, rows.iterrows(), strict=True):
        result = _single(path, **{key: value})
        spec = CONTROLLER_TYPES[read_toml(path)["controller"]["type"]]
        controller = dataclasses.replace(load_scenario(path).loop.controller, **{key: value})
        assert isinstance(controller, spec)
        _assert_row_is_run(row, result, controller)
        # and from the traces, not through the library's metric functions
        assert row["force_rms_reaction_error"] == pytest.approx(
            _rms(result.tau_reac - result.tau_contact), rel=1e-12)  # fmt: skip
    # the value reaches the loop: every row differs from the others
    errors = rows["force_rms_reaction_error"].to_numpy()
    assert len(set(errors.tolist())) == len(values)


def test_impedance_gains_are_sweepable():
    base = load_scenario(IMPEDANCE)
    values = [0.05, 0.1]
    rows = sweep(base, grid={"controller.K_d": values, "controller.D_d": [0.01]}, progress=False)
    for value, (_, row) in zip(values, rows.iterrows(), strict=True):
        result = _single(IMPEDANCE, K_d=value, D_d=0.01)
        controller = dataclasses.replace(base.loop.controller, K_d=value, D_d=0.01)
        _assert_row_is_run(row, result, controller)
        assert row["max_abs_position_error"] == np.max(np.abs(result.theta - result.r))
    assert rows["rms_estimation_error"].nunique() == len(values)
    rows = sweep(base, grid={"controller.M_d": [2e-4, 4e-4]}, progress=False)
    for value, (_, row) in zip([2e-4, 4e-4], rows.iterrows(), strict=True):
        controller = dataclasses.replace(base.loop.controller, M_d=value)
        _assert_row_is_run(row, _single(IMPEDANCE, M_d=value), controller)
    assert rows["rms_estimation_error"].nunique() == 2


def test_a_bad_gain_is_its_rows_error_and_the_others_run():
    rows = sweep(load_scenario(FORCE), grid={"controller.kf": [1000.0, -1.0]}, progress=False)
    good, bad = rows.iloc[0], rows.iloc[1]
    assert bool(good["stable"]) and not good["error"]
    assert not bool(bad["stable"])
    assert "kf" in bad["error"] and "-1" in bad["error"] and "positive" in bad["error"]
    assert math.isnan(bad["force_rms_reaction_error"])


def test_a_gain_the_controller_does_not_have_is_refused_naming_its_gains():
    force = load_scenario(FORCE)
    with pytest.raises(ParameterValueError, match=r"'controller\.kp'.*ForceControl has no "
                       r"parameter 'kp' \(it has kf, kv\)"):  # fmt: skip
        sweep(force, grid={"controller.kp": [1.0]}, progress=False)
    with pytest.raises(ParameterValueError, match=r"ImpedanceControl has no parameter 'kf' "
                       r"\(it has D_d, K_d, M_d\)"):  # fmt: skip
        sweep(load_scenario(IMPEDANCE), grid={"controller.kf": [1.0]}, progress=False)
    # a controller parameter no controller has: not a sweep path, the valid ones listed
    with pytest.raises(ParameterValueError, match=r"'controller\.kx' is not a sweep parameter"
                       r".*controller\.kf, controller\.kv, controller\.M_d"):  # fmt: skip
        sweep(force, grid={"controller.kx": [1.0]}, progress=False)


def test_every_numeric_parameter_of_every_controller_type_is_a_sweep_path():
    paths = set(sweep_paths())
    for kind, spec in CONTROLLER_TYPES.items():
        for field in dataclasses.fields(spec):
            if not field.init or field.name == "_" or field.name in ("feedforward", "velocity"):
                continue  # a flag and a name: not a number a grid holds
            assert f"controller.{field.name}" in paths, (kind, field.name)


def test_hpdob_sweep_on_a_toml_force_scenario(tmp_path, capsys):
    spec = tmp_path / "force_kf.toml"
    spec.write_text(FORCE.read_text() + '\n[sweep]\ngrid = { "controller.kf" = [500.0, 2000.0] }\n')
    out = tmp_path / "rows.csv"
    assert main(["sweep", str(spec), "--out", str(out), "--workers", "1", "--no-progress"]) == 0
    rows = pd.read_csv(out)
    assert list(rows["controller.kf"]) == [500.0, 2000.0]
    for kf, (_, row) in zip([500.0, 2000.0], rows.iterrows(), strict=True):
        result = _single(FORCE, kf=kf)
        assert row["force_rms_force_error"] == pytest.approx(
            _rms(result.tau_contact - result.r), rel=1e-12)  # fmt: skip
    bad = tmp_path / "bad.toml"
    bad.write_text(FORCE.read_text() + '\n[sweep]\ngrid = { "controller.K_d" = [1.0] }\n')
    assert main(["sweep", str(bad), "--out", str(tmp_path / "b.csv"), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "ForceControl has no parameter 'K_d' (it has kf, kv)" in err[0]
