"""Tests of ``hpdob export-c`` and of the C example in examples/c (the library itself is
tested in test_export_c.py)."""

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from hpdob import ServoModel, design_observer, export_c
from hpdob.cli import main
from hpdob.testing import find_compiler

ROOT = Path(__file__).resolve().parents[2]
DTYPES = ("double", "float")

needs_cc = pytest.mark.skipif(
    find_compiler() is None,
    reason="no C compiler (gcc, or $CC) is installed, so the generated C cannot be built",
)


# -- command line and the C example --------------------------------------------------------
def test_cli_export_matches_library(capsys, tmp_path):
    argv = [
        "export-c",
        "--J-n",
        "3.06e-4",
        "--b-n",
        "5e-5",
        "--order",
        "2",
        "--bandwidth",
        "150",
        "--gain-direction",
        "0,1",
        "--prefix",
        "axis",
        "--dtype",
        "float",
        "-o",
        str(tmp_path / "cli"),
    ]
    code = main(argv)
    out, err = capsys.readouterr()
    assert code == 0 and err == ""
    paths = [Path(line) for line in out.splitlines()]
    assert paths == [tmp_path / "cli" / "axis.h", tmp_path / "cli" / "axis.c"]
    design = design_observer(
        ServoModel(3.06e-4, 5e-5).discretize(1e-3),
        order=2,
        bandwidth=150.0,
        gain_direction=(0, 1),
    )
    expected = export_c(design, tmp_path / "lib", prefix="axis", dtype="float")
    assert [p.read_text() for p in paths] == [p.read_text() for p in expected]


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["--prefix", "9lives"], "prefix must be a C identifier"),
        (["--dtype", "half"], "dtype must be one of 'double', 'float', 'q31', 'q15'; got 'half'"),
        (["--order", "-1"], "order must be a non-negative integer"),
    ],
)
def test_cli_bad_arguments_one_line_exit_2(capsys, tmp_path, argv, needle):
    code = main(["export-c", "-o", str(tmp_path / "x"), *argv])
    out, err = capsys.readouterr()
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and needle in err
    assert not (tmp_path / "x").exists()


@needs_cc
@pytest.mark.skipif(shutil.which("make") is None, reason="make is not installed")
@pytest.mark.parametrize("dtype", DTYPES)
def test_c_example_builds_and_runs(tmp_path, dtype):
    example = tmp_path / "c"
    shutil.copytree(
        ROOT / "examples" / "c", example, ignore=shutil.ignore_patterns("main", "dob.*", "*.args")
    )
    cmd = ["make", f"HPDOB={sys.executable} -m hpdob", f"DTYPE={dtype}"]
    done = subprocess.run(cmd, cwd=example, capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stdout + done.stderr
    assert f"order 1 observer in {dtype}" in done.stdout
    assert "with the observer" in done.stdout
    assert (example / "dob.h").exists() and (example / "main").exists()


def _example_without_hpdob_on_path(tmp_path, *, venv: bool):
    """A copy of examples/c two levels below a fake repository, optionally with its .venv."""
    repo = tmp_path / "repo"
    example = repo / "examples" / "c"
    shutil.copytree(
        ROOT / "examples" / "c", example, ignore=shutil.ignore_patterns("main", "dob.*", "*.args")
    )
    if venv:  # the repository's venv, not activated: its hpdob runs this interpreter
        script = repo / ".venv" / "bin" / "hpdob"
        script.parent.mkdir(parents=True)
        script.write_text(f'#!/bin/sh\nexec "{sys.executable}" -m hpdob "$@"\n')
        script.chmod(0o755)
    path = "/usr/bin:/bin"
    assert shutil.which("hpdob", path=path) is None, "an hpdob outside any venv"
    return example, {"PATH": path, "HOME": str(tmp_path)}


@needs_cc
@pytest.mark.skipif(shutil.which("make") is None, reason="make is not installed")
def test_c_example_finds_the_repositorys_venv_without_activating_it(tmp_path):
    example, env = _example_without_hpdob_on_path(tmp_path, venv=True)
    done = subprocess.run(["make"], cwd=example, env=env, capture_output=True, text=True)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "with the observer" in done.stdout and (example / "dob.h").exists()


@pytest.mark.skipif(shutil.which("make") is None, reason="make is not installed")
def test_c_example_falls_back_to_python_m_hpdob(tmp_path):
    example, env = _example_without_hpdob_on_path(tmp_path, venv=False)
    done = subprocess.run(["make", "-n"], cwd=example, env=env, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert "python3 -m hpdob export-c" in done.stdout


# -- --scenario: a scenario file's observer, the RTOB composition as one C observer --------
FORCE_SCENARIO = ROOT / "examples" / "force_step_stiff_wall.toml"


def test_cli_exports_the_rtob_composition_of_a_scenario(capsys, tmp_path):
    from hpdob.simulation import load_scenario

    argv = ["export-c", "--scenario", str(FORCE_SCENARIO), "--prefix", "rtob",
            "-o", str(tmp_path / "cli")]  # fmt: skip
    assert main(argv) == 0
    paths = [Path(line) for line in capsys.readouterr().out.splitlines()]
    observer = load_scenario(FORCE_SCENARIO).loop.observer  # the [reaction_observer] composition
    expected = export_c(observer, tmp_path / "lib", prefix="rtob")
    assert [p.read_text() for p in paths] == [p.read_text() for p in expected]
    header = paths[0].read_text()
    assert "rtob_reaction(" in header and "void rtob_estimates(" in header


def test_cli_scenario_refuses_design_options_and_arms(capsys, tmp_path):
    argv = ["export-c", "--scenario", str(FORCE_SCENARIO), "--bandwidth", "50",
            "-o", str(tmp_path / "a")]  # fmt: skip
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "drop --bandwidth, or drop --scenario" in err
    arm = ROOT / "examples" / "two_link_observers.toml"
    assert main(["export-c", "--scenario", str(arm), "-o", str(tmp_path / "b")]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "takes a single-axis one" in err
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()
