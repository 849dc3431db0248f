"""The Coulomb term's dead band in scenario files and sweeps: ``[reaction_observer]
coulomb_deadband`` as a number [rad/s] or ``"encoder"`` (the ``[sensor]``'s velocity
resolution through the term's velocity path, (1 - exp(-omega_f Ts)) q / Ts), the sweep path
``reaction_observer.coulomb_deadband``, and the scenario writer."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from hpdob import ParameterValueError, design_observer, paper, simulate, sweep
from hpdob.observers import design_reaction_observer
from hpdob.simulation import load_scenario, scenario_toml

FORCE_STEP = Path(__file__).resolve().parents[2] / "examples" / "force_step_stiff_wall.toml"
#: one count of the 16384-count encoder through the 100 rad/s filter [rad/s]
RESOLUTION = (1 - math.exp(-0.1)) * 2 * math.pi / 16384 / 1e-3


def _file(tmp_path, extra: str, *, sensor: bool = True) -> Path:
    text = FORCE_STEP.read_text().replace(
        "velocity_filter = 100.0  # rad/s: w, the measured velocity low-passed",
        f"velocity_filter = 100.0\n{extra}",
    )
    assert extra in text
    if not sensor:
        text = text.replace("[sensor]           # the paper's 16384-count encoder\n"
                            "counts_per_rev = 16384\n", "")  # fmt: skip
        assert "counts_per_rev" not in text
    path = tmp_path / "scenario.toml"
    path.write_text(text)
    return path


def _direct(loop, deadband):
    dob = design_observer(paper.NOMINAL.discretize(paper.TS), order=1, bandwidth=100.0)
    observer = design_reaction_observer(dob, friction=paper.PLANT, velocity_filter=100.0,
                                        coulomb_deadband=deadband)  # fmt: skip
    return loop.replace(observer=observer)


def test_encoder_dead_band_is_the_sensors_resolution(tmp_path):
    """``coulomb_deadband = "encoder"`` reads into (1 - e^-0.1) q / Ts and runs as the loop
    built in Python with that number, bit for bit; written back it is that number, which reads
    back into the same loop."""
    scenario = load_scenario(_file(tmp_path, 'coulomb_deadband = "encoder"'))
    design = scenario.loop.observer
    assert design.coulomb_deadband == pytest.approx(RESOLUTION, rel=1e-12)
    assert design.system.coulomb.deadband == design.coulomb_deadband
    run = {**scenario.run, "duration": 0.4}
    got = simulate(scenario.loop, **run)
    expected = simulate(_direct(scenario.loop, design.coulomb_deadband), **run)
    np.testing.assert_array_equal(got.tau_reac, expected.tau_reac)
    text = scenario_toml(scenario.loop, **scenario.run)
    assert f"coulomb_deadband = {design.coulomb_deadband!r}" in text
    path = tmp_path / "written.toml"
    path.write_text(text)
    again = load_scenario(path)
    assert again.loop.observer.coulomb_deadband == design.coulomb_deadband


def test_bad_dead_bands_in_a_scenario_are_refused_naming_the_key(tmp_path):
    with pytest.raises(ParameterValueError, match=r"^reaction_observer.coulomb_deadband = "
                       r"'encoder' needs a \[sensor\] encoder"):  # fmt: skip
        load_scenario(_file(tmp_path, 'coulomb_deadband = "encoder"', sensor=False))
    with pytest.raises(
        ParameterValueError, match=r"^reaction_observer.coulomb_deadband must be a non-negative"
    ):
        load_scenario(_file(tmp_path, "coulomb_deadband = -0.01"))
    with pytest.raises(ParameterValueError,
                       match=r"^reaction_observer.coulomb_deadband must be a non-negative dead "
                             r"band \[rad/s\] or 'encoder', got 'sensor'"):  # fmt: skip
        load_scenario(_file(tmp_path, 'coulomb_deadband = "sensor"'))


def test_sweep_over_the_dead_band(tmp_path):
    """reaction_observer.coulomb_deadband: each row is the run of the composition with that
    dead band, built by hand; 0 is the scenario without one."""
    scenario = load_scenario(FORCE_STEP)
    run = {**scenario.run, "duration": 0.6}
    run.pop("label")
    rows = sweep({"loop": scenario.loop, **run},
                 grid={"reaction_observer.coulomb_deadband": [0.0, RESOLUTION]},
                 progress=False)  # fmt: skip
    assert (rows["error"] == "").all(), rows["error"].tolist()
    values = []
    for _, row in rows.iterrows():
        d = row["reaction_observer.coulomb_deadband"]
        direct = simulate(_direct(scenario.loop, d), **run).metrics()
        assert row["rms_estimation_error"] == direct["rms_estimation_error"]
        values.append(direct["rms_estimation_error"])
    assert values[0] != values[1]  # the dead band changes the run
    assert values[0] == simulate(scenario.loop, **run).metrics()["rms_estimation_error"]
