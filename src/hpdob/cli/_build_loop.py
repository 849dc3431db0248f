"""``hpdob build-loop scenario.toml``: build a scenario's sample loop ahead of time."""

from __future__ import annotations

import argparse
from pathlib import Path

from ._options import add_scenario_overrides, apply_scenario_overrides

__all__ = ["register"]


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "build-loop",
        help="build a scenario's sample loop ahead of time (numba.pycc), for a faster first "
        "simulate in later processes",
        description="Build the compiled sample loop of the scenario in a TOML file (as "
        "hpdob simulate reads it) into a C extension with numba.pycc, so that a later "
        "process's first simulate of a run of that structure runs it without importing numba "
        "(opt-in; bit for bit the JIT loop's result; HPDOB_AOT=0 turns it off). Give it "
        "the options of hpdob simulate that change the loop (--measurement, --pd-velocity) "
        "as the runs will have them. Needs "
        "setuptools and a C compiler (pip install hpdob[aot]); see docs/simulation.md. "
        "Prints the extension's path.",
    )
    parser.add_argument("scenario", type=Path, help="scenario file (.toml)")
    parser.add_argument(
        "--folder",
        type=_folder,
        default=None,
        metavar="DIR",
        help="where the extension is written (default: $HPDOB_AOT_DIR, else "
        "$XDG_CACHE_HOME/hpdob/aot or ~/.cache/hpdob/aot: the folder simulate looks in; "
        "a build elsewhere is used by processes that set HPDOB_AOT_DIR to it)",
    )
    add_scenario_overrides(parser)  # they change the loop: the same as simulate's
    parser.add_argument(
        "--compiler",
        default=None,
        metavar="CMD",
        help="the C compiler command, split as a shell would, e.g. 'clang' or 'gcc -O2'; "
        "'zig': the ziglang package's zig cc (default: $CC, else the one setuptools finds)",
    )
    parser.set_defaults(handler=_run)


def _folder(text: str) -> Path:
    if not text:  # Path("") would be the working folder
        raise argparse.ArgumentTypeError("it must name a folder, got ''")
    return Path(text)


#: The scenario's simulate() arguments that decide the loop (the label and the rest do not).
_RUN_KEYS = ("plant", "nominal", "Ts", "controller", "observer", "sensor", "actuator",
             "reference", "disturbance", "duration", "substeps", "x0")  # fmt: skip


def _run(args: argparse.Namespace) -> int:
    from ..simulation import (
        LoopBuildError,
        build_loop_extension,
        plant_type_of,
        read_toml,
        scenario_from_dict,
    )
    from ._errors import CLIError

    data = read_toml(args.scenario)
    kind = plant_type_of(data)
    if kind is not None and kind.scenario is not None:
        raise CLIError(
            f"{args.scenario}: a [plant] type with a loop of its own (an N-joint arm) has no "
            "sample loop to build"
        )
    kwargs = scenario_from_dict(apply_scenario_overrides(args, data))
    run = {k: v for k, v in kwargs.items() if k in _RUN_KEYS}
    try:
        path = build_loop_extension(**run, folder=args.folder, compiler=args.compiler)
    except LoopBuildError as error:
        raise CLIError(str(error).splitlines()[0]) from error  # the reason, not the log
    print(path)
    return 0
