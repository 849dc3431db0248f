"""Tests of the ``hpdob`` command line."""

from __future__ import annotations

import contextlib
import io
import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from hpdob import ServoModel, design_observer
from hpdob.cli import build_parser, main


def run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_design_table(capsys):
    code, out, err = run(
        capsys,
        "design",
        "--J-n",
        "3.06e-4",
        "--b-n",
        "5e-5",
        "--Ts",
        "1e-3",
        "--order",
        "1",
        "--bandwidth",
        "100",
    )
    assert code == 0 and err == ""
    design = design_observer(ServoModel(3.06e-4, 5e-5).discretize(1e-3), order=1, bandwidth=100)
    for name in ("A_D", "B_D", "D_D", "L_1", "L_2", "eigenvalues", "M"):
        assert name in out
    assert f"{design.gains[0, 0]:.6e}" in out and f"{design.gains[1, 1]:.6e}" in out
    assert "0.904837, 0.904837" in out  # exp(-100 * 1e-3), printed to 6 digits


def test_design_json_matches_library(capsys):
    code, out, _ = run(
        capsys,
        "design",
        "--J-n",
        "2.8e-4",
        "--b-n",
        "0",
        "--order",
        "2",
        "--poles",
        "0.9,0.8+0.1j,0.8-0.1j",
        "--gain-direction",
        "0,1",
        "--json",
    )
    assert code == 0
    data = json.loads(out)
    design = design_observer(
        ServoModel(2.8e-4).discretize(1e-3),
        order=2,
        poles=[0.9, 0.8 + 0.1j, 0.8 - 0.1j],
        gain_direction=(0, 1),
    )
    np.testing.assert_array_equal(data["gains"], design.gains)
    np.testing.assert_array_equal(data["error_matrix"], design.error_matrix)
    np.testing.assert_array_equal(data["A_D"], design.model.A)
    assert data["poles"][1] == {"real": 0.8, "imag": 0.1}
    eig = [complex(v["real"], v["imag"]) for v in data["eigenvalues"]]
    np.testing.assert_allclose(
        sorted(eig, key=lambda c: (c.real, c.imag)),
        sorted([0.8 - 0.1j, 0.8 + 0.1j, 0.9], key=lambda c: (c.real, c.imag)),
        atol=1e-12,
    )


def test_defaults_are_the_paper_motor(capsys):
    code, out, _ = run(capsys, "design", "--json")
    data = json.loads(out)
    # the paper's nominal model (section IV): J_n = 2.8e-4 kg m^2, b_n = 0, Ts = 1 ms
    assert code == 0 and data["model"] == {"J": 2.8e-4, "b": 0.0, "Ts": 1e-3}
    assert data["order"] == 1 and data["bandwidth"] == 100.0


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["--J-n", "-1"], "J must be a positive finite inertia [kg m^2], got -1.0"),
        (["--J-n", "abc"], "argument --J-n: expected a number, got 'abc'"),
        (["--J-n", "nan"], "argument --J-n: expected a finite number, got 'nan'"),
        (["--J", "3e-4"], "--J sets the true plant, and this command has none"),
        (["--b", "0"], "the nominal model is --J-n/--b-n"),
        (["--Ts", "0"], "Ts must be a positive finite sampling period"),
        (["--b-n", "-1"], "b must be a non-negative"),
        (["--order", "-1"], "order must be a non-negative integer"),
        (["--order", "1.5"], "argument --order: expected an integer"),
        (["--poles", "0.9"], "poles must have order + 1 = 2 entries"),
        (["--poles", "0.9,1.5"], "strictly inside the unit circle"),
        (["--poles", "0.9,x"], "argument --poles"),
        (["--bandwidth", "-3"], "bandwidth must be a positive"),
        (["--bandwidth", "3", "--poles", "0.9,0.9"], "not allowed with argument"),
        (["--gain-direction", "1"], "gain_direction must be"),
        (["--gain-direction", "0,0"], "gain_direction must not be zero or orthogonal"),
        (["--frobnicate"], "unrecognized arguments: --frobnicate"),
        (["--poles", ","], "argument --poles: expected comma-separated numbers, got ','"),
        (["--gain-direction", ","], "argument --gain-direction: expected comma-separated"),
    ],
)
def test_bad_arguments_one_line_exit_2(capsys, argv, needle):
    try:
        code = main(["design", *argv])
    except SystemExit as exit_:  # argparse's own errors exit; ours return the code
        code = exit_.code
    assert code == 2
    out, err = capsys.readouterr()
    assert out == ""
    assert err.count("\n") == 1 and needle in err
    assert "Traceback" not in err


def test_console_script_and_module():
    script = shutil.which("hpdob", path=str(Path(sys.executable).parent))
    assert script is not None, "the hpdob console script is not installed next to python"
    for cmd in ([script, "--version"], [sys.executable, "-m", "hpdob", "--version"]):
        done = subprocess.run(cmd, capture_output=True, text=True, check=False)
        assert done.returncode == 0 and done.stdout.startswith("hpdob ")
    done = subprocess.run(
        [script, "design", "--J", "0"], capture_output=True, text=True, check=False
    )
    assert done.returncode == 2 and done.stderr.count("\n") == 1


def test_no_command_is_an_error(capsys):
    with pytest.raises(SystemExit) as info:
        main([])
    assert info.value.code == 2


