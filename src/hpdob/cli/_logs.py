"""The log a subcommand reads (``hpdob identify``, ``hpdob estimate``): a file with named
columns, or the shipped EMPS run; the options are defined once so that they mean one thing."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from ._errors import CLIError
from ._options import finite

__all__ = ["add_log_arguments", "log_file_from_args", "log_from_args", "logs_from_args"]


def add_log_arguments(
    parser: argparse.ArgumentParser,
    *,
    emps_help: str,
    reference: bool = False,
    several: bool = False,
) -> None:
    """``LOG`` or ``--emps``, and the column options (``--reference`` with ``reference``;
    several ``LOG`` files and ``--run`` with ``several``)."""
    if several:
        parser.add_argument(
            "log", type=Path, nargs="*", metavar="LOG",
            help="log file(s) (.csv, .parquet, .mat), all with the same columns",
        )  # fmt: skip
    else:
        parser.add_argument("log", type=Path, nargs="?", help="log file (.csv, .parquet, .mat)")
    parser.add_argument("--emps", action="store_true", help=emps_help)
    columns = parser.add_argument_group("columns of LOG")
    columns.add_argument("--time", metavar="NAME", help="time column [s] (or give --Ts)")
    columns.add_argument("--position", metavar="NAME", help="position column [rad or m]")
    columns.add_argument("--input", metavar="NAME", help="input column (torque/force or command)")
    columns.add_argument(
        "--input-gain",
        default=None,
        metavar="GAIN",
        help="factor from the input column to torque/force, or the name of a scalar variable "
        "of a .mat file holding it (default: 1)",
    )
    if reference:
        columns.add_argument("--reference", metavar="NAME", help="reference position column")
    if several:
        columns.add_argument(
            "--run", metavar="NAME",
            help="column telling which run each row belongs to: one file holding several runs",
        )  # fmt: skip
    columns.add_argument("--Ts", type=finite, help="sampling period [s] of a log without time")
    columns.add_argument(
        "--axis", choices=("rotary", "linear"), help="units of the report (default: unstated)"
    )


def _input_gain(text: str):
    try:
        value = float(text)
    except ValueError:
        return text  # the name of a scalar variable
    if not math.isfinite(value):
        raise CLIError(f"--input-gain must be a finite number or a variable name, got {text!r}")
    return value


def logs_from_args(args: argparse.Namespace, columns=None, progress=None) -> list:
    """The logs of ``LOG ...`` (several files, or one with ``--run``) or ``--emps``
    (``progress(name)``: the ``progress(done, total)`` callback, bytes read, for the file
    ``name``, or None)."""

    def reading(name):
        return None if progress is None else progress(name)

    from ..identification import read_logs

    files = list(args.log)
    if args.emps == bool(files):
        raise CLIError("give LOG file(s) or --emps (the shipped EMPS run), exactly one")
    if args.emps:
        if getattr(args, "run", None) is not None:
            raise CLIError("--emps is one run; drop --run")
        return [log_from_args(argparse.Namespace(**{**vars(args), "log": None}))]
    if getattr(args, "run", None) is None:
        return [log_from_args(argparse.Namespace(**{**vars(args), "log": f}), columns,
                              reading(Path(f).name))
                for f in files]  # fmt: skip
    if len(files) > 1:
        raise CLIError("--run splits one file into its runs: give one LOG with it")
    _require_columns(args)
    roles = [r for r in ("time", "position", "input", "reference") if hasattr(args, r)]
    return read_logs(
        files[0],
        run=args.run,
        **{role: getattr(args, role) for role in roles},
        input_gain=1.0 if args.input_gain is None else _input_gain(args.input_gain),
        Ts=args.Ts,
        axis=args.axis,
        columns=columns,
        progress=reading(Path(files[0]).name),
    )


def _require_columns(args) -> None:
    for name in ("position", "input"):
        if getattr(args, name) is None:
            raise CLIError(f"--{name} is required: the name of the log's {name} column")
    if (args.time is None) == (args.Ts is None):  # in the command's terms, not read_log's
        raise CLIError(
            "give the log's time column as --time NAME or, for a log without one, its sampling "
            "period as --Ts SECONDS"
            + (
                f" (not both: got --time {args.time} and --Ts {args.Ts:g})"
                if args.Ts is not None
                else ""
            )
        )


def log_from_args(args: argparse.Namespace, columns=None, progress=None):
    """The :class:`~hpdob.identification.Log` that ``add_log_arguments`` options describe
    (``progress(done, total)``: bytes read, see :func:`~hpdob.identification.read_log`)."""
    from ..identification import emps, read_log

    roles = [r for r in ("time", "position", "input", "reference") if hasattr(args, r)]
    if args.emps == (args.log is not None):
        raise CLIError("give a LOG file or --emps (the shipped EMPS run), exactly one")
    if args.emps:
        given = [f"--{k.replace('_', '-')}" for k in (*roles, "input_gain", "Ts", "axis")
                 if getattr(args, k) is not None]  # fmt: skip
        if given:
            raise CLIError(
                f"--emps uses the EMPS file's own columns, input gain, sampling period and "
                f"units; drop {', '.join(given)}"
            )
        return emps()
    _require_columns(args)
    return read_log(
        args.log,
        **{role: getattr(args, role) for role in roles},
        input_gain=1.0 if args.input_gain is None else _input_gain(args.input_gain),
        Ts=args.Ts,
        axis=args.axis,
        columns=columns,
        progress=progress,
    )


def log_file_from_args(args: argparse.Namespace, progress=None):
    """The log that ``add_log_arguments`` options describe, for a command that reads it block
    by block: a :class:`~hpdob.identification.LogFile` for a Parquet file (checked, never held
    whole; ``progress`` is called at the start and the end), else the
    :class:`~hpdob.identification.Log` of :func:`log_from_args`."""
    from ..identification import open_log

    if args.emps or args.log is None or Path(args.log).suffix.lower() not in (".parquet", ".pq"):
        return log_from_args(args, progress=progress)
    _require_columns(args)
    total = Path(args.log).stat().st_size if Path(args.log).is_file() else 0
    if progress is not None:
        progress(0, total)
    log = open_log(
        args.log,
        time=args.time,
        position=args.position,
        input=args.input,
        input_gain=1.0 if args.input_gain is None else _input_gain(args.input_gain),
        Ts=args.Ts,
        axis=args.axis,
    )
    if progress is not None:
        progress(total, total)
    return log
