"""``hpdob export-fmu``: write a designed observer as an FMI 2.0 co-simulation FMU."""

from __future__ import annotations

import argparse

from ._design import add_design_arguments, design_from_args
from ._options import output_path

__all__ = ["register"]


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "export-fmu",
        help="write the observer as an FMI 2.0 co-simulation FMU (Simulink, OpenModelica)",
        description="Design an observer (same options as 'hpdob design') and write it as an "
        "FMI 2.0 co-simulation FMU built for this machine: inputs theta [, omega], u; outputs "
        "tau_hat [, omega_hat]; communication step Ts. The binary is compiled with zig cc "
        "(pip install ziglang) or $CC. See docs/deployment.md.",
    )
    add_design_arguments(parser)
    out = parser.add_argument_group("output")
    out.add_argument(
        "--model-identifier",
        default="dob",
        help="FMU model identifier and C prefix (default: %(default)s)",
    )
    out.add_argument(
        "-o",
        "--out",
        type=output_path,
        default="observer.fmu",
        metavar="FILE",
        help="the .fmu file to write (default: %(default)s)",
    )
    parser.set_defaults(handler=_run)


def _run(args: argparse.Namespace) -> int:
    from ..export import FMUBuildError, export_fmu
    from ._errors import CLIError

    design = design_from_args(args)
    try:
        path = export_fmu(design, args.out, model_identifier=args.model_identifier)
    except FMUBuildError as err:
        raise CLIError(str(err)) from None
    print(path)
    return 0
