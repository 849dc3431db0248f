"""``hpdob identify LOG [LOG ...]``: identify J, b, Coulomb friction and offset from logged runs.

Option names mean what they mean in every other command (docs/naming.md): ``--kp/--kd`` are
hpdob's PD gains [1/s^2, 1/s] with the nominal inertia ``--J-n``; the gains of a loop in
torque units are ``--loop-kp/--loop-kd``.
"""

from __future__ import annotations

import argparse
import re
from pathlib import Path

import numpy as np

from .._validation import ParameterTypeError, ParameterValueError
from ._design import _integer, _number_list
from ._errors import CLIError
from ._logs import add_log_arguments, log_from_args, logs_from_args
from ._options import finite as _real
from ._options import output_path
from ._progress import ProgressLine, StagedProgress, show_progress

__all__ = ["register"]

_PARAMETERS = ("J", "b", "coulomb", "offset")


def _fixed(text: str) -> tuple[str, float]:
    name, _, value = text.partition("=")
    if name not in _PARAMETERS or not value:
        raise argparse.ArgumentTypeError(
            f"expected NAME=VALUE with NAME one of {', '.join(_PARAMETERS)}, got {text!r}"
        )
    return name, _real(value)


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "identify",
        help="identify inertia, friction and offset of an axis from logged runs",
        description="Identify u = J qdd + b qd + coulomb sign(qd) + offset from one or more logs "
        "(CSV, Parquet or MATLAB .mat) with filters read from the log and instrumental "
        "variables (default), or by the EMPS benchmark's IDIM-LS or IDIM-IV; writes "
        "identification.json, identification.csv and identification.png into the output "
        "directory and prints a summary (and validation.json/.png with --validate). A linear "
        "axis (m, N, kg) works like a rotary one (rad, N m, kg m^2): --axis sets the units of "
        "the report. See docs/real-data.md.",
    )
    add_log_arguments(
        parser,
        emps_help="use the EMPS benchmark's measured run shipped with hpdob (and its "
        "controller for --method idim-iv) instead of LOG",
        reference=True,
        several=True,
    )
    method = parser.add_argument_group("method and model")
    method.add_argument(
        "--method",
        choices=("auto", "idim-ls", "idim-iv", "idim-iv-input"),
        default="auto",
        help="auto: filters from the log and instrumental variables (through the loop if one "
        "is given); idim-ls/idim-iv: the EMPS benchmark's methods and rules (default: "
        "%(default)s)",
    )
    method.add_argument(
        "--friction", choices=("viscous+coulomb", "viscous"), default="viscous+coulomb",
        help="friction model; viscous lumps Coulomb friction into the offset of a one-way log "
        "(default: %(default)s)",
    )  # fmt: skip
    method.add_argument(
        "--fix", type=_fixed, action="append", default=[], metavar="NAME=VALUE",
        help="hold a parameter (J, b, coulomb, offset) at a value; repeatable",
    )  # fmt: skip
    method.add_argument(
        "--offsets", choices=("per-log", "shared"), default="per-log",
        help="with several logs: one offset each, or one for all (default: %(default)s)",
    )  # fmt: skip
    method.add_argument("--no-diagnostics", action="store_true",
                        help="skip the simulation-fit and filter-sensitivity checks")  # fmt: skip
    loop = parser.add_argument_group(
        "the loop that produced the log (for IDIM-IV; needs --reference)",
        "hpdob's PD, u = J_n (kp (r - y) + kd (r_dot - v) + r_ddot): --kp, --kd, --J-n; or "
        "any PD in torque units, u = loop_kp (r - y) + loop_kd (r_dot - v) + feedforward: "
        "--loop-kp, --loop-kd.",
    )
    loop.add_argument("--kp", type=_real, help="PD gain kp [1/s^2] (as in tune, simulate)")
    loop.add_argument("--kd", type=_real, help="PD gain kd [1/s] (as in tune, simulate)")
    loop.add_argument("--J-n", type=_real, help="nominal inertia J_n of that PD [kg m^2 or kg]")
    loop.add_argument("--no-feedforward", action="store_true",
                      help="that PD has no J_n r_ddot feed-forward")  # fmt: skip
    loop.add_argument(
        "--loop-kp", type=_real, help="position gain in torque units [N m/rad or N/m]"
    )
    loop.add_argument(
        "--loop-kd", type=_real, help="velocity gain in torque units [N m s/rad or N s/m]"
    )
    loop.add_argument("--reference-velocity", metavar="NAME", help="reference velocity column")
    loop.add_argument("--reference-acceleration", metavar="NAME",
                      help="reference acceleration column (the PD's feed-forward)")  # fmt: skip
    loop.add_argument(
        "--derive-reference", action="store_true",
        help="derive the reference velocity and acceleration from --reference by identify's "
        "filtered differentiation (Butterworth, forward-backward, then central differences). "
        "Default with --kp/--kd when no column is given, except for a step reference (it "
        "holds its value exactly between jumps for 95 %% of the samples): zero velocity and "
        "acceleration, as a PD answering steps uses",
    )  # fmt: skip
    loop.add_argument("--feedforward", metavar="NAME", help="feed-forward torque column [N m or N]")
    loop.add_argument(
        "--velocity-filter", type=_number_list(float), default=None, metavar="C0,C1,...",
        help="the loop's velocity estimate sum c_i y_(k-i) / Ts (default: 1,-1)",
    )  # fmt: skip
    loop.add_argument("--torque-limit", type=_real,
                      help="the loop's torque limit [N m or N] (as in tune)")  # fmt: skip
    loop.add_argument("--limit", type=_real, dest="removed_limit", help=argparse.SUPPRESS)
    filters = parser.add_argument_group("filters (default: from the log, see identify())")
    filters.add_argument(
        "--filter-bandwidth", type=_real,
        help="bandwidth of the motion the filters keep [Hz] (cutoff 5x)",
    )  # fmt: skip
    filters.add_argument("--bandwidth", type=_real, dest="removed_bandwidth",
                         help=argparse.SUPPRESS)  # fmt: skip
    filters.add_argument("--cutoff", type=_real, help="Butterworth cut-off [Hz]")
    filters.add_argument("--filter-order", type=_integer, default=4,
                         help="order of the Butterworth filters (4)")  # fmt: skip
    filters.add_argument("--order", type=_integer, dest="removed_order", help=argparse.SUPPRESS)
    filters.add_argument("--decimation", type=_integer, help="decimation factor")
    filters.add_argument("--border", type=_integer, help="samples dropped at each end")
    filters.add_argument(
        "--min-speed", type=_real, default=None,
        help="drop rows slower than this [rad/s or m/s]; 0 keeps every row (default with "
        "--method auto: drop the log's rests, where the speed stays below 2 %% of its largest)",
    )  # fmt: skip
    parser.add_argument(
        "--validate", type=Path, default=None, metavar="LOG",
        help="simulate the identified model on LOG (same columns; through its loop if the "
        "loop options are given) and report the fit (MATLAB compare)",
    )  # fmt: skip
    parser.add_argument(
        "--out",
        type=output_path,
        default=None,
        metavar="DIR",
        help="output directory (default: hpdob-results/identify-<log name>)",
    )
    parser.add_argument("--no-plot", action="store_true", help="skip the figures")
    parser.add_argument(
        "--progress", action=argparse.BooleanOptionalAction, default=None,
        help="reading and identification progress with the time left on stderr (default: "
        "when stderr is a terminal)",
    )  # fmt: skip
    parser.set_defaults(handler=_run)


