"""``hpdob export-c``: write a designed observer as dependency-free C99 source."""

from __future__ import annotations

import argparse

from ._design import add_design_arguments, design_from_args
from ._options import output_path

__all__ = ["register"]


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "export-c",
        help="write the observer as dependency-free C99 (<prefix>.h, <prefix>.c)",
        description="Design an observer (same options as 'hpdob design') and write it as "
        "dependency-free C99 for a microcontroller: <prefix>.h declares <prefix>_state, "
        "<prefix>_init, <prefix>_estimate and <prefix>_update; <prefix>.c holds the gains as "
        "constants. See docs/deployment.md.",
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
        help="scalar type, 'double' or 'float' (default: %(default)s)",
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
    parser.set_defaults(handler=_run)


def _run(args: argparse.Namespace) -> int:
    from ..export._c import export_c

    design = design_from_args(args)
    paths = export_c(
        design, args.out, prefix=args.prefix, dtype=args.dtype, nan_guard=args.nan_guard
    )
    for path in paths:
        print(path)
    return 0
