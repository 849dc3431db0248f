"""``hpdob analyze`` and ``hpdob tune --families`` read the family registry (issue 20 audit):
``analyze --type`` takes any registered family with its options, as ``hpdob design`` does;
``tune --families`` takes the registry's family types (and the tuner's variant names).

A family defined in the tests only, registered at run time (the DOb followed by a first-order
low-pass of its estimate, tests/low_pass_family.py), works in both with no edit under src/;
the expected values come from the library's functions on the family's own design function,
not from the command line.
"""

from __future__ import annotations

import csv
import json
import math
import re

import numpy as np
import pytest

import low_pass_family
from hpdob import (
    PD,
    Encoder,
    ServoLoop,
    ServoModel,
    design_observer,
    estimation_response,
    noise_gains,
    robust_stability_map,
)
from hpdob.cli import main
from hpdob.observers import design_eso
from low_pass_family import design_filtered

TS = 1e-3
NOMINAL, PLANT = ServoModel(2.8e-4), ServoModel(3.06e-4, 5e-5)  # canonical
MODEL = NOMINAL.discretize(TS)


registered = low_pass_family.registered  # the fixture registering FILTERED


def run(capsys, *argv):
    try:
        code = main(list(argv))
    except SystemExit as exc:
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


def rows(path) -> list[dict]:
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


def test_analyze_stability_of_the_eso_and_of_a_registered_family(capsys, tmp_path, registered):
    # the audit: "analyze stability --type eso" was "unrecognized arguments"
    common = ["analyze", "stability", "--orders", "1", "--bandwidths", "50,200", "--values",
              "0.5,1,2", "--no-progress", "--dpi", "40"]  # fmt: skip
    cases = [
        (["--type", "eso", "--form", "current"], {"type": "eso", "extended_order": 1,
                                                  "form": "current"}, "eso"),
        (["--type", "dob_lp", "--filter-bandwidth", "300"], {"type": "dob_lp", "order": 1,
                                                         "filter_bandwidth": 300.0}, "dob_lp"),
    ]  # fmt: skip
    for options, spec, stem in cases:
        out = tmp_path / stem
        code, _, err = run(capsys, *common, *options, "--out", str(out))
        assert code == 0 and err == "", err
        loop = ServoLoop(plant=PLANT, nominal=NOMINAL, Ts=TS, controller=PD(50.0, 5.0),
                         observer={**spec, "bandwidth": 100.0})  # fmt: skip
        expected = robust_stability_map(loop, J_ratio=[0.5, 1.0, 2.0], b=PLANT.b,
                                        bandwidth=[50.0, 200.0])  # fmt: skip
        got = [float(r["spectral_radius"]) for r in rows(out / f"stability_{stem}_J_ratio_m1.csv")]
        np.testing.assert_array_equal(got, expected.spectral_radius.ravel())
        summary = json.loads((out / "stability.json").read_text())
        assert summary["maps"][0]["observer"] == spec


def test_analyze_noise_and_bode_of_a_registered_family(capsys, tmp_path, registered):
    options = ["--type", "dob_lp", "--filter-bandwidth", "300", "--orders", "0,1", "--dpi", "40",
               "--no-progress"]  # fmt: skip
    code, _, err = run(capsys, "analyze", "noise", *options, "--bandwidths", "50,200",
                       "--out", str(tmp_path / "n"))  # fmt: skip
    assert code == 0 and err == "", err
    table = rows(tmp_path / "n" / "noise.csv")
    assert [(int(r["order"]), float(r["bandwidth_rad_s"])) for r in table] == [
        (0, 50.0), (0, 200.0), (1, 50.0), (1, 200.0)]  # fmt: skip
    for r in table:
        m, g = int(r["order"]), float(r["bandwidth_rad_s"])
        design = design_filtered(MODEL, order=m, bandwidth=g, filter_bandwidth=300.0)
        gains = noise_gains(plant=PLANT, nominal=NOMINAL, Ts=TS, controller=PD(50.0, 5.0),
                            observer=design)  # fmt: skip
        assert float(r["tau_hat_position"]) == pytest.approx(gains.tau_hat_position, rel=1e-12)
        assert float(r["u_velocity"]) == pytest.approx(gains.u_velocity, rel=1e-12)
    code, _, err = run(capsys, "analyze", "bode", *options, "--out", str(tmp_path / "b"))
    assert code == 0 and err == "", err
    bode = rows(tmp_path / "b" / "bode.csv")
    f = np.array([float(r["frequency_Hz"]) for r in bode if r["order"] == "1"])
    q = np.array([float(r["Q_abs"]) for r in bode if r["order"] == "1"])
    # Q of the family is the DOb's times the low-pass (1 - a)/(z - a): independent of the CLI
    z, a = np.exp(2j * np.pi * f * TS), math.exp(-300.0 * TS)
    dob = design_observer(MODEL, order=1, bandwidth=100.0)
    np.testing.assert_allclose(q, np.abs(estimation_response(dob, f) * (1 - a) / (z - a)),
                               rtol=1e-9)  # fmt: skip