#: The stages of identify()'s progress, as the command's lines name them.
STAGES = {
    "filtering": "filtering the logs",
    "iterating": "IDIM-IV iterations (at most)",
    "sensitivity": "re-estimating with the filters x2, /2",
    "simulating": "simulating the fit",
}


def _columns(args) -> dict:
    names = {
        "reference_velocity": args.reference_velocity,
        "reference_acceleration": args.reference_acceleration,
        "feedforward": args.feedforward,
    }
    return {key: name for key, name in names.items() if name is not None}


def _wants_loop(args) -> bool:
    return any(
        getattr(args, k) is not None for k in ("kp", "kd", "J_n", "loop_kp", "loop_kd")
    ) or bool(_columns(args))


#: A reference whose sample-to-sample changes are exactly 0 this often is a step reference.
STEP_FRACTION = 0.95


def _is_steps(reference) -> bool:
    """Whether ``reference`` is piecewise constant: it holds its value exactly between jumps
    for at least :data:`STEP_FRACTION` of its samples (and moves at all)."""
    changes = np.diff(np.asarray(reference, dtype=float))
    return bool(changes.size and np.any(changes) and np.mean(changes == 0.0) >= STEP_FRACTION)


def _loop(args, log, name: str):
    """The :class:`FeedbackLoop` of ``log`` from the loop options, and how its reference
    velocity was obtained."""
    from ..identification import FeedbackLoop, differentiate

    pd = [k for k in ("kp", "kd", "J_n") if getattr(args, k) is not None]
    torque = [k for k in ("loop_kp", "loop_kd") if getattr(args, k) is not None]
    if pd and torque:
        raise CLIError(
            "give hpdob's PD (--kp, --kd, --J-n) or the gains in torque units (--loop-kp, "
            "--loop-kd), not both"
        )
    if pd and len(pd) < 3:
        missing = [f"--{k.replace('_', '-')}" for k in ("kp", "kd", "J_n") if k not in pd]
        raise CLIError(
            f"--kp/--kd are hpdob's PD gains [1/s^2, 1/s] (as in tune and simulate), scaled by "
            f"the nominal inertia: give {', '.join(missing)}; for gains in torque units "
            "[N m/rad, N m s/rad] use --loop-kp/--loop-kd"
        )
    if torque and len(torque) < 2:
        raise CLIError("give both --loop-kp and --loop-kd")
    if not pd and not torque:
        raise CLIError(
            "the loop needs its gains: --kp, --kd and --J-n (hpdob's PD) or --loop-kp and "
            "--loop-kd (torque units)"
        )
    if log.reference is None:
        raise CLIError(f"the loop needs the reference position of {name}: give --reference")
    velocity = log.columns.get("reference_velocity")
    acceleration = log.columns.get("reference_acceleration")
    derive = args.derive_reference or (pd and velocity is None and acceleration is None)
    if derive and (velocity is not None or acceleration is not None):
        raise CLIError("--derive-reference replaces --reference-velocity/acceleration: drop one")
    source = "columns" if velocity is not None else "none (velocity feedback only)"
    if derive and not args.derive_reference and _is_steps(log.reference):
        # A step reference's velocity is zero but at its jumps, and a sampled PD sees a jump
        # in the error only (hpdob's simulate: r_dot = r_ddot = 0 for steps); filtering the
        # jump would smear it into a velocity pulse the loop never had.
        velocity = acceleration = np.zeros_like(log.reference)
        source = (
            f"zero: the reference holds between jumps (steps; {STEP_FRACTION:.0%} or more of "
            "its sample-to-sample changes are exactly 0)"
        )
    elif derive:
        velocity, acceleration = differentiate(log.reference, log.Ts, like=log.theta)
        source = "derived from the reference (filtered differentiation, cutoff as identify's)"
    feedforward = log.columns.get("feedforward")
    if pd:
        kp, kd = args.J_n * args.kp, args.J_n * args.kd
        if not args.no_feedforward and acceleration is not None:
            extra = args.J_n * acceleration
            feedforward = extra if feedforward is None else feedforward + extra
    else:
        kp, kd = args.loop_kp, args.loop_kd
    loop = FeedbackLoop(
        log.reference, kp=kp, kd=kd, reference_velocity=velocity, feedforward=feedforward,
        velocity_filter=tuple(args.velocity_filter or (1.0, -1.0)), limit=args.torque_limit,
    )  # fmt: skip
    return loop, source


