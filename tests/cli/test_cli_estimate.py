"""``hpdob estimate``: an observer run offline over a log file; one-line errors, exit code 2."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest

from hpdob import ServoModel, design_observer, estimate_disturbance, paper
from hpdob.cli import main
from hpdob.observers import design_eso, design_kalman, kalman_process_noise


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def write_csv(path, **columns):
    rows = [",".join(columns)]
    rows += [",".join(repr(float(v)) for v in row) for row in zip(*columns.values(), strict=True)]
    path.write_text("\n".join(rows) + "\n")
    return path


@pytest.fixture
def log(tmp_path):
    """A 2 s encoder log of the canonical HPDOb-100 loop, the input logged as a current."""
    result = paper.run("virtual-experiment", duration=2.0)
    gain = 0.05  # N m per A: the log holds u / gain
    path = write_csv(tmp_path / "log.csv", t=result.t, q=result.theta_measured, i=result.u / gain)
    return path, result, gain


def test_csv_log_matches_the_library(tmp_path, capsys, log):
    path, result, gain = log
    out_dir = tmp_path / "out"
    code, out, err = run(
        capsys, "estimate", path, "--time", "t", "--position", "q", "--input", "i",
        "--input-gain", gain, "--J-n", 2.8e-4, "--order", 1, "--bandwidth", 100, "--out", out_dir,
    )  # fmt: skip
    assert code == 0 and err == "", err
    assert {p.name for p in out_dir.iterdir()} == {"estimate.csv", "estimate.json", "estimate.png"}
    table = np.genfromtxt(out_dir / "estimate.csv", delimiter=",", names=True)
    design = design_observer(ServoModel(2.8e-4).discretize(1e-3), order=1, bandwidth=100.0)
    expected = estimate_disturbance(design, theta=result.theta_measured, u=result.u / gain * gain)
    np.testing.assert_allclose(table["tau_hat"], expected.tau_hat, rtol=1e-12, atol=1e-15)
    report = json.loads((out_dir / "estimate.json").read_text())
    assert report["nominal"]["J"] == 2.8e-4 and report["observer"]["order"] == 1
    assert "tau_hat: mean" in out


def test_emps_with_an_identification_file(tmp_path, capsys):
    ident = tmp_path / "ident"
    assert run(capsys, "identify", "--emps", "--out", ident, "--no-plot")[0] == 0
    code, _, err = run(
        capsys, "estimate", "--emps", "--from-identification", ident / "identification.json",
        "--order", 0, "--bandwidth", 50, "--out", tmp_path / "est", "--no-plot",
    )  # fmt: skip
    assert code == 0 and err == ""
    report = json.loads((tmp_path / "est" / "estimate.json").read_text())
    identified = json.loads((ident / "identification.json").read_text())["parameters"]
    assert report["nominal"]["J"] == identified["J"]
    assert report["nominal"]["b"] == identified["b"]


@pytest.mark.parametrize(
    ("options", "design"),
    [
        (("--type", "eso", "--extended-order", 1, "--bandwidth", 80),
         lambda m: design_eso(m, bandwidth=80.0, extended_order=1)),
        (("--type", "kalman", "--position-noise-std", 1e-6, "--process-noise-std", 50.0),
         lambda m: design_kalman(m, position_noise_std=1e-6, process_noise_std=50.0)),
        (("--measurement", "position", "--bandwidth", 60),
         lambda m: design_observer(m, order=1, bandwidth=60.0, measurement="position")),
        (("--type", "kalman", "--position-noise-std", 1e-6, "--bandwidth", 40),
         lambda m: design_kalman(m, position_noise_std=1e-6, process_noise_std=(
             kalman_process_noise(m, bandwidth=40.0, position_noise_std=1e-6)))),
        ((), lambda m: design_observer(m, order=1, bandwidth=100.0)),
    ],
    ids=["eso", "kalman", "position", "kalman-for-bandwidth", "defaults"],
)  # fmt: skip
def test_every_family_matches_the_library(tmp_path, capsys, log, options, design):
    """``--type``/``--measurement`` build the same observer as the library's own design call."""
    path, result, gain = log
    code, _, err = run(
        capsys, "estimate", path, "--time", "t", "--position", "q", "--input", "i",
        "--input-gain", gain, "--J-n", 2.8e-4, *options, "--out", tmp_path / "o", "--no-plot",
    )  # fmt: skip
    assert code == 0 and err == "", err
    table = np.genfromtxt(tmp_path / "o" / "estimate.csv", delimiter=",", names=True)
    expected = estimate_disturbance(
        design(ServoModel(2.8e-4).discretize(1e-3)), theta=result.theta_measured, u=result.u
    )
    np.testing.assert_allclose(table["tau_hat"], expected.tau_hat, rtol=1e-9, atol=1e-12)
    report = json.loads((tmp_path / "o" / "estimate.json").read_text())["observer"]
    assert report["type"] == (options[1] if options[:1] == ("--type",) else "dob")
    # The settings in effect, defaults and derived values included, are the design's.
    reference = design(ServoModel(2.8e-4).discretize(1e-3))
    for name in ("order", "extended_order", "form", "bandwidth", "velocity_bandwidth",
                 "position_noise_std", "process_noise_std"):  # fmt: skip
        value = getattr(reference, name, None)
        if isinstance(value, str):
            assert report[name] == value, name
        elif value is not None:
            assert report[name] == pytest.approx(value, rel=1e-12), name
    if hasattr(reference, "gain_direction") and reference.gain_direction is not None:
        assert report["gain_direction"] == list(reference.gain_direction)


