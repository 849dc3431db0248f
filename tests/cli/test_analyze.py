"""``hpdob analyze``: files written, numbers equal to the library's, clear errors."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from hpdob import (
    PD,
    ServoModel,
    design_observer,
    estimation_response,
    loop_margins,
    noise_gains,
    noise_tradeoff,
    robust_stability_map,
)
from hpdob.cli import main

TS = 1e-3
NOMINAL, PLANT, PDC = ServoModel(2.8e-4), ServoModel(3.06e-4, 5e-5), PD(50.0, 5.0)  # canonical


def run(capsys, *argv):
    try:
        code = main(list(argv))
    except SystemExit as exc:  # argparse's own errors (bad option syntax)
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


def test_bode(capsys, tmp_path):
    code, out, err = run(
        capsys, "analyze", "bode", "--orders", "0,1", "--out", str(tmp_path), "--dpi", "40"
    )
    assert code == 0 and err == "" and "bode.png" in out
    data = json.loads((tmp_path / "bode.json").read_text())
    for m in (0, 1):
        design = design_observer(NOMINAL.discretize(TS), order=m, bandwidth=100.0)
        entry = data["orders"][str(m)]
        assert entry["error_gain_at_frequency"] == abs(
            estimation_response(design, 2.0, error=True)[0]
        )
        lm = loop_margins(plant=PLANT, nominal=NOMINAL, Ts=TS, controller=PDC, observer=design)
        assert entry["loop_margins"]["gain_margin"] == lm.gain_margin
        assert entry["loop_margins"]["delay_margin"] == lm.delay_margin
    with (tmp_path / "bode.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    assert {"frequency_Hz", "order", "Q_abs", "Q_phase_deg", "error_abs", "S_abs"} <= set(rows[0])
    assert (tmp_path / "bode.png").stat().st_size > 0


@pytest.mark.parametrize("Ts", ["1e-4", "3e-4"])
def test_bode_grid_stays_below_nyquist(capsys, tmp_path, Ts):
    # Issue 27: at Ts = 1e-4 the grid's last point 1/(2 Ts) gave 2 pi f Ts one ulp above pi and
    # python-control's "evaluation above Nyquist frequency" warning leaked (an error here).
    code, _, err = run(capsys, "analyze", "bode", "--Ts", Ts, "--out", str(tmp_path), "--dpi", "20")
    assert code == 0 and err == ""
    with (tmp_path / "bode.csv").open() as handle:
        f = np.array([float(row["frequency_Hz"]) for row in csv.DictReader(handle)])
    assert np.all(2 * np.pi * f * float(Ts) <= np.pi) and f.max() > 0.4999 / float(Ts)


def test_bode_margins_at_a_short_sampling_period(capsys, tmp_path):
    # At Ts = 7e-5 s the margin grid's lowest frequency (1e-3 rad/s) put z = exp(j w Ts) on the
    # loop's double pole at z = 1 to rounding: zI - A was singular (an internal LinAlgError).
    code, _, err = run(
        capsys, "analyze", "bode", "--Ts", "7e-5", "--out", str(tmp_path), "--dpi", "20"
    )
    assert code == 0 and err == ""
    assert (tmp_path / "bode.json").exists()


def test_noise(capsys, tmp_path):
    code, _, _ = run(
        capsys,
        "analyze",
        "noise",
        "--orders",
        "1",
        "--bandwidths",
        "50,200",
        "--out",
        str(tmp_path),
        "--dpi",
        "40",
    )
    assert code == 0
    data = json.loads((tmp_path / "noise.json").read_text())
    design = design_observer(NOMINAL.discretize(TS), order=1, bandwidth=200.0)
    exact = noise_gains(plant=PLANT, nominal=NOMINAL, Ts=TS, controller=PDC, observer=design)
    assert data["gains"][1] == {"order": 1, "bandwidth_rad_s": 200.0, **exact.to_dict()}
    assert (tmp_path / "noise.png").exists() and (tmp_path / "noise.csv").exists()


def test_tradeoff(capsys, tmp_path):
    code, _, _ = run(
        capsys,
        "analyze",
        "tradeoff",
        "--orders",
        "0,1",
        "--bandwidths",
        "20:800:5",
        "--frequency",
        "2",
        "--out",
        str(tmp_path),
        "--dpi",
        "40",
    )
    assert code == 0
    data = json.loads((tmp_path / "tradeoff.json").read_text())
    table = noise_tradeoff(
        nominal=NOMINAL, Ts=TS, frequency=2.0, bandwidths=np.geomspace(20, 800, 5), orders=(0, 1)
    )
    values = list(data["improvement_at_equal_noise"]["1"].values())
    expected = [None if np.isnan(v) else v for v in table.improvement(1).tolist()]
    assert values == expected
    assert (tmp_path / "tradeoff.png").exists() and (tmp_path / "tradeoff.csv").exists()


def test_tradeoff_pole_tolerance(capsys, tmp_path):
    """Order 3 at 2.22 rad/s is refused by the default realised-pole check (one line, exit 2)
    and accepted with ``--pole-tolerance none``, as ``noise_tradeoff(pole_tolerance=None)``."""
    argv = ["analyze", "tradeoff", "--orders", "0,3", "--bandwidths", "2.220254341396507,100",
            "--out", str(tmp_path), "--dpi", "40"]  # fmt: skip
    code, _, err = run(capsys, *argv)
    assert code == 2 and "cannot be realised for order 3" in err and err.count("\n") == 1
    assert not (tmp_path / "tradeoff.json").exists()
    code, _, _ = run(capsys, *argv, "--pole-tolerance", "none")
    assert code == 0
    table = noise_tradeoff(nominal=NOMINAL, Ts=TS, frequency=2.0, orders=(0, 3),
                           bandwidths=[2.220254341396507, 100.0], pole_tolerance=None)  # fmt: skip
    data = json.loads((tmp_path / "tradeoff.json").read_text())
    values = list(data["improvement_at_equal_noise"]["3"].values())
    assert values == [None if np.isnan(v) else v for v in table.improvement(3).tolist()]


def test_stability(capsys, tmp_path):
    code, out, _ = run(
        capsys,
        "analyze",
        "stability",
        "--orders",
        "1",
        "--values",
        "0.05:2:7",
        "--bandwidths",
        "100,400",
        "--delay",
        "1",
        "--out",
        str(tmp_path),
        "--dpi",
        "40",
    )
    assert code == 0 and "stability_J_ratio_m1_delay1.png" in out
    data = json.loads((tmp_path / "stability.json").read_text())
    smap = robust_stability_map(
        J_ratio=np.geomspace(0.05, 2, 7),
        bandwidth=[100.0, 400.0],
        order=1,
        nominal=NOMINAL,
        Ts=TS,
        controller=PDC,
        b=PLANT.b,
        delay_samples=1,
    )
    assert data["maps"][0]["boundary"] == smap.boundary()
    assert (tmp_path / "stability_J_ratio_m1_delay1.csv").exists()
    code, _, _ = run(
        capsys,
        "analyze",
        "stability",
        "--orders",
        "0",
        "--parameter",
        "b",
        "--values",
        "0,0.1",
        "--bandwidths",
        "100",
        "--out",
        str(tmp_path),
        "--dpi",
        "40",
    )
    assert code == 0 and (tmp_path / "stability_b_m0.png").exists()


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["tradeoff", "--bandwidths", "10:x:3"], "expected LO:HI:N"),
        (["tradeoff", "--bandwidths", "0:100:3"], "expected LO:HI:N"),
        (["noise", "--orders", "one"], "expected comma-separated integer orders"),
        (["stability", "--values=-1,2"], "J_ratio must be positive"),
        (["tradeoff", "--bandwidths=100,-5"], "bandwidths must be positive"),
        (["bode", "--J-n=-1"], "J must be a positive finite inertia"),
        (["tradeoff", "--frequency", "700"], "frequency must be below the Nyquist"),
        # empty comma lists (used to crash with IndexError) name the option
        (["noise", "--bandwidths", ","], "argument --bandwidths: expected LO:HI:N"),
        (["tradeoff", "--bandwidths", " , "], "at least one comma-separated number, got ' , '"),
        (["stability", "--bandwidths", ","], "argument --bandwidths: expected LO:HI:N"),
        (["stability", "--values", ","], "argument --values: expected LO:HI:N"),
        (["bode", "--orders", ","], "argument --orders: expected comma-separated integer"),
        (
            ["bode", "--dpi", "0"],
            "--dpi: expected a resolution of 10 to 1200 dots per inch, got '0'",
        ),
        (
            ["noise", "--dpi=-72"],
            "--dpi: expected a resolution of 10 to 1200 dots per inch",
        ),
        (["tradeoff", "--dpi", "inf"], "argument --dpi: expected a resolution of 10 to"),
        (["stability", "--dpi", "high"], "argument --dpi: expected a resolution of 10 to"),
    ],
)
def test_bad_arguments_exit_2_with_one_line(capsys, tmp_path, argv, message):
    code, _, err = run(capsys, "analyze", *argv, "--out", str(tmp_path))
    assert code == 2
    assert message in err and len(err.strip().splitlines()) == 1
    assert not list(tmp_path.glob("*.png"))


def test_analysis_is_required(capsys):
    code, _, err = run(capsys, "analyze")
    assert code == 2 and "ANALYSIS" in err


def test_stability_grids_in_any_order(capsys, tmp_path):
    # A grid on the command line is a set of values: descending or unsorted input gives the
    # map of the sorted grid (the library itself requires increasing axes).
    maps = []
    for values, bandwidths in (("0.2,0.5,1.5", "100,400"), ("1.5,0.2,0.5,0.5", "400,100")):
        out = tmp_path / values
        code, _, _ = run(
            capsys, "analyze", "stability", "--orders", "1", "--values", values,
            "--bandwidths", bandwidths, "--out", str(out), "--dpi", "30",
        )  # fmt: skip
        assert code == 0
        maps.append(json.loads((out / "stability.json").read_text())["maps"])
    assert maps[0] == maps[1]