def _load(args, progress=None):
    from ..identification import emps_loop

    logs = logs_from_args(args, _columns(args) or None, progress)
    if args.emps:
        if _wants_loop(args):
            raise CLIError("--emps brings its own controller: drop the loop options")
        with_loop = args.method in ("auto", "idim-iv")
        return logs, [emps_loop(logs[0]) if with_loop else None], None
    if not _wants_loop(args):
        if args.method == "idim-iv":
            raise CLIError(
                "--method idim-iv needs the loop that produced the log: give --reference and "
                "its gains (--kp, --kd, --J-n, or --loop-kp, --loop-kd)"
            )
        return logs, [None] * len(logs), None
    built = [_loop(args, log, log.source) for log in logs]
    return logs, [b[0] for b in built], built[0][1]


def _validate(args, result, files):
    """``--validate LOG``: the identified model simulated on another log."""
    from ..identification import emps_loop

    log = log_from_args(argparse.Namespace(**{**vars(args), "log": args.validate, "emps": False}),
                        _columns(args) or None)  # fmt: skip
    loop = None
    if args.emps:
        loop = emps_loop(log) if log.reference is not None else None
    elif _wants_loop(args):
        loop = _loop(args, log, log.source)[0]
    check = result.validate(log, loop=loop)
    files.write_json("validation.json", check.to_dict())
    if not args.no_plot:
        files.plot("validation.png", lambda: check.plot())
    return check


