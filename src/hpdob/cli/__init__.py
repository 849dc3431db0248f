"""Command-line interface: ``hpdob <command> [options]``.

Each command lives in its own module that exposes ``register(subparsers)``; the module's
handler returns the process exit code. Bad arguments print one line naming the argument
and exit with code 2, never a traceback; so do files that cannot be written (OSError).
Ctrl-C prints one line and exits with code 130.
"""

from __future__ import annotations

import argparse
import os
import re
import sys

from .._validation import ParameterTypeError, ParameterValueError
from .._version import __version__
from . import (
    _analyze,
    _compare,
    _design,
    _estimate,
    _export_c,
    _export_fmu,
    _identify,
    _reproduce,
    _simulate,
    _sweep,
    _tune,
)
from ._errors import CLIError

__all__ = ["CLIError", "main"]

_COMMANDS = (
    _reproduce,
    _simulate,
    _sweep,
    _design,
    _export_c,
    _export_fmu,
    _analyze,
    _identify,
    _estimate,
    _compare,
    _tune,
)


class _Parser(argparse.ArgumentParser):
    """ArgumentParser whose errors are a single line and exit code 2."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message}\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="hpdob",
        description="Discrete-time disturbance observers "
        "(DOb, HPDOb, any truncation order) for motion control.",
    )
    parser.add_argument("--version", action="version", version=f"hpdob {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True
    for module in _COMMANDS:
        module.register(sub)
    return parser


def _one_line(err: BaseException) -> str:
    """The message of ``err`` on one line (wrapped array reprs and the like are joined)."""
    return re.sub(r"\s*\n\s*", " ", str(err)).strip()


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``hpdob`` console script; returns the exit code.

    Errors print one line ``hpdob <command>: error: ...`` and return 2; Ctrl-C
    (KeyboardInterrupt) cancels the pending work, prints ``hpdob <command>: interrupted`` and
    returns 130 (128 + SIGINT), leaving the previous outputs (``docs/reliability.md``).

    Parameters
    ----------
    argv : list of str, optional
        The arguments after ``hpdob`` (e.g. ``["design", "--order", "1"]``). Default
        ``sys.argv[1:]``.

    Returns
    -------
    int
        The exit code: 0 on success, 2 for a rejected argument or a file error, 130 when
        interrupted, 1 otherwise (a diverged simulation, a closed output pipe, a bug).

    Examples
    --------
    >>> from hpdob.cli import main
    >>> main(["design", "--order", "-1"])   # prints the error on stderr
    2
    """
    command = "hpdob"
    try:
        parser = build_parser()
        args = parser.parse_args(argv)
        command = f"hpdob {args.command}"
        return int(args.handler(args) or 0)
    except KeyboardInterrupt:
        print(f"{command}: interrupted", file=sys.stderr)
        return 130
    except (CLIError, ParameterTypeError, ParameterValueError) as err:
        print(f"{command}: error: {_one_line(err)}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # e.g. `hpdob design --json | head`: stop quietly
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 1
    except OSError as err:  # e.g. an --out directory that cannot be created or written
        print(f"{command}: error: {_one_line(err)}", file=sys.stderr)
        return 2
    except Exception as err:  # a bug: still one line, the traceback on request
        if os.environ.get("HPDOB_TRACEBACK"):
            raise
        print(
            f"{command}: internal error: {type(err).__name__}: {_one_line(err)} (please report "
            f"it; set HPDOB_TRACEBACK=1 for the traceback)",
            file=sys.stderr,
        )
        return 1