@pytest.mark.parametrize(
    ("extra", "needle"),
    [
        (("--J-n", 2.8e-4, "--type", "eso", "--order", 1), "--type eso takes --extended-order"),
        (("--J-n", 2.8e-4, "--type", "kalman"), "--type kalman needs --position-noise-std"),
        ((), "give the nominal model: --J-n (and --b-n), or --from-identification FILE"),
        (("--J-n", 2.8e-4, "--position", "nope"), "nope"),
        (("--J-n", -1), "J must be a positive finite inertia"),
        (("--J-n", 2.8e-4, "--bandwidth", 0), "bandwidth must be a positive"),
        (("--J-n", "x"), "argument --J-n: expected a number, got 'x'"),
    ],
)
def test_bad_arguments_one_line_exit_2(tmp_path, capsys, log, extra, needle):
    path, _, _ = log
    argv = ["estimate", path, "--time", "t", "--position", "q", "--input", "i",
            "--out", tmp_path / "o", "--no-plot"]  # fmt: skip
    if "--position" in extra:
        argv = [a for a in argv if a not in ("--position", "q")]
    try:
        code = main([str(a) for a in (*argv, *extra)])
    except SystemExit as exit_:
        code = exit_.code
    _, err = capsys.readouterr()
    assert code == 2 and err.count("\n") == 1 and needle in err, err


@pytest.mark.parametrize(
    ("content", "needle"),
    [
        (
            "t,q,i\n0,0,0\n0.001,0,nan\n" + "".join(f"{k / 1000},0,0\n" for k in range(2, 20)),
            "non-finite sample nan at index 1",
        ),
        ("t,q\n" + "".join(f"{k / 1000},0\n" for k in range(20)), "i"),
        ("t,q,i\n" + "".join(f"{k / 1000},0,x\n" for k in range(20)), "i"),
    ],
)
def test_bad_log_files_one_line_exit_2(tmp_path, capsys, content, needle):
    path = tmp_path / "bad.csv"
    path.write_text(content)
    code, _, err = run(capsys, "estimate", path, "--time", "t", "--position", "q", "--input",
                       "i", "--J-n", 2.8e-4, "--out", tmp_path / "o", "--no-plot")  # fmt: skip
    assert code == 2 and err.count("\n") == 1 and needle in err, err


def test_bad_identification_file(tmp_path, capsys):
    bad = tmp_path / "ident.json"
    bad.write_text('{"J": 1}')
    code, _, err = run(capsys, "estimate", "--emps", "--from-identification", bad, "--no-plot")
    assert code == 2 and "is not an 'hpdob identify' result" in err


@pytest.mark.parametrize(
    ("extra", "needle"),
    [
        ((), "--J-n"),  # the nominal model missing
        (("--from-identification", "missing.json"), "missing.json"),
        (("--J-n", 2.8e-4, "--extended-order", 2), "--extended-order"),
        (("--J-n", 2.8e-4, "--out", "a_file/out"), "a_file"),
    ],
)
@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="POSIX FIFOs")
def test_options_are_checked_before_the_log_is_read(tmp_path, capsys, monkeypatch, extra, needle):
    """Issue 27: a missing --J-n (or another bad option, or an output location that cannot be
    written) was reported only after the whole log was read (up to 256 MiB: minutes). The log
    reader here is a FIFO nobody writes to, and read_log is replaced by a trap: an error that
    reaches it would hang or fail differently."""
    import hpdob.identification as identification

    def trap(*args, **kwargs):
        raise AssertionError("the log was read before the options were checked")

    monkeypatch.setattr(identification, "read_log", trap)
    monkeypatch.chdir(tmp_path)
    (tmp_path / "a_file").write_text("")
    fifo = tmp_path / "slow.csv"
    os.mkfifo(fifo)
    code, out, err = run(
        capsys, "estimate", fifo, "--time", "t", "--position", "q", "--input", "i", *extra
    )
    assert code == 2 and out == "", err
    assert err.count("\n") == 1 and needle in err, err
