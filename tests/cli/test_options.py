"""The controller options shared by ``hpdob analyze``, ``compare`` and ``tune``: ``--controller``
is a scenario file's ``[controller] type``; each type's options (``--ki``, ``--time-constant``,
``--adrc-bandwidth``, ...) apply to it only; the paper's PD stays the default."""

from __future__ import annotations

import csv
import json
import re

import numpy as np
import pytest
import tomllib

from hpdob import ADRC, PD, PID, FilteredPD, ServoLoop, ServoModel, robust_stability_map
from hpdob.cli import main

TS = 1e-3
NOMINAL, PLANT = ServoModel(2.8e-4), ServoModel(3.06e-4, 5e-5)  # canonical


def run(capsys, *argv):
    try:
        code = main(list(argv))
    except SystemExit as exc:  # argparse's own errors (bad option syntax)
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


def radii(path) -> np.ndarray:
    with open(path, newline="") as handle:
        return np.array([float(row["spectral_radius"]) for row in csv.DictReader(handle)])


@pytest.mark.parametrize(
    ("options", "controller"),
    [
        ((), PD(50.0, 5.0)),  # the default: the paper's PD
        (("--controller", "pid", "--ki", "100"), PID(50.0, 100.0, 5.0)),
        (("--controller", "pid", "--ki", "100", "--tracking-time", "0.5", "--kp", "40"),
         PID(40.0, 100.0, 5.0, tracking_time=0.5)),
        (("--controller", "filtered-pd", "--time-constant", "0.002"),
         FilteredPD(50.0, 5.0, time_constant=2e-3)),
        (("--controller", "adrc", "--adrc-bandwidth", "40", "--adrc-observer-bandwidth", "300"),
         ADRC(40.0, observer_bandwidth=300.0)),
    ],
    ids=["pd", "pid", "pid-options", "filtered-pd", "adrc"],
)  # fmt: skip
def test_analyze_stability_maps_the_loop_of_that_controller(capsys, tmp_path, options, controller):
    argv = ["analyze", "stability", "--orders", "1", "--bandwidths", "50,200", "--values",
            "0.5,1,2", "--no-progress", "--dpi", "40", "--out", str(tmp_path)]  # fmt: skip
    code, _, err = run(capsys, *argv, *options)
    assert code == 0 and err == "", err
    loop = ServoLoop(plant=PLANT, nominal=NOMINAL, Ts=TS, controller=controller,
                     observer={"order": 1, "bandwidth": 100.0})  # fmt: skip
    expected = robust_stability_map(loop, J_ratio=[0.5, 1.0, 2.0], b=PLANT.b,
                                    bandwidth=[50.0, 200.0])  # fmt: skip
    np.testing.assert_array_equal(radii(tmp_path / "stability_J_ratio_m1.csv"),
                                  expected.spectral_radius.ravel())  # fmt: skip
    described = json.loads((tmp_path / "stability.json").read_text())["loop"]["controller"]
    assert described["type"] == (options[1] if options else "pd")


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (("--ki", "3"), "--ki applies to --controller pid only, not pd"),
        (("--controller", "pid"), r"--controller pid needs --ki \(PID integral gain ki"),
        (("--controller", "filtered-pd"), "--controller filtered-pd needs --time-constant"),
        (("--controller", "adrc"), "--controller adrc needs --adrc-bandwidth"),
        (("--controller", "adrc", "--adrc-bandwidth", "40", "--kd", "3"),
         "--kd applies to --controller pd, pid, filtered-pd, not adrc"),
        (("--controller", "pid", "--ki", "100", "--time-constant", "0.01"),
         "--time-constant applies to --controller filtered-pd only, not pid"),
        (("--controller", "pid", "--ki", "-1"), "ki must be a positive"),
        (("--controller", "lqr"), "invalid choice: 'lqr'"),
    ],
)  # fmt: skip
@pytest.mark.parametrize("command", ["analyze stability", "compare", "tune"])
def test_refused_before_any_work(capsys, tmp_path, command, options, message):
    out = tmp_path / "out"
    code, _, err = run(capsys, *command.split(), *options, "--out", str(out))
    assert code == 2 and err.count("\n") == 1, err
    assert re.search(message, err), err
    assert not out.exists()


