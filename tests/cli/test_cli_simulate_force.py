"""``hpdob simulate`` on a force scenario (issue 21 section 6): the figure shows the torques in
N m, not an angle, and metrics.json reports the reaction-torque estimate and the force
tracking errors, recomputed here from the CSV the same run wrote."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
import pytest
from matplotlib.figure import Figure

from hpdob._files import TEMPORARY_PREFIX
from hpdob.cli import main

ROOT = Path(__file__).resolve().parents[2]
FORCE = ROOT / "examples" / "force_step_stiff_wall.toml"
SWITCH = ROOT / "examples" / "position_force_switch.toml"


def _run(path, out, monkeypatch):
    """Run ``hpdob simulate path``; return (metrics of the label, CSV columns, saved figure)."""
    saved = []
    original = Figure.savefig

    def catch(self, fname, *args, **kwargs):
        if Path(str(fname)).name.startswith(TEMPORARY_PREFIX):
            saved.append(self)
        return original(self, fname, *args, **kwargs)

    monkeypatch.setattr(Figure, "savefig", catch)
    assert main(["simulate", str(path), "--out", str(out)]) == 0
    ((label, metrics),) = json.loads((out / "metrics.json").read_text()).items()
    with open(out / f"{label}.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    columns = {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}
    assert (out / f"{label}.png").is_file() and len(saved) == 1
    return metrics, columns, saved[0]


def _rms(x):
    return float(np.sqrt(np.mean(np.square(x))))


def test_force_scenario_reports_force_errors(tmp_path, monkeypatch):
    metrics, col, _ = _run(FORCE, tmp_path / "force", monkeypatch)
    assert metrics["force_rms_reaction_error"] == pytest.approx(
        _rms(col["tau_reac"] - col["tau_contact"]), rel=1e-9)  # fmt: skip
    # the force controller's reference r is tau_ref [N m]
    assert metrics["force_rms_force_error"] == pytest.approx(
        _rms(col["tau_contact"] - col["r"]), rel=1e-9)  # fmt: skip
    assert 0.0 < metrics["force_rms_force_error"] < 0.05  # the step is tracked, not ignored
    # theta - r (an angle minus a torque) is not reported
    assert not any(k.startswith("rms_position_error") for k in metrics)


def test_force_scenario_figure_plots_torques(tmp_path, monkeypatch):
    _, _, fig = _run(FORCE, tmp_path / "force", monkeypatch)
    top = fig.axes[0]
    assert top.get_ylabel() == "torque [N m]"
    assert fig.axes[-1].get_xlabel() == "time [s]"
    labels = top.get_legend_handles_labels()[1]
    assert any("tau_{contact}" in s for s in labels)
    assert any("tau_{reac}" in s for s in labels)
    assert any("tau_{ref}" in s for s in labels)
    assert not any("rad" in ax.get_ylabel() for ax in fig.axes)
    plt.close("all")


def test_switching_scenario_reports_force_errors_and_keeps_position(tmp_path, monkeypatch):
    metrics, col, fig = _run(SWITCH, tmp_path / "switch", monkeypatch)
    assert metrics["force_rms_reaction_error"] == pytest.approx(
        _rms(col["tau_reac"] - col["tau_contact"]), rel=1e-9)  # fmt: skip
    assert metrics["force_rms_force_error"] == pytest.approx(
        _rms(col["tau_contact"] - 0.05), rel=1e-9)  # the file's tau_ref  # fmt: skip
    assert "rms_position_error_regulation" in metrics  # r is an angle here
    assert fig.axes[0].get_ylabel() == "torque [N m]"
    plt.close("all")


def test_force_scenario_reports_steady_state_errors(tmp_path, monkeypatch):
    """``force_rms_*_steady``: over the samples from 0.5 s after the first contact (the
    default window), recomputed from the CSV; far below the whole run's (which holds the
    approach, the impact and the step)."""
    metrics, col, _ = _run(FORCE, tmp_path / "force", monkeypatch)
    first = col["t"][np.argmax(col["in_contact"] > 0.0)]
    assert metrics["force_steady_start"] == pytest.approx(first + 0.5, abs=1e-12)
    w = col["t"] >= first + 0.5
    assert metrics["force_rms_force_error_steady"] == pytest.approx(
        _rms(col["tau_contact"][w] - col["r"][w]), rel=1e-6)  # fmt: skip
    assert metrics["force_rms_reaction_error_steady"] == pytest.approx(
        _rms(col["tau_reac"][w] - col["tau_contact"][w]), rel=1e-6)  # fmt: skip
    assert metrics["force_rms_force_error_steady"] < 0.05 * metrics["force_rms_force_error"]


def test_force_window_option(tmp_path, capsys):
    out = tmp_path / "window"
    args = ["simulate", str(FORCE), "--out", str(out), "--no-plot"]
    assert main([*args, "--force-window", "0.8", "inf"]) == 0
    ((_, metrics),) = json.loads((out / "metrics.json").read_text()).items()
    assert metrics["force_steady_start"] == 0.8
    with open(out / "force-step-stiff-wall.csv", newline="") as f:
        rows = [r for r in csv.DictReader(f) if float(r["t"]) >= 0.8]
    expected = _rms([float(r["tau_contact"]) - float(r["r"]) for r in rows])
    assert metrics["force_rms_force_error_steady"] == pytest.approx(expected, rel=1e-6)
    capsys.readouterr()
    assert main([*args, "--force-window", "0.8", "0.2"]) == 2  # refused before the run
    assert "--force-window must have start < stop [s], got [0.8, 0.2]" in capsys.readouterr().err


def test_force_window_outside_the_run_or_without_a_wall_is_refused(tmp_path, capsys):
    """--force-window 5 inf on the 1 s run would give NaN metrics, and on a scenario without a
    wall it would be ignored: both are refused before the run, in one line naming the option."""
    out = tmp_path / "refused"
    assert main(["simulate", str(FORCE), "--out", str(out), "--no-plot",
                 "--force-window", "5", "inf"]) == 2  # fmt: skip
    err = capsys.readouterr().err.strip()
    assert "\n" not in err
    assert "--force-window [5, inf] s holds no sample of the run" in err
    assert "the window must overlap the run" in err
    canonical = ROOT / "examples" / "canonical_hpdob.toml"  # no wall
    assert main(["simulate", str(canonical), "--out", str(out), "--no-plot",
                 "--force-window", "0.5", "inf"]) == 2  # fmt: skip
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "--force-window:" in err and "drop --force-window" in err
    assert not out.exists()  # nothing ran, nothing written
