"""``hpdob export-c``: write a designed observer as dependency-free C99 source."""

from __future__ import annotations

import argparse
from pathlib import Path

from ._design import add_design_arguments, design_from_args
from ._options import finite, output_path

__all__ = ["add_range_arguments", "ranges_from_args", "register"]

#: The ranges of the fixed-point formats: option name -> (key of export_c's ranges, help).
_RANGES = {
    "counts_per_rev": ("encoder counts per revolution (the angle input is the count)", int),
    "omega_max": ("velocity range [rad/s] (the input saturates there)", finite),
    "u_max": ("torque command range [N m] (the input saturates there)", finite),
    "tau_max": ("estimate range [N m] (the estimate saturates there)", finite),
}


def add_range_arguments(parser: argparse.ArgumentParser) -> None:
    """The declared ranges of ``--dtype q31``/``q15``."""
    group = parser.add_argument_group(
        "fixed point (--dtype q31 or q15; all four are required, docs/deployment.md)"
    )
    for name, (note, kind) in _RANGES.items():
        group.add_argument(f"--{name.replace('_', '-')}", type=kind, default=None, help=note)


def ranges_from_args(args: argparse.Namespace) -> dict | None:
    """The ``ranges`` dict of export_c for a fixed-point dtype (None for double/float)."""
    from ._errors import CLIError

    given = {k: getattr(args, k) for k in _RANGES if getattr(args, k) is not None}
    if args.dtype not in ("q31", "q15"):
        if given:
            names = ", ".join(f"--{k.replace('_', '-')}" for k in given)
            raise CLIError(f"{names}: only for --dtype q31 or q15, got --dtype {args.dtype}")
        return None
    missing = [f"--{k.replace('_', '-')}" for k in _RANGES if k not in given]
    if missing:
        raise CLIError(f"--dtype {args.dtype} needs {', '.join(missing)} (the declared ranges)")
    return given


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "export-c",
        help="write the observer as dependency-free C99 (<prefix>.h, <prefix>.c)",
        description="Design an observer (same options as 'hpdob design') and write it as "
        "dependency-free C99 for a microcontroller: <prefix>.h declares <prefix>_state, "
        "<prefix>_init, <prefix>_estimate and <prefix>_update; <prefix>.c holds the gains as "
        "constants. --dtype q31 writes integer fixed-point code from the declared ranges. "
        "--scenario FILE exports a scenario file's observer instead (a [reaction_observer] "
        "table: the DOb and the RTOB as one C observer, <prefix>_estimates giving tau_hat "
        "and tau_reac). See docs/deployment.md.",
    )
    parser.add_argument(
        "--scenario",
        type=Path,
        default=None,
        metavar="FILE",
        help="export the observer of this scenario file (.toml: its [nominal], Ts, [observer] "
        "and [reaction_observer]) instead of designing one from the options",
    )
    add_design_arguments(parser)
    out = parser.add_argument_group("output")
    out.add_argument(
        "--prefix",
        default="dob",
        help="C identifier prefix of the names and files (default: %(default)s)",
    )
    out.add_argument(
        "--dtype",
        default="double",
        help="scalar type, 'double', 'float', or fixed point 'q31' (int32) or 'q15' (int16) "
        "(default: %(default)s)",
    )
    out.add_argument(
        "--nan-guard",
        action="store_true",
        help="skip and flag samples with a non-finite input instead of letting one NaN poison "
        "the state until <prefix>_init (see docs/deployment.md)",
    )
    out.add_argument(
        "-o",
        "--out",
        type=output_path,
        default=".",
        metavar="DIR",
        help="output directory, created if missing (default: current directory)",
    )
    add_range_arguments(parser)
    # the design options' defaults: --scenario refuses any given one (they would be ignored)
    defaults = vars(parser.parse_args([]))
    parser.set_defaults(handler=_run, design_defaults=defaults)


#: Options that shape the C files, not the design: they apply with --scenario too.
_OUTPUT_OPTIONS = ("scenario", "prefix", "dtype", "nan_guard", "out", *_RANGES)


def _scenario_design(args: argparse.Namespace):
    """The observer of ``--scenario FILE`` (its RTOB composition, if it has one)."""
    from .. import robots  # noqa: F401  # registers the arm plant types (registration from above)
    from .._validation import ParameterTypeError, ParameterValueError
    from ..simulation import ServoLoop, load_scenario
    from ._errors import CLIError

    defaults = args.design_defaults
    given = [name for name, value in defaults.items() if name not in _OUTPUT_OPTIONS
             and getattr(args, name, value) != value]  # fmt: skip
    if given:
        names = ", ".join("--" + name.replace("_", "-") for name in given)
        raise CLIError(
            f"--scenario takes the design from {args.scenario} ([nominal], Ts, [observer], "
            f"[reaction_observer]): drop {names}, or drop --scenario"
        )
    try:
        scenario = load_scenario(args.scenario)
    except (ParameterValueError, ParameterTypeError) as err:
        raise CLIError(f"--scenario {args.scenario}: {err}") from None
    if not isinstance(scenario.loop, ServoLoop):  # an N-joint arm: one observer per joint
        raise CLIError(
            f"--scenario {args.scenario} is an N-joint arm ({type(scenario.loop).__name__}): "
            "export-c takes a single-axis one (export each joint's observer with export_c)"
        )
    observer = scenario.loop.observer
    if observer is None:
        raise CLIError(
            f"--scenario {args.scenario} has no [observer] table: nothing to export (add one, "
            "or design the observer with the options instead of --scenario)"
        )
    return observer


def _run(args: argparse.Namespace) -> int:
    from ..export import export_c

    ranges = ranges_from_args(args)
    design = design_from_args(args) if args.scenario is None else _scenario_design(args)
    paths = export_c(
        design,
        args.out,
        prefix=args.prefix,
        dtype=args.dtype,
        nan_guard=args.nan_guard,
        ranges=ranges,
    )
    for path in paths:
        print(path)
    return 0