@pytest.mark.parametrize("analysis", ["noise", "tradeoff"])
def test_analyze_default_grid_follows_the_family(capsys, tmp_path, analysis):
    """The default grid is the paper's family's; another family keeps of it what it can design
    (the fresh-clone audit of issue 20: `analyze noise --type eso` stopped at the ESO of
    extended order 2 at 10 rad/s). Which points fail comes from the design functions here, not
    from the command: the note names what was left out, and the table holds the rest."""
    from hpdob.cli._analyze import GRID_DEFAULTS, _grid  # the documented defaults

    orders_text, grid_text = GRID_DEFAULTS[analysis]
    grid = _grid(grid_text)
    orders = [int(m) for m in orders_text.split(",")]

    def designs(m, g):
        try:
            design_eso(MODEL, bandwidth=g, extended_order=m)
        except ValueError:
            return False
        return True

    expected = [m for m in orders if all(designs(m, g) for g in grid)]
    assert 0 < len(expected) < len(orders)  # the case of the audit: some orders fail
    out = tmp_path / analysis
    code, _, err = run(capsys, "analyze", analysis, "--type", "eso", "--no-progress", "--dpi",
                       "40", "--out", str(out))  # fmt: skip
    assert code == 0, err
    left = [m for m in orders if m not in expected]
    assert err.count("\n") == 1 and f"orders {', '.join(map(str, left))}" in err, err
    assert "give --orders and --bandwidths" in err
    table = rows(out / f"{analysis}.csv")
    assert sorted({int(r["order"]) for r in table}) == expected
    assert len({float(r["bandwidth_rad_s"]) for r in table}) == len(grid)
    # given orders are kept whole: the default bandwidths they cannot design are left out
    kept = [g for g in grid if designs(left[0], g)]
    assert 0 < len(kept) < len(grid)
    code, _, err = run(capsys, "analyze", analysis, "--type", "eso", "--orders", str(left[0]),
                       "--no-progress", "--dpi", "40",
                       "--out", str(tmp_path / "order"))  # fmt: skip
    assert code == 0 and f"{len(grid) - len(kept)} default bandwidths" in err, err
    table = rows(tmp_path / "order" / f"{analysis}.csv")
    assert sorted({float(r["bandwidth_rad_s"]) for r in table}) == pytest.approx(kept)
    # a grid the user gives is kept whole: its undesignable point stops the analysis, named
    code, _, err = run(capsys, "analyze", analysis, "--type", "eso", "--orders", str(left[0]),
                       "--bandwidths", f"{grid[0]}", "--no-progress",
                       "--out", str(tmp_path / "given"))  # fmt: skip
    assert code == 2 and "cannot be realised for an ESO of extended order" in err
    assert not (tmp_path / "given").exists()


def test_analyze_kalman_default_grid_keeps_the_bandwidths_it_designs(capsys, tmp_path):
    """The Kalman design refuses bandwidths at or beyond pi/(2 Ts): the default bandwidths
    above it are left out (one given order: the Kalman design is the slow one here)."""
    out = tmp_path / "kalman"
    code, _, err = run(capsys, "analyze", "noise", "--type", "kalman", "--orders", "0",
                       "--position-noise-std", "1e-4", "--no-progress", "--dpi", "40",
                       "--out", str(out))  # fmt: skip
    assert code == 0, err
    assert "--type kalman cannot design" in err and "default bandwidths" in err
    table = rows(out / "noise.csv")
    bandwidths = [float(r["bandwidth_rad_s"]) for r in table]
    assert {int(r["order"]) for r in table} == {0}
    assert max(bandwidths) < math.pi / (2 * TS) < 2000.0
    # the paper's family keeps its default grid, every point
    code, _, err = run(capsys, "analyze", "tradeoff", "--no-progress", "--dpi", "40",
                       "--out", str(tmp_path / "dob"))  # fmt: skip
    assert code == 0 and err == "", err
    assert len(rows(tmp_path / "dob" / "tradeoff.csv")) == 4 * 61


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (["--type", "dob_lp"], r"--type dob_lp needs --filter-bandwidth \(low-pass bandwidth"),
        (["--filter-bandwidth", "300"],
         "--filter-bandwidth applies to another family, not --type dob"),
        (["--type", "eso", "--measurement", "position"],
         "--measurement applies to --type dob, not --type eso"),
        (["--type", "kalman"], "--type kalman needs --position-noise-std"),
        (["--type", "nope"], "invalid choice: 'nope'"),
    ],
)  # fmt: skip
@pytest.mark.parametrize("analysis", ["bode", "noise", "stability"])
def test_analyze_family_options_refused_before_any_work(
    capsys, tmp_path, registered, analysis, options, message
):
    out = tmp_path / "out"
    code, _, err = run(capsys, "analyze", analysis, *options, "--no-progress", "--out", str(out))
    assert code == 2 and err.count("\n") == 1, err
    assert re.search(message, err), err
    assert not out.exists()


