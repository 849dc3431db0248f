"""A sweep of a scenario whose reaction-torque observer's friction model is the plant's
(``[reaction_observer] friction = "plant"``, issue 21): each row subtracts that row's plant's
friction, as ``hpdob simulate`` of the file with the value written into ``[plant]`` does; a
friction model given as numbers stays fixed while the plant varies.

The expected rows are single runs of scenario files edited by hand (``read_toml``, the value
put into the table, ``simulate(**scenario_from_dict(...))``), not the sweep's own loops."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from hpdob import simulate, sweep
from hpdob._validation import ParameterValueError
from hpdob.cli import main
from hpdob.simulation import load_scenario, load_sweep, read_toml, scenario_from_dict

ROOT = Path(__file__).resolve().parents[2]
FORCE = ROOT / "examples" / "force_step_stiff_wall.toml"
# the example at half its duration (the step at 0.1 s, contact from ~0.1 s: 0.4 s of force
# control): friction = "plant" (the plant's b = 5e-5, coulomb = 0.01, coulomb_velocity = 0.01)
FOLLOWS = FORCE.read_text().replace("duration = 1.0 ", "duration = 0.5 ")
# the same friction model as numbers (b_n = 0: viscous = b; coulomb_velocity at its default,
# the plant's 0.01)
FIXED = FOLLOWS.replace('friction = "plant"', "viscous = 5e-5\ncoulomb = 0.01")
PLANT_CASES = [("b", [5e-5, 1.5e-4]), ("coulomb", [0.005, 0.02]),
               ("coulomb_velocity", [0.005, 0.02])]  # fmt: skip


def _rms(x):
    return float(np.sqrt(np.mean(np.square(x))))


@pytest.fixture
def files(tmp_path):
    assert FORCE.read_text() != FOLLOWS and 'friction = "plant"' not in FIXED
    paths = {"follows": tmp_path / "follows.toml", "fixed": tmp_path / "fixed.toml"}
    paths["follows"].write_text(FOLLOWS)
    paths["fixed"].write_text(FIXED)
    return paths


def _single(path, **tables):
    """The run of the scenario file ``path`` with ``tables`` ({"plant": {"coulomb": 0.02}},
    ...) written into it, as ``hpdob simulate`` runs it."""
    data = read_toml(path)
    for name, values in tables.items():
        data[name] = {**data[name], **values}
    return simulate(**scenario_from_dict(data))


def _assert_row_is(row, result):
    # the same loop: the same floats (rms_estimation_error reads the whole closed loop, which
    # the force controller closes on tau_reac), and the force columns from the traces
    assert bool(row["stable"]) and row["error"] == "", row["error"]
    assert row["rms_estimation_error"] == result.metrics()["rms_estimation_error"]
    assert row["force_rms_reaction_error"] == pytest.approx(
        _rms(result.tau_reac - result.tau_contact), rel=1e-12)  # fmt: skip
    assert row["force_rms_force_error"] == pytest.approx(
        _rms(result.tau_contact - result.r), rel=1e-12)  # fmt: skip


@pytest.mark.parametrize(("name", "values"), PLANT_CASES, ids=[c[0] for c in PLANT_CASES])
def test_each_row_subtracts_its_plants_friction(files, name, values):
    follows = sweep(load_scenario(files["follows"]), grid={f"plant.{name}": values},
                    progress=False)  # fmt: skip
    fixed = sweep(load_scenario(files["fixed"]), grid={f"plant.{name}": values}, progress=False)
    for value, (_, a), (_, b) in zip(values, follows.iterrows(), fixed.iterrows(), strict=True):
        _assert_row_is(a, _single(files["follows"], plant={name: value}))
        _assert_row_is(b, _single(files["fixed"], plant={name: value}))
        # independently: "follows" is the fixed numbers written as the row's plant's
        known = {"b": "viscous"}.get(name, name)
        by_hand = _single(files["fixed"], plant={name: value}, reaction_observer={known: value})
        assert a["rms_estimation_error"] == by_hand.metrics()["rms_estimation_error"]
    # the plant's friction reached the RTOB: the rows differ, and at a value other than the
    # base's the two files give other loops
    assert follows["rms_estimation_error"].nunique() == len(values)
    base = {"b": 5e-5}.get(name, 0.01)
    for i, value in enumerate(values):
        same = follows["rms_estimation_error"][i] == fixed["rms_estimation_error"][i]
        assert same == (value == base), (name, value)


def test_a_redesigned_composition_follows_the_plant_too(files):
    """observer.bandwidth redesigns DOb and RTOB; the friction model still is the row's plant's
    (and on nominal.b, the viscous part b - b_n on the row's nominal model)."""
    grid = {"observer.bandwidth": [60.0, 150.0], "plant.coulomb": [0.005, 0.02]}
    rows = sweep(load_scenario(files["follows"]), grid=grid, progress=False)
    for _, row in rows.iterrows():
        result = _single(files["follows"], observer={"bandwidth": row["observer.bandwidth"]},
                         plant={"coulomb": row["plant.coulomb"]})  # fmt: skip
        _assert_row_is(row, result)
    rows = sweep(load_scenario(files["follows"]), grid={"nominal.b": [0.0, 2e-5]},
                 progress=False)  # fmt: skip
    for b_n, (_, row) in zip([0.0, 2e-5], rows.iterrows(), strict=True):
        _assert_row_is(row, _single(files["follows"], nominal={"b": b_n}))
        by_hand = _single(files["fixed"], nominal={"b": b_n},
                          reaction_observer={"viscous": 5e-5 - b_n})  # fmt: skip
        assert row["rms_estimation_error"] == by_hand.metrics()["rms_estimation_error"]
    rows = sweep(load_scenario(files["follows"]), grid={"reaction_observer.velocity_filter":
                 [50.0], "plant.coulomb": [0.02]}, progress=False)  # fmt: skip
    _assert_row_is(rows.iloc[0], _single(files["follows"], plant={"coulomb": 0.02},
                                         reaction_observer={"velocity_filter": 50.0}))  # fmt: skip


def test_a_plant_the_friction_model_cannot_take_is_that_rows_error(files):
    """plant.coulomb = 0 leaves the velocity filter nothing to filter, a nominal b_n above the
    plant's b a negative viscous part: the file with that value is refused, and the row has
    the reason; the other rows run."""
    rows = sweep(load_scenario(files["follows"]), grid={"plant.coulomb": [0.0, 0.01]},
                 progress=False)  # fmt: skip
    why = "velocity_filter = 100.0 filters the Coulomb term's velocity, but coulomb is 0"
    assert why in rows["error"][0] and not rows["stable"][0]
    assert rows["error"][1] == "" and rows["stable"][1]
    data = read_toml(files["follows"])
    data["plant"]["coulomb"] = 0.0
    with pytest.raises(ParameterValueError, match=re.escape(why)):
        scenario_from_dict(data)
    rows = sweep(load_scenario(files["follows"]), grid={"nominal.b": [1e-4]}, progress=False)
    assert rows["error"][0].startswith(
        "plant.b = 5e-05 must be at least the nominal b_n = 0.0001: the reaction-torque "
        "observer's friction model is the plant's")  # fmt: skip
    data = read_toml(files["follows"])
    data["nominal"]["b"] = 1e-4
    with pytest.raises(ParameterValueError, match=r"must be at least the nominal b_n = 0\.0001"):
        scenario_from_dict(data)


@pytest.mark.parametrize("name", ["viscous", "coulomb", "coulomb_velocity"])
def test_the_friction_numbers_of_a_plant_model_are_not_sweep_paths(files, name):
    follows = load_scenario(files["follows"])
    plant = {"viscous": "b"}.get(name, name)
    with pytest.raises(
        ParameterValueError,
        match=(
            rf"^sweep path 'reaction_observer\.{name}' does not apply to this base: its "
            rf"friction model is the plant's \(friction = 'plant'\): {name} follows "
            rf"plant\.{plant} in every row; vary that, or give the friction model as numbers"
        ),
    ):
        sweep(follows, grid={f"reaction_observer.{name}": [0.02]}, progress=False)
    # given as numbers, they are (tests/simulation/test_sweep.py varies them)
    value = {"viscous": 1e-4}.get(name, 0.02)
    rows = sweep(load_scenario(files["fixed"]), grid={f"reaction_observer.{name}": [value]},
                 progress=False)  # fmt: skip
    assert rows["error"][0] == ""


def test_hpdob_sweep_on_a_toml_follows_the_plant(files, tmp_path):
    spec = tmp_path / "coulomb.toml"
    spec.write_text(FOLLOWS + '\n[sweep]\ngrid = { "plant.coulomb" = [0.005, 0.02] }\n')
    out = tmp_path / "rows.csv"
    assert main(["sweep", str(spec), "--out", str(out), "--workers", "1", "--no-progress"]) == 0
    rows = pd.read_csv(out, keep_default_na=False)
    assert list(rows["plant.coulomb"]) == [0.005, 0.02]
    for value, (_, row) in zip([0.005, 0.02], rows.iterrows(), strict=True):
        _assert_row_is(row, _single(files["follows"], plant={"coulomb": value}))
    # the sweep file read in Python gives the same rows
    base, options = load_sweep(spec)
    again = sweep(base, **options, progress=False)
    np.testing.assert_array_equal(again["rms_estimation_error"], rows["rms_estimation_error"])
