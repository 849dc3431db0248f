"""Command-line interface: ``hpdob <command> [options]``.

Each command lives in its own module that exposes ``register(subparsers)``; the module's
handler returns the process exit code. Bad arguments print one line naming the argument
and exit with code 2, never a traceback; so do files that cannot be written (OSError).
Ctrl-C prints one line and exits with code 130; SIGTERM and SIGHUP are handled the same way
(exit 143 and 129). The signal handlers are installed before the command modules (and numpy)
are imported.
"""

from __future__ import annotations

import argparse
import os
import re
import sys

from .._interrupts import (
    EXIT_CODES,
    Interrupted,
    check,
    checkpoint,
    handling_signals,
    received,
)
from .._plugins import load_plugins
from .._version import __version__
from ._errors import CLIError

__all__ = ["CLIError", "main"]

#: The command modules, imported by build_parser() (after main() installed its signal
#: handlers: an interrupt while numpy and the rest import then exits 130 with one line).
_COMMANDS = (
    "_reproduce",
    "_simulate",
    "_build_loop",
    "_sweep",
    "_design",
    "_export_c",
    "_export_fmu",
    "_analyze",
    "_identify",
    "_estimate",
    "_compare",
    "_tune",
)


class _Parser(argparse.ArgumentParser):
    """ArgumentParser whose errors are a single line and exit code 2.

    A negative number in exponent form (``--J-n -5e-4``) is read as a value, as ``-0.0005``
    is (argparse's own pattern has no exponent: "expected one argument").
    """

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message}\n")


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The ``hpdob`` parser with every command, or with ``command`` alone (``main`` passes
    the first argument: a run of one command needs no other's parser, which would hold
    about 0.2 MB and import every command's module; the command's help, usage and errors are
    the same)."""
    modules = _COMMANDS
    if command is not None and "_" + command.replace("-", "_") in _COMMANDS:
        modules = ("_" + command.replace("-", "_"),)
    parser = _Parser(
        prog="hpdob",
        description="Discrete-time disturbance observers "
        "(DOb, HPDOb, any truncation order) for motion control.",
    )
    parser.add_argument("--version", action="version", version=f"hpdob {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True
    import importlib

    for name in modules:
        importlib.import_module(f"{__name__}.{name}").register(sub)
    return parser


def _parse(parser: argparse.ArgumentParser, argv: list) -> argparse.Namespace:
    """``parser.parse_args(argv)``, then the parser taken apart: its actions and their
    groups refer to each other, so that once dropped it would stay (about 40 kB for one
    command) until the next full collection, through the command's run."""
    try:
        return parser.parse_args(argv)
    finally:
        _dismantle(parser)


def _dismantle(parser: argparse.ArgumentParser) -> None:
    """Empty ``parser``, its subparsers, their groups and actions (no cycle is left)."""
    parsers, seen = [parser], set()
    while parsers:
        p = parsers.pop()
        if id(p) in seen:  # a subparser's aliases name it again
            continue
        seen.add(id(p))
        for action in p._actions:
            if isinstance(action, argparse._SubParsersAction):
                parsers.extend(action.choices.values())
            vars(action).clear()
        for group in (*p._action_groups, *p._mutually_exclusive_groups):
            vars(group).clear()
        vars(p).clear()