def _stem(log) -> str:
    """The default output directory's name part for ``log`` (its file, without a run)."""
    return Path(log.source.split(" run ")[0]).stem


#: identify()'s keyword spellings in its messages and hints, and the options that set them.
_CLI_WORDS = [
    (
        re.compile(r"\bidentify\(\[log, other\], offsets='shared'\)"),
        "hpdob identify LOG OTHER_LOG --offsets shared",
    ),
    (re.compile(r"fixed\[['\"](\w+)['\"]\]"), r"--fix \1"),
    (re.compile(r"\bfixed=\{'(\w+)': (\w+)\}"), r"--fix \1=\2"),
    (re.compile(r"\bmethod='([\w-]+)'"), r"--method \1"),
    (re.compile(r"\bfriction='([\w+-]+)'"), r"--friction \1"),
    (re.compile(r"\boffsets='(\w+)'"), r"--offsets \1"),
    (re.compile(r"\bfixed=\{[^}]*\}"), "--fix NAME=VALUE"),
    (
        re.compile(r"FeedbackLoop\(reference_velocity=\.\.\., feedforward=\.\.\.\)"),
        "--reference-velocity/--reference-acceleration columns, or --derive-reference",
    ),
    (re.compile(r"\bloop="), "the loop options (--kp/--kd with --J-n, or --loop-kp/--loop-kd)"),
    (re.compile(r"\bmin_speed=(?=\d)"), "--min-speed "),
    (re.compile(r"\bmin_speed\b"), "--min-speed"),
    (re.compile(r"(?<![-\w])decimation\b(?= ?[=<>]| must)"), "--decimation"),
    (re.compile(r"(?<![-\w])cutoff\b(?= ?[=<>]| must)"), "--cutoff"),
    (re.compile(r"(?<![-\w])border\b(?= ?[=<>]| must)"), "--border"),
    (re.compile(r"\bfilter_bandwidth=(?=\d)"), "--filter-bandwidth "),
]


def cli_words(text: str) -> str:
    """``text`` (a message or hint of :func:`hpdob.identification.identify`) with its keyword
    spellings replaced by the command's options (``fixed['J']`` -> ``--fix J``, ...)."""
    for pattern, replacement in _CLI_WORDS:
        text = pattern.sub(replacement, text)
    return text


#: identify's option spellings before 0.2 that other commands use with another meaning, and
#: the option that replaces each (docs/naming.md: one meaning per option name).
_REMOVED = {
    "bandwidth": ("--bandwidth", "--filter-bandwidth", "[Hz], the filters' band; --bandwidth is "
                  "an observer's bandwidth [rad/s] in design, estimate and analyze"),
    "limit": ("--limit", "--torque-limit", "[N m or N], as in tune"),
    "order": ("--order", "--filter-order", "the Butterworth filters'; --order is an observer's "
              "truncation order m in design, estimate and export-c"),
}  # fmt: skip