def test_compare_runs_the_loop_of_that_controller(capsys, tmp_path):
    argv = ["compare", "--controller", "filtered-pd", "--time-constant", "0.002", "--sensor",
            "ideal", "--no-plot", "--out", str(tmp_path)]  # fmt: skip
    code, _, err = run(capsys, *argv)
    assert code == 0 and err == "", err
    rows = json.loads((tmp_path / "comparison.json").read_text())["rows"]
    # the filtered derivative changes every loop figure from the PD's default comparison
    code, _, _ = run(capsys, "compare", "--sensor", "ideal", "--no-plot", "--out",
                     str(tmp_path / "pd"))  # fmt: skip
    pd_rows = json.loads((tmp_path / "pd" / "comparison.json").read_text())["rows"]
    assert [r["observer"] for r in rows] == [r["observer"] for r in pd_rows]
    assert all(r["delay_margin"] != p["delay_margin"] for r, p in zip(rows, pd_rows, strict=True))


def test_tune_writes_the_controller_into_its_scenario(capsys, tmp_path):
    argv = ["tune", "--controller", "pid", "--ki", "100", "--families", "position",
            "--J-range", "0.9,1.1", "--counts-per-rev", "16384", "--no-plot", "--no-progress",
            "--out", str(tmp_path)]  # fmt: skip
    code, _, err = run(capsys, *argv)
    assert code == 0 and err == "", err
    table = tomllib.loads((tmp_path / "scenario.toml").read_text())["controller"]
    # the position-only observers estimate the velocity: tune's PID takes it
    assert table == {"type": "pid", "kp": 50.0, "ki": 100.0, "kd": 5.0, "velocity": "observer"}
    settings = json.loads((tmp_path / "tune.json").read_text())["settings"]["controller"]
    assert settings["type"] == "PID" and settings["ki"] == 100.0


@pytest.mark.parametrize("kind", ["force", "impedance", "position-force"])
@pytest.mark.parametrize("command", ["analyze stability", "analyze noise", "compare", "tune"])
def test_force_controllers_are_refused_not_run_as_a_pd(capsys, tmp_path, command, kind):
    # issue 20 audit: these fell through to PD(kp, kd) (compare's CSV was the PD's)
    out = tmp_path / "out"
    code, _, err = run(capsys, *command.split(), "--controller", kind, "--out", str(out))
    assert code == 2 and err.count("\n") == 1, err
    assert f"--controller: {kind!r} needs a wall and a reaction-torque observer" in err, err
    assert "it runs pd, pid, filtered-pd, adrc" in err and "hpdob simulate" in err, err
    assert not out.exists()


@pytest.mark.parametrize("command", ["analyze stability", "compare", "tune"])
def test_help_offers_only_the_controllers_the_command_runs(capsys, command):
    code, out, _ = run(capsys, *command.split(), "--help")
    assert code == 0
    assert "--controller {pd,pid,filtered-pd,adrc}" in out
    assert "impedance" not in out and "position-force" not in out


@pytest.mark.parametrize(
    ("options", "families", "text", "velocity"),
    [
        (("--controller", "pid", "--ki", "100"), "state",
         "the PID's derivative uses the measured velocity (velocity 'observer' was asked for; "
         "HPDOb (order 1) gives no velocity estimate)", "measured"),
        (("--controller", "filtered-pd", "--time-constant", "0.002"), "position",
         "the filtered PD's derivative uses the observer's velocity estimate omega_hat",
         "observer"),
    ],
    ids=["pid-state", "filtered-pd-position"],
)  # fmt: skip
def test_tune_summary_names_the_controller_and_the_velocity_it_ran(
    capsys, tmp_path, options, families, text, velocity
):
    # the audit: "the PD's derivative" for a PID, and "measured" beside tune.json's "observer"
    argv = ["tune", *options, "--families", families, "--J-range", "0.9,1.1", "--counts-per-rev",
            "16384", "--no-plot", "--no-progress", "--out", str(tmp_path)]  # fmt: skip
    code, out, err = run(capsys, *argv)
    assert code == 0 and err == "", err
    assert text in out and "the PD's derivative" not in out
    data = json.loads((tmp_path / "tune.json").read_text())
    assert data["recommendation"]["velocity"] == velocity  # the loop that was verified
    assert data["settings"]["controller"]["velocity"] == "observer"  # what was asked for
    scenario = tomllib.loads((tmp_path / "scenario.toml").read_text())["controller"]
    assert scenario.get("velocity", "measured") == velocity