def _one_line(err: BaseException) -> str:
    """The message of ``err`` on one line (wrapped array reprs and the like are joined)."""
    return re.sub(r"\s*\n\s*", " ", str(err)).strip()


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``hpdob`` console script; returns the exit code.

    Errors print one line ``hpdob <command>: error: ...`` and return 2; Ctrl-C
    (KeyboardInterrupt) cancels the pending work, prints ``hpdob <command>: interrupted`` and
    returns 130 (128 + SIGINT), leaving the previous outputs (``docs/reliability.md``). SIGTERM
    and SIGHUP do the same, printing ``hpdob <command>: interrupted (SIGTERM)`` and returning
    143 (129 for SIGHUP).

    Parameters
    ----------
    argv : list of str, optional
        The arguments after ``hpdob`` (e.g. ``["design", "--order", "1"]``). Default
        ``sys.argv[1:]``.

    Returns
    -------
    int
        The exit code: 0 on success, 2 for a rejected argument or a file error, 130 when
        interrupted by Ctrl-C (143 by SIGTERM, 129 by SIGHUP), 1 otherwise (a diverged
        simulation, a closed output pipe, a bug).

    Examples
    --------
    >>> from hpdob.cli import main
    >>> main(["design", "--order", "-1"])   # prints the error on stderr
    2
    """
    command = "hpdob"
    try:
        with handling_signals():
            try:
                checkpoint("startup")  # a test hook (hpdob._interrupts); no-op otherwise
                load_plugins()  # HPDOB_PLUGINS and hpdob.families: their families' options
                argv = sys.argv[1:] if argv is None else list(argv)
                first = argv[0] if argv and isinstance(argv[0], str) else None
                args = _parse(build_parser(first), argv)
                command = f"hpdob {args.command}"
                _check_outputs(args)
                code = int(args.handler(args) or 0)
                check()  # a signal whose KeyboardInterrupt Python ignored (in a __del__)
                return code
            except KeyboardInterrupt as err:
                return _interrupted(command, err)
            except Exception as err:
                if received() is not None:  # the signal's exception, turned into another
                    # by C code it interrupted (an import: SyntaxError "can't load unicodedata")
                    return _interrupted(command, Interrupted(received()))
                return _failed(command, err)
    # a signal while the handlers go in or come out, or a second one while the first (or an
    # error) is reported
    except KeyboardInterrupt as err:
        return _interrupted(command, err)


#: Commands whose --out is a file (the others' is a directory).
_FILE_OUTPUTS = ("sweep", "export-fmu")


def _check_outputs(args: argparse.Namespace) -> None:
    """Check the command's output locations before its work (a file where a directory is
    wanted, a read-only directory): the run is not lost at its end."""
    from .._files import check_output

    if getattr(args, "out", None) is not None:
        kind = "file" if args.command in _FILE_OUTPUTS else "directory"
        check_output(args.out, kind=kind)
    if getattr(args, "export_c", None) is not None:
        check_output(args.export_c, name="--export-c")
    if args.command == "build-loop" and args.folder is not None:
        check_output(args.folder, name="--folder")


def _interrupted(command: str, err: KeyboardInterrupt) -> int:
    """Report an interrupt on one line; the exit code is 128 + the signal's number."""
    detail = getattr(err, "detail", "")  # e.g. where a sweep's finished rows went
    detail = f"; {detail}" if detail else ""
    if isinstance(err, Interrupted) and err.name != "SIGINT":
        print(f"{command}: interrupted ({err.name}){detail}", file=sys.stderr)
        return EXIT_CODES[err.signum]
    print(f"{command}: interrupted{detail}", file=sys.stderr)
    return 130


def _failed(command: str, err: Exception) -> int:
    """Report an error on one line and return its exit code."""
    from .._validation import ParameterTypeError, ParameterValueError

    if isinstance(err, (CLIError, ParameterTypeError, ParameterValueError)):
        print(f"{command}: error: {_one_line(err)}", file=sys.stderr)
        return 2
    if isinstance(err, BrokenPipeError):  # e.g. `hpdob design --json | head`: stop quietly
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 1
    if isinstance(err, OSError):  # e.g. an --out directory that cannot be created or written
        print(f"{command}: error: {_one_line(err)}", file=sys.stderr)
        return 2
    if os.environ.get("HPDOB_TRACEBACK"):  # a bug: still one line, the traceback on request
        raise err
    print(
        f"{command}: internal error: {type(err).__name__}: {_one_line(err)} (please report "
        f"it; set HPDOB_TRACEBACK=1 for the traceback)",
        file=sys.stderr,
    )
    return 1