def _refuse_removed(args) -> None:
    for key, (old, new, why) in _REMOVED.items():
        value = getattr(args, f"removed_{key}")
        if value is not None:
            raise CLIError(f"identify {old} is now {new}: give {new} {value:g} ({why})")


def _run(args: argparse.Namespace) -> int:
    import warnings

    from .._files import check_output, staged_outputs
    from ..identification import EMPS_PUBLISHED, IdentificationWarning, identify

    _refuse_removed(args)
    if args.emps and args.validate is not None:
        raise CLIError("--validate takes a LOG with the same columns as LOG; not with --emps")
    show = show_progress(args.progress)
    lines = []

    def reading(name):
        lines.append(ProgressLine(f"hpdob identify: reading {name}", unit="MiB", scale=2**20))
        return lines[-1]

    try:
        logs, loops, loop_source = _load(args, reading if show else None)
    finally:  # an error or interrupt message starts on its own line
        for line in lines:
            line.end()
    # before the identification, not after it
    check_output(args.out or Path("hpdob-results") / f"identify-{_stem(logs[0])}")
    stages = StagedProgress("hpdob identify:", STAGES)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", IdentificationWarning)
        try:
            result = identify(
                logs if len(logs) > 1 else logs[0], method=args.method,
                loop=loops if len(logs) > 1 else loops[0],
                filter_bandwidth=args.filter_bandwidth, cutoff=args.cutoff,
                order=args.filter_order, decimation=args.decimation, border=args.border,
                min_speed=args.min_speed, friction=args.friction,
                fixed=dict(args.fix) or None, offsets=args.offsets,
                diagnostics=not args.no_diagnostics, axis=args.axis or logs[0].axis,
                progress=stages if show else None,
            )  # fmt: skip
        except (ParameterTypeError, ParameterValueError) as err:
            raise CLIError(cli_words(str(err))) from None
        finally:
            stages.end()
    out = args.out or Path("hpdob-results") / f"identify-{_stem(logs[0])}"
    described = [
        {"source": log.source, "names": dict(log.names), "input_gain": log.input_gain,
         "samples": len(log), "Ts": log.Ts}
        for log in logs
    ]  # fmt: skip
    # the result holds what it needs of the logs (their time and position, shared): the
    # rest not beside the outputs (issue 25)
    del logs, loops
    report = result.to_dict()
    report["logs"] = described
    report["log"] = report["logs"][0]
    if loop_source is not None:
        report["loop"] = {"reference_velocity": loop_source}
    if args.emps:
        report["published"] = dict(EMPS_PUBLISHED)
    written = ["identification.json", "identification.csv"]
    check = None
    # Staged and renamed together, identification.json last (docs/reliability.md).
    with staged_outputs(
        out,
        markers=["identification.json"],
        replaces=["identification.png", "validation.json", "validation.png"],
    ) as files:  # with --no-plot a previous identification.png goes: one consistent set
        result.to_csv(files.path("identification.csv"))
        if not args.no_plot:
            files.plot(
                "identification.png",
                lambda: result.plot(title=f"{result.method.upper()} on {described[0]['source']}"),
            )
            written.append("identification.png")
        if args.validate is not None:
            check = _validate(args, result, files)
            written += ["validation.json"] + ([] if args.no_plot else ["validation.png"])
        files.write_json("identification.json", report)
    for log in described:
        print(f"{log['source']}: {log['samples']} samples, Ts = {log['Ts']:g} s")
    if loop_source is not None:
        print(f"loop reference velocity: {loop_source}")
    print(cli_words(result.summary()))
    if args.emps:
        p = EMPS_PUBLISHED
        print(
            f"  published IDIM-LS (EMPS description, section 3.4): M {p['J']} kg, "
            f"Fv {p['b']} N s/m, Fc {p['coulomb']} N, offset {p['offset']} N"
        )
    if check is not None:
        print(check.summary())
    print(f"wrote {', '.join(written)} to {out}")
    caught = [w for w in caught if issubclass(w.category, IdentificationWarning)]
    return 1 if caught else 0