@pytest.mark.parametrize(
    "argv",
    [
        ["export-c", "--out"],
        ["analyze", "bode", "--orders", "0", "--out"],
    ],
)
def test_unwritable_output_is_one_line_exit_2(capsys, tmp_path, argv):
    blocker = tmp_path / "file"
    blocker.write_text("not a directory\n")
    out = blocker / "sub"  # a directory under a regular file cannot be created
    code = main([*argv, str(out)])
    _, err = capsys.readouterr()
    assert code == 2
    assert err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith(f"hpdob {argv[0]}: error: ") and str(out) in err
    assert blocker.read_text() == "not a directory\n"


def test_every_error_is_one_line(capsys):
    # issue 16, item 9: the message holds an array whose repr wrapped onto a second line
    code, out, err = run(capsys, "design", "--order", "50", "--bandwidth", "1000")
    assert code == 2 and out == ""
    assert err.startswith("hpdob design: error: bandwidth=1000.0 rad/s cannot be realised")
    assert err.count("\n") == 1


def test_unexpected_errors_are_one_line_too(capsys, monkeypatch):
    import hpdob.cli._design

    def broken(args):
        raise RuntimeError("first line\nsecond line")

    monkeypatch.setattr(hpdob.cli._design, "_run", broken)
    monkeypatch.delenv("HPDOB_TRACEBACK", raising=False)
    code, _, err = run(capsys, "design")
    assert code == 1
    assert err == (
        "hpdob design: internal error: RuntimeError: first line second line (please report it; "
        "set HPDOB_TRACEBACK=1 for the traceback)\n"
    )


# -- --help: a description line for every command, pages that exist -------------------------
COMMANDS = [
    ["reproduce"],
    ["simulate"],
    ["sweep"],
    ["design"],
    ["export-c"],
    ["analyze"],
    ["analyze", "bode"],
    ["analyze", "noise"],
    ["analyze", "tradeoff"],
    ["analyze", "stability"],
]


@pytest.mark.parametrize("command", COMMANDS, ids=" ".join)
def test_help_has_a_description_and_points_to_pages_that_exist(capsys, command):
    with pytest.raises(SystemExit) as exit_:
        main([*command, "--help"])
    assert exit_.value.code == 0
    out = capsys.readouterr().out
    paragraphs = [p for p in out.split("\n\n") if p.strip()]
    assert paragraphs[0].startswith("usage:")
    description = paragraphs[1]
    assert not description.startswith(("positional arguments", "options")), (
        f"`hpdob {' '.join(command)} --help` has no description line"
    )
    root = Path(__file__).resolve().parents[2]
    for page in re.findall(r"docs/[\w-]+\.md", " ".join(out.split())):
        assert (root / page).exists(), f"--help points to {page}, which does not exist"


def test_sweep_help_points_to_the_sweep_page(capsys):
    with pytest.raises(SystemExit):
        main(["sweep", "--help"])
    assert "docs/sweep.md" in " ".join(capsys.readouterr().out.split())


#: The commands and their sub-commands, as the CLI reference documents them.
COMMANDS = {"reproduce": (), "simulate": (), "build-loop": (), "sweep": (), "design": (),
            "export-c": (), "export-fmu": (), "analyze": ("bode", "noise", "tradeoff",
            "stability"), "compare": (), "estimate": (), "identify": (), "tune": ()}  # fmt: skip


def _help(parser, words):
    out = io.StringIO()
    with contextlib.redirect_stdout(out), pytest.raises(SystemExit):
        parser.parse_args([*words, "--help"])
    return out.getvalue()


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_a_command_alone_helps_as_among_all(name):
    """main builds only the command it runs (the others' parsers held 0.2 MB, a quarter of
    the EMPS log: issue 25's two copies); each command's help, and its sub-commands', read
    the same as with every command registered."""
    full, alone = build_parser(), build_parser(name)
    assert _help(alone, [name]) == _help(full, [name])
    for child in COMMANDS[name]:
        assert _help(alone, [name, child]) == _help(full, [name, child]), child


def test_every_command_is_listed_and_a_non_command_builds_them_all():
    full = _help(build_parser(), [])
    assert all(name in full for name in COMMANDS)
    assert _help(build_parser("--version"), []) == full
    assert _help(build_parser("no-such-command"), []) == full
    with contextlib.redirect_stderr(io.StringIO()) as err, pytest.raises(SystemExit):
        build_parser("design").parse_args(["identify", "--emps"])  # only design is built
    assert "invalid choice: 'identify'" in err.getvalue()


@pytest.mark.parametrize(
    "argv",
    [["design", "--order", "1"], ["design", "--frobnicate"]],
    ids=["a run", "a rejected argument"],
)
def test_the_parser_is_freed_when_main_lets_go_of_it(monkeypatch, argv):
    """main takes its parser apart once parsed: no reference cycle keeps the command's parser
    and its actions (tens of kB) until the next full collection, through the command's run
    or after an error."""
    import argparse
    import gc
    import weakref

    import hpdob.cli

    made = []

    def recorded(command=None):
        parser = build_parser(command)
        parsers = [parser]
        while parsers:  # every parser and action, through the subparsers
            p = parsers.pop()
            made.append(weakref.ref(p))
            for action in p._actions:
                made.append(weakref.ref(action))
                if isinstance(action, argparse._SubParsersAction):
                    parsers.extend(action.choices.values())
        return parser

    monkeypatch.setattr(hpdob.cli, "build_parser", recorded)
    gc.collect()
    gc.disable()
    try:
        quiet = contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO())
        with quiet[0], quiet[1], contextlib.suppress(SystemExit):
            main(argv)
        alive = [ref() for ref in made if ref() is not None]
        assert len(made) > 20 and alive == []
    finally:
        gc.enable()
