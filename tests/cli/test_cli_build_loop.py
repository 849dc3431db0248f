"""``hpdob build-loop scenario.toml``: a scenario's sample loop built ahead of time (the build
itself is tested in ``tests/simulation/test_aot_build.py``; here what the command passes on
and how it reports)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

import hpdob.simulation
from hpdob.cli import main

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def test_help_describes_the_command_and_its_page(capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["build-loop", "--help"])
    assert exit_.value.code == 0
    out = " ".join(capsys.readouterr().out.split())
    assert "numba.pycc" in out and "HPDOB_AOT=0" in out and "docs/simulation.md" in out
    assert (EXAMPLES.parent / "docs" / "simulation.md").is_file()


def test_the_scenario_s_run_settings_are_built(capsys, monkeypatch, tmp_path):
    seen = {}

    def build(**kwargs):
        seen.update(kwargs)
        return tmp_path / "built.so"

    monkeypatch.setattr(hpdob.simulation, "build_loop_extension", build)
    code = main(["build-loop", str(EXAMPLES / "encoder_noise_order2.toml"),
                 "--folder", str(tmp_path), "--compiler", "zig"])  # fmt: skip
    assert code == 0
    assert capsys.readouterr().out.strip() == str(tmp_path / "built.so")
    assert seen["folder"] == tmp_path and seen["compiler"] == "zig"
    expected = hpdob.simulation.scenario_from_dict(
        hpdob.simulation.read_toml(EXAMPLES / "encoder_noise_order2.toml")
    )
    assert "label" in expected and "label" not in seen  # the label does not decide the loop
    assert {k: v for k, v in seen.items() if k not in ("folder", "compiler")}.keys() == {
        k for k in expected if k != "label"
    }
    assert seen["substeps"] == expected["substeps"] and seen["sensor"] == expected["sensor"]


def test_a_failed_build_is_one_line_and_writes_no_extension(capsys, tmp_path):
    failing = f"{sys.executable} -c 'raise SystemExit(1)'"
    code = main(["build-loop", str(EXAMPLES / "canonical_pid.toml"), "--folder", str(tmp_path),
                 "--compiler", failing])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1
    assert err.startswith("hpdob build-loop: error: numba.pycc failed to build the loop")
    assert not list(tmp_path.glob("hpdob_aot_*"))


def test_an_arm_scenario_has_no_loop_to_build(capsys, tmp_path):
    code = main(["build-loop", str(EXAMPLES / "two_link_observers.toml"),
                 "--folder", str(tmp_path)])  # fmt: skip
    assert code == 2
    assert "a [plant] type with a loop of its own" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (["--folder", "FILE"], "--folder '{tmp}/FILE' cannot be written: it is an existing file"),
        (["--folder", "FILE/below"], "--folder '{tmp}/FILE/below' cannot be written"),
        (["--folder", ""], "argument --folder: it must name a folder, got ''"),
        (["--compiler", 'gcc "-O2'], "compiler must be a command line shlex can split"),
        (["--compiler", ""], "compiler must name a compiler command"),
    ],
)
def test_bad_options_are_one_line_before_the_build(options, message, capsys, monkeypatch,
                                                   tmp_path):  # fmt: skip
    import hpdob.simulation._aot_build as aot_build

    def compile_(work, command, timeout):
        raise AssertionError(f"the build started in {work}")

    monkeypatch.setattr(aot_build, "_compile", compile_)
    (tmp_path / "FILE").write_text("a file")
    options = [o.replace("FILE", str(tmp_path / "FILE")) for o in options]
    if "--folder" not in options:
        options += ["--folder", str(tmp_path / "out")]
    try:
        code = main(["build-loop", str(EXAMPLES / "canonical_pid.toml"), *options])
    except SystemExit as exit_:  # argparse's own refusal of an option's value
        code = exit_.code
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1, err
    assert err.startswith("hpdob build-loop: error: ")
    assert message.format(tmp=tmp_path) in err
    assert [p.name for p in tmp_path.iterdir()] == ["FILE"]


def test_a_mujoco_scenario_has_no_compiled_loop_to_build(capsys, tmp_path):
    pytest.importorskip("mujoco")
    code = main(["build-loop", str(EXAMPLES / "mujoco_wall.toml"), "--folder", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1
    assert "plant (MujocoServo) is advanced from Python" in err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    "options",
    [["--measurement", "position", "--pd-velocity", "observer"], ["--measurement", "position"]],
)
def test_simulate_s_loop_options_build_the_loop_simulate_takes(options, capsys, monkeypatch,
                                                               tmp_path):  # fmt: skip
    """``--measurement`` and ``--pd-velocity`` change the run's loop (the observer family, the
    PD's velocity): build-loop takes them as simulate does, and ``hpdob simulate`` with them
    then takes the built loop (the path it tries to load is recorded; a fake build, not
    loaded: the JIT loop runs), while the loop built without them is not the run's."""
    import json

    import hpdob.simulation._aot_build as aot_build
    from hpdob.simulation import _aot

    def compile_(work, command, timeout):
        spec = json.loads((work / "spec.json").read_text())
        (work / spec["file"]).write_bytes(b"not loaded")

    monkeypatch.setattr(aot_build, "_compile", compile_)
    tried = []
    monkeypatch.setattr(_aot, "load_extension", lambda p: tried.append(p))
    scenario = str(EXAMPLES / "canonical_hpdob.toml")
    plain, folder = tmp_path / "plain", tmp_path / "aot"
    assert main(["build-loop", scenario, "--folder", str(plain)]) == 0
    assert main(["build-loop", scenario, "--folder", str(folder), *options]) == 0
    built = Path(capsys.readouterr().out.split()[-1])
    assert built.parent == folder and built.name not in {p.name for p in plain.iterdir()}
    monkeypatch.setenv("HPDOB_AOT_DIR", str(folder))
    out = ["--out", str(tmp_path / "results"), "--no-plot"]
    assert main(["simulate", scenario, *options, *out]) == 0
    assert tried == [built]
    monkeypatch.setenv("HPDOB_AOT_DIR", str(plain))  # built without them: not this run's
    tried.clear()
    assert main(["simulate", scenario, *options, *out]) == 0
    assert tried == []


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (["--measurement", "angle"], "argument --measurement: invalid choice: 'angle' (choose "
                                     "from 'state', 'position')"),
        (["--pd-velocity", "x"], "argument --pd-velocity: invalid choice: 'x'"),
    ],
)  # fmt: skip
def test_bad_loop_options_are_refused_and_build_nothing(options, message, capsys, tmp_path):
    with pytest.raises(SystemExit) as exit_:
        main(["build-loop", str(EXAMPLES / "canonical_hpdob.toml"), "--folder",
              str(tmp_path / "aot"), *options])  # fmt: skip
    assert exit_.value.code == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "aot").exists()


def test_measurement_needs_an_observer_table(capsys, tmp_path):
    code = main(["build-loop", str(EXAMPLES / "canonical_pid.toml"), "--folder",
                 str(tmp_path / "aot"), "--measurement", "position"])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1
    assert "--measurement needs an [observer] table in" in err
    assert not (tmp_path / "aot").exists()