@pytest.mark.parametrize(
    ("families", "variants"),
    [("dob_lp", ["filtered"]),  # a registered type: its variants
     ("dob", ["state", "position"]),  # the paper's type: both its variants
     ("position,filtered,dob_lp", ["position", "filtered"])],  # old names kept
)  # fmt: skip
def test_tune_families_takes_the_registry_types(capsys, tmp_path, registered, families, variants):
    # the audit: "--families dob" was refused (only the tuner's own names were accepted)
    argv = ["tune", "--families", families, "--J-range", "0.9,1.1", "--counts-per-rev",
            "16384", "--no-plot", "--no-progress", "--out", str(tmp_path)]  # fmt: skip
    code, _, err = run(capsys, *argv)
    assert code == 0 and err == "", err
    result = json.loads((tmp_path / "tune.json").read_text())
    assert result["settings"]["families"] == variants
    assert {r["family"] for r in rows(tmp_path / "tune.csv")} == set(variants)


def test_tune_families_refuses_an_unknown_name_up_front(capsys, tmp_path):
    out = tmp_path / "out"
    code, _, err = run(capsys, "tune", "--families", "dob,lqg", "--out", str(out))
    assert code == 2 and err.count("\n") == 1, err
    assert "--families takes family types dob, eso, kalman or their variants state, " in err
    assert "got 'lqg'" in err
    assert not out.exists()


def test_analyze_tradeoff_of_the_eso_and_of_a_registered_family(capsys, tmp_path, registered):
    """`analyze tradeoff --type T` (was refused): each CSV entry against the direct computation
    on the family's design; the registered low-pass's error |1 - Q| against the DOb's Q times
    the low-pass (1 - a)/(z - a), independent of the family's code."""
    grid = ["--bandwidths", "100,400", "--frequency", "2", "--dpi", "40", "--no-progress"]
    for kind, options in (("eso", ["--form", "predictive", "--orders", "0,1"]),
                          ("dob_lp",
                           ["--filter-bandwidth", "300", "--orders", "0,1"])):  # fmt: skip
        out = tmp_path / kind
        code, _, err = run(capsys, "analyze", "tradeoff", "--type", kind, *options, *grid,
                           "--out", str(out))  # fmt: skip
        assert code == 0 and err == "", err
        table = rows(out / "tradeoff.csv")
        summary = json.loads((out / "tradeoff.json").read_text())
        assert {r["family"] for r in table} == {kind}
        # the ESO measures the angle only: the default noise is then the encoder's
        noise = "encoder" if kind == "eso" else "velocity"
        assert summary["noise"] == noise and summary["observer"]["type"] == kind
        assert [(int(r["order"]), float(r["bandwidth_rad_s"])) for r in table] == [
            (0, 100.0), (0, 400.0), (1, 100.0), (1, 400.0)]  # fmt: skip
        for r in table:
            m, g = int(r["order"]), float(r["bandwidth_rad_s"])
            if kind == "eso":
                design = design_eso(MODEL, bandwidth=g, extended_order=m, form="predictive")
                error = abs(estimation_response(design, 2.0, error=True)[0])
            else:
                design = design_filtered(MODEL, order=m, bandwidth=g, filter_bandwidth=300.0)
                z, a = np.exp(2j * np.pi * 2.0 * TS), math.exp(-300.0 * TS)
                dob = design_observer(MODEL, order=m, bandwidth=g)
                error = abs(1 - estimation_response(dob, 2.0)[0] * (1 - a) / (z - a))
            assert float(r["error_gain"]) == pytest.approx(error, rel=1e-9)
            encoder = Encoder(2**20, velocity="backward-difference") if kind == "eso" else None
            gains = noise_gains(plant=NOMINAL, nominal=NOMINAL, Ts=TS, controller=PD(50.0, 5.0),
                                observer=design, sensor=encoder)  # fmt: skip
            # plant = nominal: the command cancels out of the estimate (its own noise gain)
            expected = gains.tau_hat_position if kind == "eso" else gains.tau_hat_velocity
            assert float(r[f"noise_gain_{noise}"]) == pytest.approx(expected, rel=1e-9)
        assert set(summary["improvement_at_equal_noise"]) == {"1"}


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (["--type", "dob_lp"], r"--type dob_lp needs --filter-bandwidth \(low-pass bandwidth"),
        (["--filter-bandwidth", "300"],
         "--filter-bandwidth applies to another family, not --type dob"),
        (["--type", "eso", "--measurements", "position"],
         "--measurements applies to --type dob, not --type eso"),
        (["--type", "eso", "--noise", "velocity"],
         "noise must be 'position' or 'encoder' for family 'eso'"),
        (["--type", "kalman"], "--type kalman needs --position-noise-std"),
        (["--type", "nope"], "invalid choice: 'nope'"),
        (["--velocity-bandwidth", "300", "--measurements", "state,position"],
         "--measurements takes one version with --type dob's options"),
    ],
)  # fmt: skip
def test_analyze_tradeoff_family_options_refused_in_one_line(capsys, tmp_path, registered,
                                                            options, message):  # fmt: skip
    out = tmp_path / "out"
    code, _, err = run(capsys, "analyze", "tradeoff", *options, "--bandwidths", "100",
                       "--no-progress", "--out", str(out))  # fmt: skip
    assert code == 2 and err.count("\n") == 1, err
    assert re.search(message, err), err
    assert not out.exists()
