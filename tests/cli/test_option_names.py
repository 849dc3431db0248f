"""One meaning per option name across commands (issue 23, docs/naming.md): every long option
that two commands share has one meaning and one unit, from an explicit table of the allowed
shared names; identify's old spellings that meant something else are refused with the new
option."""

from __future__ import annotations

import argparse
import re
from collections import defaultdict

import pytest
from test_cli_identify import _error

from hpdob.cli import build_parser

#: Every option name two or more commands share: a phrase its help must contain in each (its
#: meaning) and its unit (the first [...] of the help; "N m or N" and "kg m^2 or kg" are the
#: same unit for a linear axis), None for a unitless option.
SHARED = {
    "--Ts": ("sampling period", "s"),
    "--J": ("true inertia", "kg m^2"),
    "--b": ("true viscous friction", "N m s/rad"),
    "--J-n": ("nominal inertia", "kg m^2"),
    "--b-n": ("nominal viscous friction", "N m s/rad"),
    "--kp": ("gain kp", "1/s^2"),
    "--kd": ("gain kd", "1/s"),
    "--coulomb": ("Coulomb friction", "N m"),
    "--torque-limit": ("torque limit", "N m"),
    "--bandwidth": ("", "rad/s"),
    "--bandwidths": ("", "rad/s"),
    "--velocity-bandwidth": ("velocity poles", "rad/s"),
    "--frequency": ("disturbance frequency", "Hz"),
    "--delay": ("actuator delay", "samples"),
    "--dpi": ("figure resolution", "dots per inch"),
    "--position-noise-std": ("angle noise std", "rad"),
    "--process-noise-std": ("process noise std", None),
    "--order": ("truncation order", None),
    "--orders": ("truncation orders", None),
    "--extended-order": ("f^(m+1) = 0", None),
    "--gain-direction": ("gain direction", None),
    "--poles": ("poles", None),
    "--form": ("discrete implementation", None),
    "--type": ("observer family", None),
    "--measurement": ("angle", None),
    "--pd-velocity": ("velocity", None),
    "--counts-per-rev": ("encoder counts per rev", None),
    "--dtype": ("scalar type", None),
    "--prefix": ("C ", None),
    "--axis": ("units of the report", None),
    "--emps": ("EMPS benchmark's measured run", None),
    "--time": ("time column", "s"),
    "--position": ("position column", "rad or m"),
    "--input": ("input column", None),
    "--input-gain": ("from the input column to torque/force", None),
    "--out": ("", None),
    "--controller": ("the outer loop", None),
    "--ki": ("PID integral gain ki", "1/s^3"),
    "--tracking-time": ("anti-windup tracking time", "s"),
    "--time-constant": ("derivative filter time constant", "s"),
    "--adrc-bandwidth": ("ADRC closed-loop bandwidth", "rad/s"),
    "--adrc-observer-bandwidth": ("ADRC's own ESO", "rad/s"),
    "--no-plot": ("skip the figure", None),
    "--progress": ("stderr", None),
    "--no-progress": ("stderr", None),
}

#: For a linear axis a rotary unit's alternative: the same quantity.
LINEAR = {"N m or N": "N m", "kg m^2 or kg": "kg m^2", "N m s/rad or N s/m": "N m s/rad"}


def _commands(parser, prefix=""):
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _commands(sub, f"{prefix} {name}".strip())
    if prefix:
        yield prefix, parser


def _options():
    """{long option: [(command, help)]} of the visible options of every command."""
    found = defaultdict(list)
    for command, parser in _commands(build_parser()):
        for action in parser._actions:
            if action.help == argparse.SUPPRESS or isinstance(action, argparse._HelpAction):
                continue
            for option in action.option_strings:
                if option.startswith("--"):
                    found[option].append((command, action.help or ""))
    return found


def _unit(help_text: str):
    found = re.search(r"\[([^\]]*)\](?! table| type)", help_text)  # not a TOML [table]
    return None if found is None else LINEAR.get(found.group(1), found.group(1))


def test_every_shared_option_has_one_meaning_and_one_unit():
    options = _options()
    shared = {o: uses for o, uses in options.items() if len({c for c, _ in uses}) > 1}
    assert set(shared) == set(SHARED), (
        "new shared option names must be added to SHARED with their one meaning: "
        f"{sorted(set(shared) ^ set(SHARED))}"
    )
    for option, uses in shared.items():
        phrase, unit = SHARED[option]
        for command, text in uses:
            assert phrase.lower() in text.lower(), (option, command, text)
            assert _unit(text) == unit, (option, command, text)


def test_identify_has_no_option_with_another_commands_meaning():
    """identify's filter bandwidth [Hz] and Butterworth order are not the observer's
    --bandwidth [rad/s] and --order m; its loop's limit is tune's --torque-limit."""
    identify = {o: text for o, uses in _options().items() for c, text in uses if c == "identify"}
    assert "--bandwidth" not in identify and "--order" not in identify
    assert "--limit" not in identify
    assert "[Hz]" in identify["--filter-bandwidth"]
    assert "Butterworth" in identify["--filter-order"]
    assert "[N m or N]" in identify["--torque-limit"]


@pytest.mark.parametrize(
    ("old", "new"),
    [("--bandwidth", "--filter-bandwidth"), ("--order", "--filter-order"),
     ("--limit", "--torque-limit")],
)  # fmt: skip
def test_identify_refuses_its_old_spellings_with_the_new_option(capsys, old, new):
    message = _error(capsys, "--emps", old, "3")
    assert f"identify {old} is now {new}: give {new} 3" in message
    assert "\n" not in message.strip()
